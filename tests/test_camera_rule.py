"""One rule for an input's camera against a given one (encode, info, Python), folder images
checked whole, and errors that say what an input lacks."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.sequences import SAMPLE, SHARED_DATA
from pcdcodec.cli import main

SEVEN = SHARED_DATA / "7scenes_redkitchen"
TUM = SHARED_DATA / "tum_fr1_rpy"


def _tum_copy(root: Path, frames: int = 3, source: Path = SAMPLE) -> Path:
    """The first frames of a TUM RGB-D folder (its lists' headers kept), without camera.json:
    a TUM folder as the dataset ships it."""
    root.mkdir(parents=True)
    (root / "rgb").mkdir()
    (root / "depth").mkdir()
    for name in ("rgb.txt", "depth.txt"):
        lines = (source / name).read_text().splitlines()
        head = [line for line in lines if line.startswith("#")]
        rows = [line for line in lines if line and not line.startswith("#")][:frames]
        (root / name).write_text("\n".join(head + rows) + "\n")
        for row in rows:
            rel = row.split()[1]
            shutil.copy(source / rel, root / rel)
    return root


def _seven_copy(root: Path, frames: int = 3) -> Path:
    """The first frames of the real 7-Scenes folder (skipped where it is absent)."""
    if not SEVEN.is_dir():
        pytest.skip(f"{SEVEN} is not present")
    root.mkdir(parents=True)
    shutil.copy(SEVEN / "camera-intrinsics.txt", root)
    for sub, pattern in (("rgb", "color.jpg"), ("depth", "depth.png")):
        (root / sub).mkdir()
        for i in range(frames):
            name = f"frame-{i:06d}.{pattern}"
            shutil.copy(SEVEN / sub / name, root / sub / name)
    return root


def _cut(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


# -- A: the input's own camera and depth scale win; a flag fills a gap; --override replaces --


def test_encode_camera_flag_keeps_a_tum_folders_own_depth_scale(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _tum_copy(tmp_path / "tum")
    out = tmp_path / "x.pcdc"
    assert main(["encode", str(root), "-o", str(out), "--camera", "kinect-v1"]) == 0
    text = capsys.readouterr().out
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 5000.0  # not kinect-v1's 1000: clouds 5x too deep
    assert "5000 units per metre (from TUM RGB-D dataset)" in text
    assert "--camera kinect-v1 depth scale 1000 differs from the input's own 5000" in text
    assert "--override replaces it" in text
    # --override replaces it, and the summary says so.
    argv = ["encode", str(root), "-o", str(out), "--camera", "kinect-v1"]
    assert main([*argv, "--overwrite", "--override"]) == 0
    text = capsys.readouterr().out
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 1000.0
    assert "1000 units per metre (from --camera kinect-v1)" in text
    assert "override     the camera flags replace the input's own" in text
    assert "depth scale 1000 replaces the input's own 5000 (from TUM RGB-D dataset)" in text


def test_encode_camera_flag_keeps_a_seven_scenes_intrinsics_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _seven_copy(tmp_path / "seven")
    out = tmp_path / "x.pcdc"
    assert main(["encode", str(root), "-o", str(out), "--camera", "tum-ros"]) == 0
    text = capsys.readouterr().out
    with pcdcodec.open(out) as rec:
        assert (rec.intrinsics.fx, rec.depth_scale) == (585.0, 1000.0)
    assert "fx=585 fy=585 cx=320 cy=240 (from camera-intrinsics.txt)" in text
    assert "--camera tum-ros camera 640x480 fx=525" in text
    assert "differs from the input's own 640x480 fx=585" in text
    # info says the same as encode, through the same rule
    assert main(["info", str(root), "--camera", "tum-ros"]) == 0
    info = capsys.readouterr().out
    assert "fx=585 fy=585 cx=320 cy=240 (from camera-intrinsics.txt)" in info
    assert "--camera tum-ros depth scale 5000 differs from the input's own 1000" in info


def test_a_flag_fills_only_what_the_input_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The sample without its camera.json and its TUM header: a folder that says nothing.
    root = _tum_copy(tmp_path / "plain")
    depth_txt = root / "depth.txt"
    depth_txt.write_text(depth_txt.read_text().replace("rgbd_dataset_", "my_own_"))
    out = tmp_path / "x.pcdc"
    assert main(["encode", str(root), "-o", str(out), "--camera", "kinect-v1"]) == 0
    text = capsys.readouterr().out
    with pcdcodec.open(out) as rec:
        assert (rec.intrinsics.fx, rec.depth_scale) == (525.0, 1000.0)
    assert "(from --camera kinect-v1)" in text
    assert "note" not in text  # nothing contradicted


def test_python_encode_follows_the_same_rule(tmp_path: Path) -> None:
    root = _tum_copy(tmp_path / "tum")
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(root, out, color=None, depth_scale=1000)
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 5000.0
    (note,) = summary.source["camera_notes"]
    assert "depth_scale=1000 differs from the input's own 5000" in note
    assert summary.source["depth_scale_from"] == "TUM RGB-D dataset"
    summary = pcdcodec.encode(
        root, out, color=None, depth_scale=1000, override=True, overwrite=True
    )
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 1000.0
    assert "replaces the input's own 5000" in summary.source["camera_notes"][0]
    # An open source follows it too.
    with pcdcodec.open_source(root) as source:
        pcdcodec.encode(source, out, color=None, depth_scale=1000, overwrite=True)
    with pcdcodec.open(out) as rec:
        assert rec.depth_scale == 5000.0
    with pytest.raises(pcdcodec.InputError, match="override=True needs"):
        pcdcodec.encode(root, out, override=True, overwrite=True)


# -- C: a TUM folder gets its dataset's camera, said in the summary -------------------------


def test_a_tum_folder_encodes_with_its_datasets_camera(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _tum_copy(tmp_path / "tum")
    out = tmp_path / "x.pcdc"
    assert main(["encode", str(root), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    with pcdcodec.open(out) as rec:
        assert (rec.intrinsics.fx, rec.intrinsics.cx, rec.depth_scale) == (525.0, 319.5, 5000.0)
    assert "(from TUM RGB-D dataset: the ROS default camera TUM's tools use, tum-ros)" in text


def test_the_real_tum_folder_encodes_as_info_describes_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if not TUM.is_dir():
        pytest.skip(f"{TUM} is not present")
    assert main(["info", str(TUM)]) == 0
    info = capsys.readouterr().out
    assert "camera       640x480, fx=525" in info
    out = tmp_path / "x.pcdc"
    assert main(["encode", str(TUM), "-o", str(out), "--max-frames", "2"]) == 0
    with pcdcodec.open(out) as rec:
        assert (rec.intrinsics.fx, rec.depth_scale, len(rec)) == (525.0, 5000.0, 2)


# -- B: images in folders are checked whole ------------------------------------------------


@pytest.mark.parametrize("what", ["color", "depth"])
def test_a_cut_image_in_a_tum_folder_is_refused_naming_it(tmp_path: Path, what: str) -> None:
    root = _tum_copy(tmp_path / "tum")
    victim = sorted((root / ("rgb" if what == "color" else "depth")).iterdir())[1]
    _cut(victim)
    with pytest.raises(pcdcodec.DecodeError, match="PNG image is cut short") as err:
        pcdcodec.encode(root, tmp_path / "x.pcdc", color=None if what == "depth" else "ffv1")
    assert victim.name in str(err.value)
    assert not (tmp_path / "x.pcdc").exists()


def test_a_cut_jpeg_in_a_seven_scenes_folder_is_refused_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _seven_copy(tmp_path / "seven")
    victim = root / "rgb" / "frame-000001.color.jpg"
    _cut(victim)
    assert main(["encode", str(root), "-o", str(tmp_path / "x.pcdc"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "frame-000001.color.jpg" in err
    assert "JPEG image is cut short" in err


def test_a_cut_depth_png_is_one_line_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _seven_copy(tmp_path / "seven")
    victim = root / "depth" / "frame-000002.depth.png"
    _cut(victim)
    assert main(["encode", str(root), "-o", str(tmp_path / "x.pcdc"), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "frame-000002.depth.png" in err
    assert "PNG image is cut short" in err
    # A file that is no image at all: one line too.
    victim.write_bytes(b"not an image")
    assert main(["encode", str(root), "-o", str(tmp_path / "x.pcdc"), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "frame-000002.depth.png" in err


def test_other_layouts_check_their_images_too(tmp_path: Path) -> None:
    # rgb/ + depth/ named by frame number, and one flat folder: the same check.
    src = sorted((SAMPLE / "depth").iterdir())[:2]
    rgb = sorted((SAMPLE / "rgb").iterdir())[:2]
    sub = tmp_path / "sub"
    (sub / "rgb").mkdir(parents=True)
    (sub / "depth").mkdir()
    flat = tmp_path / "flat"
    flat.mkdir()
    for i, (d, c) in enumerate(zip(src, rgb, strict=True)):
        shutil.copy(d, sub / "depth" / f"{i:04d}.png")
        shutil.copy(c, sub / "rgb" / f"{i:04d}.png")
        shutil.copy(d, flat / f"{i:04d}_depth.png")
        shutil.copy(c, flat / f"{i:04d}_rgb.png")
    _cut(sub / "depth" / "0001.png")
    _cut(flat / "0001_rgb.png")
    for root, name in ((sub, "0001.png"), (flat, "0001_rgb.png")):
        with (
            pcdcodec.open_source(root, depth_scale=5000) as source,
            pytest.raises(pcdcodec.DecodeError, match=f"{name}.*cut short"),
        ):
            list(source)


# -- C: a folder that lacks its depth says so ------------------------------------------------


def test_a_folder_without_depth_says_what_it_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    nodepth = tmp_path / "nodepth"
    (nodepth / "rgb").mkdir(parents=True)
    for c in sorted((SAMPLE / "rgb").iterdir())[:2]:
        shutil.copy(c, nodepth / "rgb")
    for command in (["info", str(nodepth)], ["encode", str(nodepth), "-o", str(tmp_path / "x")]):
        assert main(command) == 1
        err = capsys.readouterr().err
        assert "holds rgb/ but no depth/ found" in err, err
        assert str(nodepth) in err
        assert "not a recording" not in err
        assert "expected one of" not in err
    tum = tmp_path / "tum"
    tum.mkdir()
    shutil.copy(SAMPLE / "rgb.txt", tum)
    assert main(["encode", str(tum), "-o", str(tmp_path / "x")]) == 1
    assert "holds rgb.txt but no depth.txt" in capsys.readouterr().err
    flat = tmp_path / "flat"
    flat.mkdir()
    shutil.copy(sorted((SAMPLE / "rgb").iterdir())[0], flat / "0001_rgb.png")
    assert main(["info", str(flat)]) == 1
    assert "holds color images (0001_rgb.png, ...) but no depth image" in (capsys.readouterr().err)


def test_a_bare_camera_matrix_fills_a_gap_at_the_images_size(tmp_path: Path) -> None:
    root = _tum_copy(tmp_path / "plain")
    depth_txt = root / "depth.txt"
    depth_txt.write_text(depth_txt.read_text().replace("rgbd_dataset_", "my_own_"))
    k = tmp_path / "K.txt"
    np.savetxt(k, [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    summary = pcdcodec.encode(root, tmp_path / "x.pcdc", color=None, intrinsics=k, depth_scale=1000)
    with pcdcodec.open(tmp_path / "x.pcdc") as rec:
        assert (rec.intrinsics.width, rec.intrinsics.fx, rec.depth_scale) == (640, 500.0, 1000.0)
    assert summary.source["camera_notes"] == []


def test_bench_reads_its_input_by_the_same_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _tum_copy(tmp_path / "tum", 2)
    argv = ["bench", str(root), "--frames", "2", "--no-rd", "--no-plots", "--depth", "zstd"]
    assert main([*argv, "--camera", "kinect-v1"]) == 0
    err = capsys.readouterr().err
    assert "--camera kinect-v1 depth scale 1000 differs from the input's own 5000" in err


def test_a_bag_without_camera_info_takes_a_bare_matrix_at_its_images_size(tmp_path: Path) -> None:
    bag = SHARED_DATA / "bags" / "spot" / "raw.bag"
    if not bag.is_file():
        pytest.skip(f"{bag} is not present")
    k = tmp_path / "K.txt"
    np.savetxt(k, [[300.0, 0, 212], [0, 300.0, 120], [0, 0, 1]])
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(bag, out, color=None, intrinsics=k, color_topic="")
    with pcdcodec.open(out) as rec:
        assert (rec.intrinsics.width, rec.intrinsics.height, rec.intrinsics.fx) == (424, 240, 300)
        assert rec.depth_scale == 1000.0
    assert summary.source["intrinsics_from"] == "intrinsics="
    assert summary.source["camera_notes"] == []


def test_a_bag_without_a_camera_is_not_told_to_put_a_file_in_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = SHARED_DATA / "bags" / "spot" / "raw.bag"
    if not bag.is_file():
        pytest.skip(f"{bag} is not present")
    assert main(["encode", str(bag), "-o", str(tmp_path / "x.pcdc"), "--color-topic", ""]) == 1
    err = capsys.readouterr().err
    assert "no intrinsics for" in err
    assert "--intrinsics FILE" in err
    assert "in the folder" not in err  # a bag file holds no camera.json beside it
    assert not (tmp_path / "x.pcdc").exists()
