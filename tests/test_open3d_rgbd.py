"""Open3D RGBDImage sequences, legacy and tensor, in and out of recordings."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import Frame, RGBDSequence

o3d = pytest.importorskip("open3d")


@pytest.fixture(scope="module")
def sample() -> RGBDSequence:
    return pcdcodec.load_sample(max_frames=3)


def _legacy(frame: Frame, scale: float) -> Any:
    return o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.geometry.Image(frame.color),
        o3d.geometry.Image(frame.depth),
        depth_scale=scale,
        depth_trunc=1000.0,
        convert_rgb_to_intensity=False,
    )


def _tensor(frame: Frame) -> Any:
    t = o3d.t.geometry
    return t.RGBDImage(t.Image(o3d.core.Tensor(frame.color)), t.Image(o3d.core.Tensor(frame.depth)))


def _open(path: Path, sample: RGBDSequence, scale: float = 5000.0) -> Any:
    return pcdcodec.open(path, "w", intrinsics=sample.intrinsics, depth_scale=scale, color="ffv1")


def test_legacy_sequence_round_trip(tmp_path: Path, sample: RGBDSequence) -> None:
    images = [_legacy(f, 5000.0) for f in sample]
    with _open(tmp_path / "a.pcdc", sample) as w:
        n = w.write_frames(
            [(img, f.timestamp_ns) for img, f in zip(images, sample, strict=True)],
            rgbd_depth_scale=5000.0,
        )
    assert n == 3
    with pcdcodec.open(tmp_path / "a.pcdc") as rec:
        # Bit-exact depth, lossless color, same stamps (RGBDImages carry no pose, nor the
        # depth's own time).
        assert list(rec) == [
            dataclasses.replace(f, pose=None, depth_timestamp_ns=None) for f in sample
        ]
        for frame, image in zip(rec, images, strict=True):
            back = frame.to_open3d_rgbd()
            assert isinstance(back, o3d.geometry.RGBDImage)
            np.testing.assert_array_equal(np.asarray(back.depth), np.asarray(image.depth))
            np.testing.assert_array_equal(np.asarray(back.color), np.asarray(image.color))


def test_tensor_sequence_round_trip(tmp_path: Path, sample: RGBDSequence) -> None:
    images = [_tensor(f) for f in sample]
    with _open(tmp_path / "t.pcdc", sample) as w:
        for img, f in zip(images, sample, strict=True):
            w.write_rgbd(img, f.timestamp_ns, depth_scale=5000.0)
    with pcdcodec.open(tmp_path / "t.pcdc") as rec:
        assert list(rec) == [
            dataclasses.replace(f, pose=None, depth_timestamp_ns=None) for f in sample
        ]
        back = rec[1].to_open3d_rgbd(tensor=True)
        assert isinstance(back, o3d.t.geometry.RGBDImage)
        depth = back.depth.as_tensor().numpy()[..., 0]
        assert depth.dtype == np.uint16
        np.testing.assert_array_equal(depth, sample[1].depth)
        np.testing.assert_array_equal(back.color.as_tensor().numpy(), sample[1].color)
        # Open3D's tensor point cloud from it matches ours, given the recording's scale.
        cam = rec.intrinsics
        k = o3d.core.Tensor(cam.K, dtype=o3d.core.float64)
        cloud = o3d.t.geometry.PointCloud.create_from_rgbd_image(
            back, k, depth_scale=rec.depth_scale, depth_max=100.0
        )
        ours = rec[1].to_point_cloud(tensor=True)
        assert cloud.point.positions.shape == ours.point.positions.shape


def test_scale_mismatch_is_an_error(tmp_path: Path, sample: RGBDSequence) -> None:
    frame = sample[0]
    with _open(tmp_path / "m.pcdc", sample) as w:
        # Made at Open3D's default 1000 and stated as such: the recording stores 5000.
        with pytest.raises(pcdcodec.InputError, match=r"depth_scale=1000.*stores 5000"):
            w.write_rgbd(_legacy(frame, 1000.0))
        # Made at 5000 but not said so: the default (1000) is assumed, and refused.
        with pytest.raises(pcdcodec.InputError, match="depth_scale="):
            w.write_rgbd(_legacy(frame, 5000.0))
        with pytest.raises(pcdcodec.InputError, match="depth_scale="):
            w.write_rgbd(_tensor(frame))
        with pytest.raises(pcdcodec.InputError, match="depth_scale="):
            w.write_frames([_tensor(frame)])
        w.write_rgbd(_legacy(frame, 5000.0), depth_scale=5000.0)
    with pcdcodec.open(tmp_path / "m.pcdc") as rec:
        assert len(rec) == 1  # nothing rescaled slipped in
        np.testing.assert_array_equal(rec[0].depth, frame.depth)


def test_depth_not_at_the_stated_scale_is_an_error(sample: RGBDSequence) -> None:
    image = _legacy(sample[0], 5000.0)
    with pytest.raises(pcdcodec.InputError, match="not whole"):
        pcdcodec.frame.from_open3d_rgbd(image, depth_scale=1000.0)
    color, depth = pcdcodec.frame.from_open3d_rgbd(image, depth_scale=5000.0)
    np.testing.assert_array_equal(depth, sample[0].depth)
    assert color is not None
    gray = o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.geometry.Image(sample[0].color), o3d.geometry.Image(sample[0].depth), 5000.0
    )
    with pytest.raises(pcdcodec.InputTypeError, match="convert_rgb_to_intensity=False"):
        Frame.from_open3d_rgbd(gray, depth_scale=5000.0)
    with pytest.raises(pcdcodec.InputTypeError, match="RGBDImage"):
        Frame.from_open3d_rgbd(sample[0])


def test_tensor_float_depth_is_metres(tmp_path: Path, sample: RGBDSequence) -> None:
    metres = np.where(sample[0].depth > 0, sample[0].depth / 5000.0, np.nan).astype(np.float32)
    t = o3d.t.geometry
    image = t.RGBDImage(t.Image(o3d.core.Tensor(sample[0].color)), t.Image(o3d.core.Tensor(metres)))
    frame = Frame.from_open3d_rgbd(image, depth_scale=1.0, timestamp_ns=7)
    np.testing.assert_array_equal(frame.depth, metres)
    assert frame.timestamp_ns == 7
    path = tmp_path / "f.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=sample.intrinsics, depth_scale=1.0, depth="zstd", color=None
    ) as w:
        w.write_rgbd(image, depth_scale=1.0)
    with pcdcodec.open(path) as rec:
        np.testing.assert_array_equal(rec[0].depth, metres)
        assert rec[0].color is None
        legacy = rec[0].to_open3d_rgbd()
        np.testing.assert_array_equal(np.asarray(legacy.depth), metres)


def test_read_side_scale_is_the_recordings(tmp_path: Path, sample: RGBDSequence) -> None:
    frame = sample[0]
    with _open(tmp_path / "r.pcdc", sample) as w:
        w.write(frame.color, frame.depth, frame.timestamp_ns)
    metres = np.asarray(_legacy(frame, 5000.0).depth)
    with pcdcodec.open(tmp_path / "r.pcdc") as rec:
        got = rec[0]
        # A legacy RGBDImage holds metres whatever scale is asked for: never 5x too large.
        for stated in (None, 5000.0, 5000):
            legacy = got.to_open3d_rgbd(depth_scale=stated)
            np.testing.assert_array_equal(np.asarray(legacy.depth), metres)
        for tensor in (False, True):
            with pytest.raises(pcdcodec.InputError, match=r"depth_scale=1000 differs.*5000"):
                got.to_open3d_rgbd(tensor=tensor, depth_scale=1000)
        with pytest.raises(pcdcodec.InputTypeError, match="depth_scale must be a number"):
            got.to_open3d_rgbd(depth_scale="5000")  # type: ignore[arg-type]
        tensor_image = got.to_open3d_rgbd(tensor=True, depth_scale=5000.0)
        np.testing.assert_array_equal(tensor_image.depth.as_tensor().numpy()[..., 0], frame.depth)
    # A frame without a camera: the stated scale is the only one there is.
    bare = Frame(frame.color, frame.depth, 0)
    np.testing.assert_array_equal(np.asarray(bare.to_open3d_rgbd(depth_scale=5000).depth), metres)
    with pytest.raises(pcdcodec.InputError, match="needs depth_scale"):
        bare.to_open3d_rgbd()


def test_write_frames_scale_error_names_its_keyword(tmp_path: Path, sample: RGBDSequence) -> None:
    image = _legacy(sample[0], 5000.0)
    with _open(tmp_path / "k.pcdc", sample) as w:
        with pytest.raises(pcdcodec.InputError, match=r"pass rgbd_depth_scale= ") as info:
            w.write_frames([image])
        assert "pass depth_scale=" not in str(info.value)
        with pytest.raises(pcdcodec.InputError, match=r"pass depth_scale= "):
            w.write_rgbd(image)
        with pytest.raises(pcdcodec.InputTypeError, match="rgbd_depth_scale must be a number"):
            w.write_frames([image], rgbd_depth_scale="5000")  # type: ignore[arg-type]
        assert w.write_frames([image], rgbd_depth_scale=5000) == 1


def test_the_conversions_live_in_geometry_and_frame_serves_them() -> None:
    import pcdcodec.frame
    import pcdcodec.geometry.open3d as conversions

    for name in ("open3d_rgbd", "from_open3d_rgbd", "open3d_rgbd_kind", "OPEN3D_DEPTH_SCALE"):
        assert getattr(pcdcodec.frame, name) is getattr(conversions, name), name
    # The module named open3d inside the package still imports the real Open3D.
    image = conversions.open3d_rgbd(None, np.full((2, 3), 1000, np.uint16), 1000.0)
    assert type(image) is o3d.geometry.RGBDImage
    assert conversions.open3d_rgbd_kind(image) == "legacy"
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        pcdcodec.frame.nothing  # noqa: B018
