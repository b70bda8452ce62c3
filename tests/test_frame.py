"""One frame type across sources, recordings and evaluation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec import Frame, RGBDFrame, RGBDSequence


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return pcdcodec.load_sample(max_frames=3)


def _frame(t: int = 5, value: int = 1000) -> Frame:
    color = np.full((4, 6, 3), 7, np.uint8)
    depth = np.full((4, 6), value, np.uint16)
    return RGBDFrame(color=color, depth=depth, timestamp_ns=t)


def test_rgbdframe_is_frame_and_takes_keywords() -> None:
    frame = _frame()
    assert RGBDFrame is Frame
    assert isinstance(frame, pcdcodec.Frame)
    assert frame.timestamp_ns == 5
    assert frame.index is None
    assert frame.pose is None
    assert Frame(frame.color, frame.depth, 5) == frame  # positional order color, depth, time


def test_equality_compares_arrays_time_and_pose() -> None:
    a, b = _frame(), _frame()
    assert a == b
    assert a != _frame(t=6)
    assert a != _frame(value=1001)
    c = _frame()
    assert c.color is not None
    c.color[0, 0, 0] = 8
    assert a != c
    as_float = _frame()
    as_float.depth = as_float.depth.astype(np.float32)
    assert a != as_float  # same values, other dtype: other data
    pose = np.eye(4)
    posed = Frame(a.color, a.depth, 5, pose=pose)
    assert a != posed
    assert posed == Frame(a.color, a.depth, 5, index=3, pose=pose.copy())  # index is provenance
    assert a != "frame"
    with pytest.raises(TypeError):
        hash(a)


def test_repr_is_short() -> None:
    frame = Frame(_frame().color, _frame().depth, 42, index=2, pose=np.eye(4))
    text = repr(frame)
    assert text == (
        "Frame(index=2, timestamp_ns=42, color=4x6x3 uint8, depth=4x6 uint16, "
        "pose=at (0.000, 0.000, 0.000) m)"
    )


def test_sequence_and_reprojection_reprs_are_short(sample: RGBDSequence) -> None:
    text = repr(sample)
    assert len(text) < 400
    assert "3 frames" in text
    assert "640x480 uint16" in text
    assert sample.intrinsics is not None
    proj = pcdcodec.Projector(sample.intrinsics, depth_scale=sample.depth_scale)
    result = proj.to_rgbd_arrays(proj.to_organized(sample[0].depth))
    assert len(repr(result)) < 300
    assert "depth=640x480 uint16" in repr(result)
    assert f"valid={np.count_nonzero(sample[0].depth)}" in repr(result)


def test_source_frames_carry_index_and_camera(sample: RGBDSequence) -> None:
    assert [f.index for f in sample] == [0, 1, 2]
    points, colors = sample[0].to_points()
    assert len(points) == np.count_nonzero(sample[0].depth)
    assert colors is not None
    bare = Frame(sample[0].color, sample[0].depth, 0)
    with pytest.raises(pcdcodec.InputError, match="projector="):
        bare.to_points()
    assert sample.intrinsics is not None
    proj = pcdcodec.Projector(sample.intrinsics, depth_scale=5000.0)
    np.testing.assert_array_equal(bare.to_points(proj)[0], points)


def test_recorded_frames_write_back_unchanged(tmp_path: Path, sample: RGBDSequence) -> None:
    first = tmp_path / "a.pcdc"
    with pcdcodec.open(
        first, "w", intrinsics=sample.intrinsics, depth_scale=5000.0, color="ffv1"
    ) as w:
        w.write_frames(sample)
    with pcdcodec.open(first) as rec:
        frames = list(rec)
    assert [f.index for f in frames] == [0, 1, 2]
    assert frames == list(sample)  # lossless color and depth, same timestamps
    assert frames[0] != frames[1]
    second = tmp_path / "b.pcdc"
    with pcdcodec.open(
        second, "w", intrinsics=sample.intrinsics, depth_scale=5000.0, color="ffv1"
    ) as w:
        assert w.write_frames(frames) == 3
    with pcdcodec.open(second) as rec:
        assert list(rec) == frames
        with pytest.warns(DeprecationWarning, match="timestamp_ns"):
            assert rec[1].timestamp == frames[1].timestamp_ns


def test_deprecated_names_still_work(sample: RGBDSequence) -> None:
    assert sample.intrinsics is not None
    proj = pcdcodec.Projector(sample.intrinsics, depth_scale=5000.0)
    organized = proj.to_organized(sample[0].depth)
    with pytest.warns(DeprecationWarning, match="to_rgbd_arrays"):
        old = proj.to_rgbd(organized)
    np.testing.assert_array_equal(old.depth, sample[0].depth)
