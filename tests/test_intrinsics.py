"""Intrinsics files, named cameras, folder timestamps and the CLI's camera flags."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import cli_message, main
from pcdcodec.datasets import open_folder, sample_dir, write_folder
from pcdcodec.geometry.camera import (
    CAMERA_PRESETS,
    CameraIntrinsics,
    camera_preset,
    find_intrinsics_file,
    read_intrinsics,
)
from pcdcodec.registry import parse_codec_specs

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
CAM = CameraIntrinsics(640, 480, 585.0, 580.0, 320.5, 241.0)


# -- files ---------------------------------------------------------------------------------


def test_k_text_needs_and_takes_the_size(tmp_path: Path) -> None:
    path = tmp_path / "intrinsics.K.txt"
    np.savetxt(path, CAM.K)  # scientific notation, as 7-Scenes ships it
    assert read_intrinsics(path, 640, 480) == CAM
    with pytest.raises(pcdcodec.InputError, match="without the image size"):
        read_intrinsics(path)
    path.write_text("585 0 320\n0 585 240\n")
    with pytest.raises(pcdcodec.InputError, match="holds 6 numbers"):
        read_intrinsics(path, 640, 480)


def test_ros_camera_info_yaml(tmp_path: Path) -> None:
    path = tmp_path / "camera_info.yaml"
    path.write_text(
        "image_width: 640\nimage_height: 480\ncamera_name: rgb\n"
        "camera_matrix:\n  rows: 3\n  cols: 3\n"
        f"  data: [{CAM.fx}, 0, {CAM.cx}, 0, {CAM.fy}, {CAM.cy}, 0, 0, 1]\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
    )
    assert read_intrinsics(path) == CAM
    path.write_text(path.read_text().replace("data: [0, 0, 0, 0, 0]", "data: [0.2, 0, 0, 0, 0]"))
    # The lens model is kept (CameraIntrinsics models distortion); unknown models are refused.
    distorted = read_intrinsics(path)
    assert distorted.distortion_model == "plumb_bob"
    assert distorted.distortion == (0.2, 0.0, 0.0, 0.0, 0.0)
    assert distorted.pinhole() == CAM
    path.write_text(path.read_text().replace("plumb_bob", "mystery_lens"))
    with pytest.raises(pcdcodec.InputError, match="distortion"):
        read_intrinsics(path)
    dump = tmp_path / "info.yaml"  # a sensor_msgs/CameraInfo message as echoed (ROS 2 names)
    dump.write_text(f"height: 480\nwidth: 640\nk: {CAM.K.ravel().tolist()}\nd: []\n")
    assert read_intrinsics(dump) == CAM


def test_open3d_intrinsic_json(tmp_path: Path) -> None:
    import open3d as o3d

    path = tmp_path / "intrinsic.json"
    o3d.io.write_pinhole_camera_intrinsic(str(path), CAM.to_open3d())
    assert read_intrinsics(path) == CAM
    ours = tmp_path / "camera.json"
    ours.write_text(json.dumps({**CAM.to_dict(), "depth_scale": 1000.0}))
    assert read_intrinsics(ours) == CAM


def test_unreadable_files_say_what_was_expected(tmp_path: Path) -> None:
    with pytest.raises(pcdcodec.InputError, match="does not exist"):
        read_intrinsics(tmp_path / "nope.txt")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: something\n")
    with pytest.raises(pcdcodec.InputError, match="camera_matrix"):
        read_intrinsics(bad)
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(pcdcodec.InputError, match="not valid JSON"):
        read_intrinsics(broken)


def test_presets_are_the_published_values() -> None:
    fr1 = camera_preset("tum-fr1")
    assert (fr1.intrinsics.fx, fr1.intrinsics.fy, fr1.intrinsics.cx, fr1.intrinsics.cy) == (
        517.3,
        516.5,
        318.6,
        255.3,
    )
    assert fr1.depth_scale == 5000.0
    assert camera_preset("kinect-v1").intrinsics.fx == 525.0
    assert {"tum-fr1", "tum-fr2", "tum-fr3", "kinect-v1", "7scenes"} <= set(CAMERA_PRESETS)
    with pytest.raises(pcdcodec.InputError, match="known cameras: tum-fr1"):
        camera_preset("kinect-v9")


# -- folders ---------------------------------------------------------------------------------


def _plain_folder(root: Path, numbers: list[int], k_file: str | None = None) -> Path:
    """rgb/ + depth/ images named by frame number (no time lists), from the bundled sample."""
    sample = sorted((sample_dir() / "rgb").iterdir())
    depth = sorted((sample_dir() / "depth").iterdir())
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    for i, n in enumerate(numbers):
        shutil.copy(sample[i], root / "rgb" / f"frame-{n:06d}.color.png")
        shutil.copy(depth[i], root / "depth" / f"frame-{n:06d}.depth.png")
    if k_file:
        np.savetxt(root / k_file, CAM.K)
    return root


def test_folder_finds_its_intrinsics_file_and_keeps_gaps(tmp_path: Path) -> None:
    root = _plain_folder(tmp_path / "f", [3, 4, 7], "camera-intrinsics.txt")
    assert find_intrinsics_file(root) == root / "camera-intrinsics.txt"
    source = open_folder(root, fps=10.0, depth_scale=1000.0)
    assert source.intrinsics == CAM
    assert [t for t, _, _ in source.pairs] == [0, 100_000_000, 400_000_000]  # 5, 6 dropped
    assert source.metadata["timestamps"].startswith("not recorded: frame numbers")
    assert source.metadata["intrinsics_file"] == "camera-intrinsics.txt"
    tum = open_folder(sample_dir(), max_frames=2)
    assert tum.metadata["timestamps"] == "recorded (TUM lists)"


@pytest.mark.shared_data
def test_7scenes_folder_reads_its_camera() -> None:
    root = SHARED / "7scenes_redkitchen"
    if not root.is_dir():
        pytest.skip(f"{root} is not present")
    source = open_folder(root, max_frames=2, depth_scale=1000.0)
    assert source.intrinsics == CameraIntrinsics(640, 480, 585.0, 585.0, 320.0, 240.0)


def test_write_folder_round_trip_and_no_partial_output(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=3)
    out = tmp_path / "out"
    assert write_folder(seq, out, intrinsics=seq.intrinsics, depth_scale=5000.0) == 3
    back = pcdcodec.load_folder(out)
    # The poses go out as groundtruth.txt, as quaternions: equal to float64 rounding.
    assert [dataclasses.replace(f, pose=None) for f in back] == [
        dataclasses.replace(f, pose=None) for f in seq
    ]
    for a, b in zip(back, seq, strict=True):
        assert a.pose is not None
        assert b.pose is not None
        np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-12)
    assert back.intrinsics == seq.intrinsics
    with pytest.raises(pcdcodec.InputError, match="overwrite=True"):
        write_folder(seq, out)

    def failing() -> object:
        yield seq[0]
        raise RuntimeError("source broke")

    with pytest.raises(RuntimeError):
        write_folder(failing(), tmp_path / "half")
    assert not (tmp_path / "half").exists()
    assert not list(tmp_path.glob(".half*"))


def test_codec_spec_lists() -> None:
    codecs = parse_codec_specs("zstd:level=9,lz4, h264:crf=20,preset=fast")
    assert codecs[0].get_config() == {"id": "zstd", "level": 9}
    assert codecs[1].name == "lz4"
    assert codecs[2].get_config()["crf"] == 20
    assert codecs[2].get_config()["preset"] == "fast"
    with pytest.raises(pcdcodec.InputError, match="no codec"):
        parse_codec_specs(" , ")


# -- CLI -------------------------------------------------------------------------------------


def test_encode_with_a_named_camera_and_a_folder_without_stamps(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _plain_folder(tmp_path / "f", [0, 1, 2])
    out = tmp_path / "a.pcdc"
    args = ["encode", str(root), "-o", str(out), "--camera", "tum-fr1", "--color", "ffv1", "-q"]
    assert main(args) == 0
    with pcdcodec.open(out) as rec:
        assert rec.intrinsics == camera_preset("tum-fr1").intrinsics
        assert rec.depth_scale == 5000.0
        assert rec.timestamps[0] == 0
        assert rec.metadata["timestamps"].startswith("not recorded")
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    assert "the input had no timestamps" in capsys.readouterr().out
    # The same again: the library's "overwrite=True" reads as the flag.
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "--overwrite" in err
    assert "overwrite=True" not in err


@pytest.mark.parametrize("command", ["encode", "bench"])
def test_encode_and_bench_share_the_camera_rules(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _plain_folder(tmp_path / "f", [0, 1])
    k = tmp_path / "K.txt"
    np.savetxt(k, CAM.K)
    extra = ["-o", str(tmp_path / "x.pcdc")] if command == "encode" else []
    both = [command, str(root), *extra, "--intrinsics", str(k), "--camera", "kinect-v1"]
    assert main(both) == 1
    assert "--intrinsics and --camera were both given" in capsys.readouterr().err
    missing = [command, str(root), *extra, "--intrinsics", str(tmp_path / "none.txt")]
    assert main(missing) == 1
    assert "none.txt" in capsys.readouterr().err
    unknown = [command, str(root), *extra, "--camera", "nope"]
    assert main(unknown) == 1
    assert "known cameras" in capsys.readouterr().err


def test_export_takes_its_output_as_import_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    seq = pcdcodec.load_sample(max_frames=3)
    rec = tmp_path / "r.pcdc"
    with pcdcodec.open(rec, "w", intrinsics=seq.intrinsics, depth_scale=5000.0) as w:
        w.write_frames(seq)
    assert main(["export", str(rec), "-o", str(tmp_path / "p")]) == 0
    assert main(["import", str(tmp_path / "p"), "-o", str(tmp_path / "back.pcdc")]) == 0
    assert main(["export", str(rec), str(tmp_path / "q")]) == 0  # the former spelling
    assert main(["export", str(rec), str(tmp_path / "q2"), "-o", str(tmp_path / "q3")]) == 1
    assert "give the output folder once" in capsys.readouterr().err


def test_cli_words() -> None:
    assert cli_message("'x' already exists; pass overwrite=True to replace it") == (
        "'x' already exists; pass --overwrite to replace it"
    )


# -- camera.json, dataset scales, info and the folder flags ----------------------------------


def test_camera_json_with_only_a_depth_scale_beside_an_intrinsics_file(tmp_path: Path) -> None:
    root = _plain_folder(tmp_path / "f", [0, 1], "intrinsics.K.txt")
    (root / "camera.json").write_text('{"depth_scale": 4000}')
    assert find_intrinsics_file(root) == root / "intrinsics.K.txt"
    source = open_folder(root)
    assert source.intrinsics == CAM
    assert (source.intrinsics_origin, source.depth_scale) == ("intrinsics.K.txt", 4000.0)
    assert source.depth_scale_origin == "camera.json"
    # What camera.json may hold is checked: a misspelt key is named, not ignored.
    (root / "camera.json").write_text('{"depth_scael": 4000}')
    with pytest.raises(pcdcodec.InputError, match=r"unknown key.*depth_scael.*may hold"):
        open_folder(root)
    (root / "camera.json").write_text('{"fx": 500, "depth_scale": 1000}')
    with pytest.raises(pcdcodec.InputError, match="gives fx but not fy, cx, cy"):
        open_folder(root)
    (root / "camera.json").write_text('{"depth_scale": 1000, "depth_to_color": [[1]]}')
    with pytest.raises(pcdcodec.InputError, match="depth_to_color without color"):
        open_folder(root)
    (root / "camera.json").write_text('{"depth_scale": -1}')
    with pytest.raises(pcdcodec.InputError, match="depth_scale must be a positive"):
        open_folder(root)


def test_defaults_fill_in_only_what_an_input_lacks(tmp_path: Path) -> None:
    from pcdcodec.sources import CameraDefaults

    preset = camera_preset("tum-ros")
    defaults = CameraDefaults(preset.intrinsics, preset.depth_scale, "--camera tum-ros")
    own = _plain_folder(tmp_path / "own", [0, 1], "camera-intrinsics.txt")  # 7-Scenes: 1000
    source = pcdcodec.open_source(own, defaults=defaults)
    assert (source.intrinsics, source.depth_scale) == (CAM, 1000.0)
    assert (source.intrinsics_origin, source.depth_scale_origin) == (
        "camera-intrinsics.txt",
        "7-Scenes dataset",
    )
    assert len(source.camera_notes) == 2
    assert all("the input's is used" in n for n in source.camera_notes)
    bare = _plain_folder(tmp_path / "bare", [0, 1])
    source = pcdcodec.open_source(bare, defaults=defaults)
    assert (source.intrinsics, source.depth_scale) == (preset.intrinsics, 5000.0)
    assert source.intrinsics_origin == source.depth_scale_origin == "--camera tum-ros"
    assert source.camera_notes == ()
    # Options given to the reader still replace what the input says.
    given = pcdcodec.open_source(own, depth_scale=5000.0)
    assert (given.depth_scale, given.depth_scale_origin) == (5000.0, "given")


@pytest.mark.shared_data
def test_7scenes_folder_gets_its_datasets_depth_scale() -> None:
    root = SHARED / "7scenes_redkitchen"
    if not root.is_dir():
        pytest.skip(f"{root} is not present")
    source = open_folder(root, max_frames=2)
    assert (source.depth_scale, source.depth_scale_origin) == (1000.0, "7-Scenes dataset")


def test_info_describes_a_folder_without_and_with_camera_flags(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _plain_folder(tmp_path / "f", [0, 1, 2])
    assert main(["info", str(root)]) == 0
    out = capsys.readouterr().out
    assert "frames       3" in out
    assert "640x480 depth, 640x480 color" in out
    assert "timestamps   not recorded: frame numbers" in out
    assert "depth scale  unknown (pass --depth-scale" in out
    assert "camera       unknown" in out
    assert main(["info", str(root), "--camera", "tum-fr1", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["depth_scale"], info["intrinsics"]["fx"]) == (5000.0, 517.3)
    assert main(["info", str(root), "--depth-scale", "1000"]) == 0
    assert "depth scale  1000 per metre (from --depth-scale)" in capsys.readouterr().out


def test_cli_color_camera_depth_only_and_patterns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import imagecodecs

    root = tmp_path / "k4a"
    root.mkdir()
    seq = pcdcodec.load_sample(max_frames=2)
    for i, frame in enumerate(seq):
        assert frame.color is not None
        (root / f"c_{i}.png").write_bytes(imagecodecs.png_encode(frame.color))
        small = np.ascontiguousarray(frame.depth[::2, ::2])
        (root / f"d_{i}.png").write_bytes(imagecodecs.png_encode(small))
    out = tmp_path / "a.pcdc"
    base = ["encode", str(root), "-o", str(out), "-q", "--depth-scale", "5000"]
    base += ["--fx", "262.5", "--fy", "262.5", "--cx", "159.75", "--cy", "119.75"]
    assert main(base) == 1
    err = capsys.readouterr().err
    assert "--depth-pattern and --color-pattern" in err  # no layout of its own: say so
    patterns = [*base, "--depth-pattern", "d_*.png", "--color-pattern", "c_*.png"]
    assert main(patterns) == 1
    err = capsys.readouterr().err
    assert "--color-intrinsics FILE" in err
    assert "--depth-only" in err
    assert "color_intrinsics=" not in err
    color_cam = tmp_path / "color.json"
    color_cam.write_text(json.dumps(camera_preset("tum-ros").intrinsics.to_dict()))
    d2c = tmp_path / "d2c.txt"
    np.savetxt(d2c, np.eye(4))
    assert (
        main([*patterns, "--color-intrinsics", str(color_cam), "--depth-to-color", str(d2c)]) == 0
    )
    with pcdcodec.open(out) as rec:
        assert rec.color_intrinsics == camera_preset("tum-ros").intrinsics
        assert rec[1].color.shape == (480, 640, 3)
        np.testing.assert_array_equal(rec[1].depth, seq[1].depth[::2, ::2])
    capsys.readouterr()
    assert main([*patterns, "--depth-only", "--overwrite"]) == 0
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"] is None
    with pytest.raises(SystemExit) as exit_info:
        main(["encode", "--camera", "list"])
    assert exit_info.value.code == 0
    listing = capsys.readouterr().out
    for name, preset in CAMERA_PRESETS.items():
        assert name in listing
        assert f"{preset.intrinsics.fx:g}" in listing


def test_camera_json_color_camera_and_transform_are_checked_naming_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A camera.json color camera without its size, or a depth_to_color that is not 16
    numbers, is refused naming camera.json: the size was taken half from the images (a 640x960
    camera for 640x480 images), and a string was read as a file relative to the working
    directory, in errors that named no file."""
    root = _plain_folder(tmp_path / "f", [0, 1], "intrinsics.K.txt")
    color = {"fx": 600, "fy": 600, "cx": 320, "cy": 240}
    cases = [
        ({"color": {**color, "height": 480}}, r"camera\.json': color gives no width"),
        ({"color": color}, r"camera\.json': color gives no width or height"),
        (
            {"color": {**color, "width": 640, "height": 480}, "depth_to_color": "d2c.txt"},
            r"camera\.json': depth_to_color must be a 4x4 matrix",
        ),
        (
            {"color": {**color, "width": 640, "height": 480}, "depth_to_color": [[1, 0], [0, 1]]},
            r"camera\.json': depth_to_color must be a 4x4 matrix",
        ),
    ]
    (tmp_path / "d2c.txt").write_text(" ".join(str(v) for v in np.eye(4).ravel()))
    monkeypatch.chdir(tmp_path)  # where a file name in depth_to_color used to be looked for
    for data, expected in cases:
        (root / "camera.json").write_text(json.dumps({"depth_scale": 1000, **data}))
        with pytest.raises(pcdcodec.InputError, match=expected):
            open_folder(root)
    # Complete, it is read: the transform as numbers.
    moved = np.eye(4)
    moved[0, 3] = 0.025
    data = {"color": {**color, "width": 640, "height": 480}, "depth_to_color": moved.tolist()}
    (root / "camera.json").write_text(json.dumps({"depth_scale": 1000, **data}))
    source = open_folder(root)
    assert source.color_intrinsics is not None
    assert (source.color_intrinsics.width, source.color_intrinsics.fx) == (640, 600.0)
    np.testing.assert_array_equal(source.depth_to_color, moved)
