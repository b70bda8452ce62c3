"""Input helpers: as_uint16_depth, the error tree, and the folder loader."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any

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
    assert len(load_folder(root, depth_scale=5000.0)) == 2  # paired by frame number


def _subfolders(root: Path, colors: list[str], depths: list[str]) -> list[Any]:
    """``rgb/`` and ``depth/`` holding the sample's frames under the given names (the k-th
    name of each list holds frame k); returns the sample's frames."""
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    sample = load_sample(max_frames=max(len(colors), len(depths)))
    for k, name in enumerate(colors):
        shutil.copy(sample.paths[k][0], root / "rgb" / name)
    for k, name in enumerate(depths):
        shutil.copy(sample.paths[k][1], root / "depth" / name)
    return list(sample)


def test_subfolders_pair_by_frame_number_and_count_the_images_left_alone(tmp_path: Path) -> None:
    """rgb 2, 3, 4 and depth 2, 4, 5: rgb2 goes with depth2 and rgb4 with depth4, at their
    frame numbers' times; rgb3 and depth5 have no partner and are counted, not paired by
    order with the next image."""
    root = tmp_path / "gaps"
    frames = _subfolders(
        root,
        ["rgb00002.png", "rgb00004.png", "rgb00003.png"],
        ["depth00002.png", "depth00004.png", "depth00005.png"],
    )
    with pcdcodec.open_source(root, depth_scale=5000.0, fps=10.0) as src:
        got = list(src)
        assert src.dropped == {"color": 1, "depth": 1}
    assert [f.timestamp_ns for f in got] == [0, 200_000_000]  # the gap of frame 3 is kept
    for f, want in zip(got, frames[:2], strict=True):
        np.testing.assert_array_equal(f.color, want.color)
        np.testing.assert_array_equal(f.depth, want.depth)
    summary = pcdcodec.encode(
        root,
        tmp_path / "gaps.pcdc",
        depth_scale=5000.0,
        intrinsics=pcdcodec.CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
        color="ffv1",
    )
    assert (summary.frames, summary.dropped) == (2, {"color": 1, "depth": 1})
    # No common frame number at all is refused, naming the files.
    other = tmp_path / "apart"
    _subfolders(other, ["c1.png", "c2.png"], ["d7.png", "d8.png"])
    with pytest.raises(pcdcodec.InputError, match=r"no color image has the frame num.*'c1\.png'"):
        pcdcodec.open_source(other, depth_scale=5000.0)


def test_subfolders_without_numbers_pair_in_order_only_one_to_one(tmp_path: Path) -> None:
    root = tmp_path / "plain"
    frames = _subfolders(root, ["a.png", "b.png"], ["x.png", "y.png"])
    with pcdcodec.open_source(root, depth_scale=5000.0) as src:
        got = list(src)
    np.testing.assert_array_equal(got[1].color, frames[1].color)
    (root / "depth" / "y.png").unlink()
    with pytest.raises(
        pcdcodec.InputError,
        match=r"2 color and 1 depth images whose names carry "
        r"no frame numbers.*name each pair's files with its frame number",
    ):
        pcdcodec.open_source(root, depth_scale=5000.0)


def test_subfolders_with_times_in_their_names_pair_by_time(tmp_path: Path) -> None:
    """Color stamped 3 ms after depth, one color image missing: paired within max_difference,
    each frame at its depth name's time."""
    root = tmp_path / "stamped"
    frames = _subfolders(
        root,
        ["1305031102.003000.png", "1305031102.203000.png"],
        ["1305031102.000000.png", "1305031102.100000.png", "1305031102.200000.png"],
    )
    with pcdcodec.open_source(root, depth_scale=5000.0) as src:
        got = list(src)
        assert src.dropped == {"color": 0, "depth": 1}
    assert [f.timestamp_ns for f in got] == [1305031102_000000000, 1305031102_200000000]
    np.testing.assert_array_equal(got[1].color, frames[1].color)
    np.testing.assert_array_equal(got[1].depth, frames[2].depth)


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


# -- other folder layouts ------------------------------------------------------------------------


def _sample_pairs(n: int = 3) -> list[tuple[np.ndarray, np.ndarray]]:
    sample = load_sample(max_frames=n)
    return [(f.color, f.depth) for f in sample]  # type: ignore[misc]


def test_flat_pcl_folder_of_tiffs(tmp_path: Path) -> None:
    import imagecodecs

    root = tmp_path / "pcl"
    root.mkdir()
    frames = _sample_pairs()
    for i, (color, depth) in zip((0, 1, 3), frames, strict=True):  # frame 2 was dropped
        (root / f"frame_{i:06d}_depth.tiff").write_bytes(imagecodecs.tiff_encode(depth))
        (root / f"frame_{i:06d}_rgb.tiff").write_bytes(imagecodecs.tiff_encode(color))
    assert pcdcodec.sources.base.detect_kind(root) == "folder"
    source = pcdcodec.open_source(root, depth_scale=5000.0, fps=10.0)
    assert source.metadata["timestamps"].startswith("not recorded: frame numbers")
    seq = list(source)
    assert [f.timestamp_ns for f in seq] == [0, 100_000_000, 300_000_000]
    for frame, (color, depth) in zip(seq, frames, strict=True):
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.color, color)
    # A depth file without its color partner is named, not paired with the wrong one.
    (root / "frame_000001_rgb.tiff").unlink()
    with pytest.raises(pcdcodec.InputError, match=r"frame_000001_depth\.tiff"):
        load_folder(root, depth_scale=5000.0)


def test_flat_folder_with_nanosecond_names(tmp_path: Path) -> None:
    import imagecodecs

    root = tmp_path / "ns"
    root.mkdir()
    stamps = [1614787200123456789, 1614787200156789012, 1614787200190000000]
    for t, (color, depth) in zip(stamps, _sample_pairs(), strict=True):
        (root / f"{t}_depth.png").write_bytes(imagecodecs.png_encode(depth))
        (root / f"{t}_color.png").write_bytes(imagecodecs.png_encode(color))
    source = pcdcodec.open_source(root, depth_scale=5000.0)
    assert source.metadata["timestamps"] == "recorded: nanoseconds in the depth file names"
    assert [f.timestamp_ns for f in source] == stamps


def test_npy_depth_by_patterns_with_tum_names(tmp_path: Path) -> None:
    import imagecodecs

    root = tmp_path / "npy"
    (root / "cam").mkdir(parents=True)
    (root / "range").mkdir()
    names = ["1305031102.175304", "1305031102.211214", "1305031102.243211"]
    frames = _sample_pairs()
    for name, (color, depth) in zip(names, frames, strict=True):
        np.save(root / "range" / f"{name}.npy", depth)
        (root / "cam" / f"{name}.png").write_bytes(imagecodecs.png_encode(color))
    with pytest.raises(pcdcodec.InputError, match=r"\.npy.*depth_pattern"):
        load_folder(root, depth_scale=5000.0)  # a layout of its own: say what was looked for
    seq = load_folder(
        root, depth_scale=5000.0, depth_pattern="range/*.npy", color_pattern="cam/*.png"
    )
    assert [f.timestamp_ns for f in seq] == [
        1305031102_175304000,
        1305031102_211214000,
        1305031102_243211000,
    ]
    for frame, (color, depth) in zip(seq, frames, strict=True):
        np.testing.assert_array_equal(frame.depth, depth)
        np.testing.assert_array_equal(frame.color, color)
    # float32 metres, depth only
    metres = (frames[0][1] / 5000.0).astype(np.float32)
    for name in names:
        np.save(root / "range" / f"{name}.npy", metres)
    only = load_folder(root, depth_scale=1.0, depth_pattern="range/*.npy")
    assert only[0].color is None
    assert only[0].depth.dtype == np.float32
    np.testing.assert_array_equal(only[0].depth, metres)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (lambda p: np.save(p, np.zeros((4, 4), np.float64)), "float64"),
        (lambda p: np.save(p, np.zeros((4, 4, 3), np.uint16)), "2-D"),
        (lambda p: p.write_bytes(b"\x93NUMPY not really"), "cannot read depth array"),
        (  # a header declaring 30000 x 30000 over a few bytes: refused before allocating
            lambda p: p.write_bytes(
                np.lib.format.magic(1, 0)
                + b"{'descr': '<u2', 'fortran_order': False, 'shape': (30000, 30000), }"
                + b" " * 50
                + b"\n"
                + b"\0" * 64
            ),
            "cannot read depth array",
        ),
    ],
)
def test_bad_npy_depth_is_an_input_error(tmp_path: Path, content: object, match: str) -> None:
    root = tmp_path / "bad"
    (root / "depth").mkdir(parents=True)
    path = root / "depth" / "0001.npy"
    content(path)  # type: ignore[operator]
    with pytest.raises(pcdcodec.InputError, match=match) as info:
        load_folder(root, depth_scale=1000.0)
    assert "0001.npy" in str(info.value)


def test_depth_only_folder_records_without_color(tmp_path: Path) -> None:
    root = tmp_path / "donly"
    (root / "depth").mkdir(parents=True)
    sample = load_sample(max_frames=3)
    for _, depth_path in sample.paths:
        shutil.copy(depth_path, root / "depth")
    source = pcdcodec.open_source(root, depth_scale=5000.0, intrinsics=sample.intrinsics)
    assert not source.has_color
    out = tmp_path / "donly.pcdc"
    pcdcodec.encode(source, out)
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"] is None
        assert len(rec) == 3
        np.testing.assert_array_equal(rec[2].depth, sample[2].depth)


def test_color_of_another_size_needs_and_takes_a_color_camera(tmp_path: Path) -> None:
    import imagecodecs

    root = tmp_path / "k4a"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    frames = _sample_pairs(2)
    for i, (color, depth) in enumerate(frames):
        (root / "rgb" / f"{i:04d}.png").write_bytes(imagecodecs.png_encode(color))
        small = np.ascontiguousarray(depth[::2, ::2])  # a depth camera of its own size
        (root / "depth" / f"{i:04d}.png").write_bytes(imagecodecs.png_encode(small))
    with pytest.raises(pcdcodec.InputError, match="color_intrinsics=") as info:
        list(pcdcodec.open_source(root, depth_scale=5000.0))
    assert "0000.png" in str(info.value)
    color_cam = {"width": 640, "height": 480, "fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5}
    d2c = np.eye(4)
    d2c[0, 3] = -0.025
    (root / "camera.json").write_text(
        json.dumps(
            {
                "fx": 262.5,
                "fy": 262.5,
                "cx": 159.75,
                "cy": 119.75,
                "depth_scale": 5000,
                "color": color_cam,
                "depth_to_color": d2c.tolist(),
            }
        )
    )
    source = pcdcodec.open_source(root)
    assert source.color_intrinsics is not None
    assert source.color_intrinsics.shape == (480, 640)
    np.testing.assert_array_equal(source.depth_to_color, d2c)
    out = tmp_path / "k4a.pcdc"
    pcdcodec.encode(source, out)
    with pcdcodec.open(out) as rec:
        assert rec.color_intrinsics == source.color_intrinsics
        assert rec[0].depth.shape == (240, 320)
        assert rec[0].color.shape == (480, 640, 3)
    # Depth only also reads it.
    assert load_folder(root, color=False)[0].color is None


def test_no_pairs_error_says_what_was_looked_for(tmp_path: Path) -> None:
    (tmp_path / "empty" / "depth").mkdir(parents=True)
    with pytest.raises(pcdcodec.InputError, match="no color/depth pairs") as info:
        load_folder(tmp_path / "empty", depth_scale=1000.0)
    for what in (".npy", "16-bit PNG", "rgb.txt", "*depth*", "depth_pattern"):
        assert what in str(info.value)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "a.png").write_bytes(b"")
    with pytest.raises(pcdcodec.InputError, match=r"not an RGB-D folder.*\.npy"):
        load_folder(tmp_path / "other")


def test_camera_recordings_take_an_intrinsics_file(tmp_path: Path) -> None:
    """``intrinsics=`` as a file for a RealSense .bag: read, a bare matrix at the recorded depth
    camera's size (it used to be kept as the path string)."""
    from .test_rosbag import RS_BAG

    if not RS_BAG.is_file():
        pytest.skip(f"{RS_BAG} is not present")
    k = tmp_path / "K.txt"
    k.write_text("400 0 320\n0 401 240\n0 0 1\n")
    with pcdcodec.open_source(RS_BAG, intrinsics=str(k)) as src:
        cam = src.intrinsics
        assert isinstance(cam, pcdcodec.CameraIntrinsics)
        assert (cam.width, cam.height, cam.fx, cam.fy) == (640, 480, 400.0, 401.0)
        assert src.intrinsics_origin == "given"
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        pcdcodec.open_source(RS_BAG, intrinsics=str(tmp_path / "none.txt"))


@pytest.mark.parametrize(
    ("listing", "stamp", "expected"),
    [
        ("rgb.txt", "12x.5", r"rgb\.txt:\d+: timestamp '12x\.5' is not seconds"),
        ("depth.txt", "-1.5", r"depth\.txt:\d+: timestamp '-1\.5' is not seconds"),
        ("depth.txt", "0.000001", r"depth\.txt:\d+: timestamp 0\.000001 is not after"),
    ],
)
def test_tum_lists_with_bad_times_are_refused_naming_the_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], listing: str, stamp: str, expected: str
) -> None:
    """A TUM list's time that is not decimal seconds (it raised ValueError), or that does not
    increase (an error naming no file, from the pairing), names the list and its line."""
    from pcdcodec.cli import main
    from pcdcodec.datasets import write_folder

    root = tmp_path / "seq"
    write_folder(load_sample(max_frames=3), root, depth_scale=5000.0)
    (root / "associations.txt").unlink()  # the lists themselves pair the images
    path = root / listing
    lines = path.read_text().splitlines()
    data = [i for i, line in enumerate(lines) if line and not line.startswith("#")]
    i = data[-1]  # the last frame: a later one with an earlier time
    lines[i] = " ".join([stamp, *lines[i].split()[1:]])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(pcdcodec.InputError, match=expected):
        pcdcodec.open_source(root, depth_scale=5000.0)
    assert main(["info", str(root), "--depth-scale", "5000"]) == 1
    err = capsys.readouterr().err
    assert re.search(expected, err), err
    if "not after" in expected:
        assert "--depth-pattern and --color-pattern" in err


def test_name_patterns_with_character_classes(tmp_path: Path) -> None:
    """``[...]`` in a name pattern is a glob wildcard, paired by what it matches (files the glob
    found were dropped as matching nothing: "holds no file matching")."""
    from pcdcodec.datasets import write_folder

    root = tmp_path / "seq"
    write_folder(load_sample(max_frames=4), root, depth_scale=5000.0)
    (root / "rgb.txt").unlink()
    (root / "depth.txt").unlink()
    depth_names = sorted(p.name for p in (root / "depth").iterdir())
    src = pcdcodec.open_source(
        root,
        depth_pattern="depth/00000[0-2].png",
        color_pattern="rgb/00000[!3-9].png",
        depth_scale=5000.0,
        intrinsics=pcdcodec.geometry.camera.camera_preset("tum-ros").intrinsics,
    )
    with src:
        frames = list(src)
    assert depth_names[:4] == ["000000.png", "000001.png", "000002.png", "000003.png"]
    assert len(frames) == 3
    seq = load_sample(max_frames=3)
    for got, want in zip(frames, seq, strict=True):
        assert (got.depth == want.depth).all()
        assert (got.color == want.color).all()


def test_name_patterns_without_partners_say_how_patterns_pair(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Patterns whose wildcards match other text: the error says what pairs them (it spoke of
    "the same name but for its kind", the flat layout's rule)."""
    from pcdcodec.datasets import write_folder

    root = tmp_path / "seq"
    write_folder(load_sample(max_frames=2), root, depth_scale=5000.0)
    for p in (root / "rgb").iterdir():
        p.rename(p.with_name("rgb" + p.name))
    with pytest.raises(pcdcodec.InputError, match="no partner") as err:
        pcdcodec.open_source(
            root, depth_pattern="depth/*.png", color_pattern="rgb/*.png", depth_scale=5000.0
        )
    assert "whose wildcards match the same text" in str(err.value)
    assert "same name but for its kind" not in str(err.value)
    # The command line names its flags.
    from pcdcodec.cli import main

    flags = ["--depth-pattern", "depth/*.png", "--depth-scale", "5000"]
    assert main(["info", str(root), *flags, "--color-pattern", "rgb/*.png"]) == 1
    assert "or no --color-pattern for depth only" in capsys.readouterr().err
    assert main(["info", str(root), *flags, "--color-pattern", "rgb/*.jpg"]) == 1
    assert "holds no file matching --color-pattern 'rgb/*.jpg'" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["depth", "rgb"])
def test_flat_folder_with_two_files_for_one_frame_is_refused(tmp_path: Path, kind: str) -> None:
    """frame_1_depth.png beside frame_1_depth.tiff: one of them was kept silently (the last
    in name order), the other's data lost."""
    import imagecodecs

    root = tmp_path / "pcl"
    root.mkdir()
    for i, (color, depth) in enumerate(_sample_pairs()[:2]):
        (root / f"frame_{i:06d}_depth.tiff").write_bytes(imagecodecs.tiff_encode(depth))
        (root / f"frame_{i:06d}_rgb.tiff").write_bytes(imagecodecs.tiff_encode(color))
    other = _sample_pairs()[2]
    data = other[1] if kind == "depth" else other[0]
    (root / f"frame_000001_{kind}.png").write_bytes(imagecodecs.png_encode(data))
    with pytest.raises(
        pcdcodec.InputError,
        match=rf"'frame_000001_{kind}\.png' and 'frame_000001_{kind}\.tiff' are the same frame's",
    ):
        pcdcodec.open_source(root, depth_scale=5000.0)


@pytest.mark.parametrize("scale", ["x", -1, 0, float("nan"), float("inf"), True])
def test_open_source_refuses_a_depth_scale_that_is_no_positive_number(
    tmp_path: Path, scale: object
) -> None:
    """depth_scale="x" raised ValueError from float(); -1, 0 and NaN were taken as the scale of
    a folder (and of a bag) and failed only later, or never."""
    from pcdcodec.datasets import write_folder
    from pcdcodec.sources import CameraDefaults

    root = tmp_path / "seq"
    write_folder(load_sample(max_frames=1), root, depth_scale=5000.0)
    with pytest.raises(pcdcodec.InputError, match="depth_scale must be"):
        pcdcodec.open_source(root, depth_scale=scale)
    with pytest.raises(pcdcodec.InputError, match="depth_scale must be"):
        CameraDefaults(depth_scale=scale)  # type: ignore[arg-type]
