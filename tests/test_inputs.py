"""Input helpers: as_uint16_depth, the error tree, and the folder loader."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.datasets import load_folder, load_sample, sample_dir

from .conftest import SEQUENCES


def test_error_tree() -> None:
    for cls in (
        pcdcodec.UnknownCodecError,
        pcdcodec.DecodeError,
        pcdcodec.InputError,
        pcdcodec.InputTypeError,
        pcdcodec.CodecUnavailableError,
    ):
        assert issubclass(cls, pcdcodec.PcdcodecError)
    assert issubclass(pcdcodec.UnknownCodecError, LookupError)
    assert issubclass(pcdcodec.DecodeError, ValueError)
    assert issubclass(pcdcodec.InputError, ValueError)
    assert issubclass(pcdcodec.InputTypeError, TypeError)
    assert issubclass(pcdcodec.InputTypeError, ValueError)


def test_as_uint16_depth_converts_exact_values() -> None:
    values = np.array([[0, 1, 65535], [1000, 2, 3]], dtype=np.int64)
    out = pcdcodec.as_uint16_depth(values)
    assert out.dtype == np.uint16
    np.testing.assert_array_equal(out, values)
    np.testing.assert_array_equal(pcdcodec.as_uint16_depth(values.astype(np.float64)), values)


@pytest.mark.parametrize(
    ("values", "match"),
    [
        (np.array([[1.0, np.nan]]), r"NaN at \(row, col\) \(0, 1\)"),
        (np.array([[1, -3]]), "negative value -3"),
        (np.array([[1.5, 2.0]]), "fractional value 1.5"),
        (np.array([[70000, 1]]), "70000 above 65535"),
        (np.zeros((2, 2, 2)), r"shape \(2, 2, 2\)"),
        (np.zeros((0, 3)), "empty"),
    ],
)
def test_as_uint16_depth_rejects_bad_values(values: np.ndarray, match: str) -> None:
    with pytest.raises(pcdcodec.InputError, match=match):
        pcdcodec.as_uint16_depth(values)


def test_as_uint16_depth_rejects_non_numeric() -> None:
    with pytest.raises(pcdcodec.InputTypeError, match="numeric"):
        pcdcodec.as_uint16_depth(np.array([["a", "b"]]))


def test_codec_error_hints_at_conversion() -> None:
    with pytest.raises(pcdcodec.InputTypeError, match="as_uint16_depth"):
        pcdcodec.get_codec("png16").encode(np.ones((3, 3), dtype=np.int32))


def test_load_sample() -> None:
    seq = load_sample()
    assert len(seq) == 15
    assert seq.depth_scale == 5000.0
    assert seq.intrinsics is not None
    assert (seq.intrinsics.fx, seq.intrinsics.cx, seq.intrinsics.cy) == (525.0, 319.5, 239.5)
    frame = seq[0]
    assert frame.depth.dtype == np.uint16
    assert frame.depth.shape == (480, 640)
    assert frame.color.shape == (480, 640, 3)
    assert frame.color.dtype == np.uint8
    stamps = [f.timestamp_ns for f in seq]
    assert stamps == sorted(stamps)
    assert stamps[0] == 1305031229_528748000
    assert 0.9 * 15 / 30 < (stamps[-1] - stamps[0]) / 1e9 < 1.1 * 15 / 30
    assert load_sample(max_frames=3).depths[2].shape == (480, 640)


def test_load_tum_lists_without_associations(tmp_path: Path) -> None:
    root = tmp_path / "tum"
    shutil.copytree(sample_dir(), root)
    (root / "associations.txt").unlink()
    with_assoc = load_sample()
    without = load_folder(root)
    assert len(without) == len(with_assoc)
    for a, b in zip(with_assoc, without, strict=True):
        np.testing.assert_array_equal(a.depth, b.depth)
        assert a.timestamp_ns == b.timestamp_ns


def test_load_plain_folders(tmp_path: Path) -> None:
    root = tmp_path / "plain"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    sample = load_sample(max_frames=3)
    for i, (color_path, depth_path) in enumerate(sample.paths):
        shutil.copy(color_path, root / "rgb" / f"{i:04d}.png")
        shutil.copy(depth_path, root / "depth" / f"{i:04d}.png")
    seq = load_folder(root, depth_scale=5000.0, fps=10.0)
    assert len(seq) == 3
    assert seq.intrinsics is None
    assert [f.timestamp_ns for f in seq] == [0, 100_000_000, 200_000_000]
    np.testing.assert_array_equal(seq[2].depth, sample[2].depth)
    (root / "depth" / "0002.png").unlink()
    with pytest.raises(pcdcodec.InputError, match="3 color and 2 depth"):
        load_folder(root)


def test_load_folder_errors(tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        load_folder(tmp_path / "nope")
    with pytest.raises(pcdcodec.InputError, match="not an RGB-D folder"):
        load_folder(tmp_path)
    with pytest.raises(pcdcodec.InputError, match="layout"):
        load_folder(sample_dir(), layout="bag")
    with pytest.raises(pcdcodec.InputError, match="max_frames"):
        load_folder(sample_dir(), max_frames=0)


@pytest.mark.shared_data
def test_load_shared_7scenes_folder() -> None:
    seq = SEQUENCES["7scenes_redkitchen"]
    if not seq.present:
        pytest.skip(f"{seq.root} is not present")
    loaded = load_folder(seq.root, max_frames=2, depth_scale=1000.0)
    assert len(loaded) == 2
    assert loaded[0].depth.dtype == np.uint16
    assert loaded[0].color.shape == (480, 640, 3)
