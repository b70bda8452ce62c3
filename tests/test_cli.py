"""The command-line tool, run as a user runs it: a subprocess per command."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.datasets import load_sample, sample_dir


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pcdcodec", *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=cwd,
        timeout=600,
    )


@pytest.fixture(scope="module")
def encoded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cli") / "sample.pcdc"
    result = run("encode", str(sample_dir()), "-o", str(out), "--max-frames", "6")
    assert result.returncode == 0, result.stderr
    assert "wrote 6 frames" in result.stdout
    return out


def test_codecs_lists_every_codec_with_its_defaults() -> None:
    out = run("codecs")
    assert out.returncode == 0, out.stderr
    for name in pcdcodec.list_codecs():
        assert f"  {name} " in out.stdout
    assert "effort=2" in out.stdout
    assert "crf=18" in out.stdout
    depth_only = run("codecs", "--kind", "depth")
    assert "jpegxl" in depth_only.stdout
    assert "h264" not in depth_only.stdout


def test_bad_arguments_exit_non_zero_with_a_message() -> None:
    out = run("codecs", "--kind", "video")
    assert out.returncode == 2
    assert "invalid choice: 'video'" in out.stderr
    assert run().returncode == 2
    version = run("--version")
    assert version.returncode == 0
    assert pcdcodec.__version__ in version.stdout


def test_the_cli_package_runs_as_a_module() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "pcdcodec.cli", "--version"],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout == f"pcdcodec {pcdcodec.__version__}\n"


def test_demo(tmp_path: Path) -> None:
    out = run("demo", "--frames", "5", "-o", str(tmp_path / "demo"))
    assert out.returncode == 0, out.stderr
    assert "depth bit-exact:                yes" in out.stdout
    assert "ratio against PointCloud2" in out.stdout
    # The ratio against a cloud of the valid points only is smaller than against every pixel.
    every = float(out.stdout.split("ratio against PointCloud2:")[1].split("x")[0])
    valid = float(out.stdout.split("of the pixels with depth only:")[1].split("x")[0])
    assert 0 < valid < every
    ply = tmp_path / "demo" / "frame0000.ply"
    assert ply.exists()
    assert ply.stat().st_size > 100_000


def test_encode_info_verify(encoded: Path) -> None:
    info = run("info", str(encoded), "--json")
    assert info.returncode == 0, info.stderr
    data = json.loads(info.stdout)
    assert data["frames"] == 6
    assert data["codecs"]["depth"]["id"] == pcdcodec.DEFAULT_DEPTH_CODEC
    assert data["intrinsics"]["fx"] == 525.0
    assert data["depth_scale"] == 5000.0
    text = run("info", str(encoded))
    assert "6 over" in text.stdout
    verify = run("verify", str(encoded))
    assert verify.returncode == 0
    assert "6 frames checked, OK" in verify.stdout


def test_encode_with_codec_options_and_explicit_camera(tmp_path: Path) -> None:
    src = tmp_path / "plain"
    (src / "rgb").mkdir(parents=True)
    (src / "depth").mkdir()
    seq = load_sample(max_frames=3)
    for i, (c, d) in enumerate(seq.paths):
        shutil.copy(c, src / "rgb" / f"{i}.png")
        shutil.copy(d, src / "depth" / f"{i}.png")
    out = tmp_path / "x.pcdc"
    no_scale = run("encode", str(src), "-o", str(out))
    assert no_scale.returncode == 1
    assert "no depth scale" in no_scale.stderr
    assert "--depth-scale" in no_scale.stderr
    assert not out.exists()
    missing = run("encode", str(src), "-o", str(out), "--depth-scale", "5000")
    assert missing.returncode == 1
    assert "no intrinsics" in missing.stderr
    assert not out.exists()
    partial = run("encode", str(src), "-o", str(out), "--fx", "525", "--depth-scale", "5000")
    assert partial.returncode == 1
    assert "--fy" in partial.stderr
    ok = run(
        "encode",
        str(src),
        "-o",
        str(out),
        "--fx",
        "525",
        "--fy",
        "525",
        "--cx",
        "319.5",
        "--cy",
        "239.5",
        "--depth-scale",
        "5000",
        "--color",
        "ffv1",
        "--depth",
        "zstd:level=9",
    )
    assert ok.returncode == 0, ok.stderr
    assert "depth scale  5000 units per metre (from --depth-scale)" in ok.stdout
    assert "640x480, fx=525 fy=525 cx=319.5 cy=239.5 (from --fx --fy --cx --cy)" in ok.stdout
    with pcdcodec.open(out) as rec:
        assert rec.codecs["depth"] == {"id": "zstd", "level": 9}
        assert rec.codecs["color"]["id"] == "ffv1"  # type: ignore[index]
        np.testing.assert_array_equal(rec[2].color, seq[2].color)
        np.testing.assert_array_equal(rec[2].depth, seq[2].depth)
    again = run(
        "encode",
        str(src),
        "-o",
        str(out),
        *("--fx", "1", "--fy", "1", "--cx", "1", "--cy", "1", "--depth-scale", "1000"),
    )
    assert again.returncode == 1
    assert "overwrite" in again.stderr


def test_encode_errors(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    out = run("encode", str(empty), "-o", str(tmp_path / "e.pcdc"))
    assert out.returncode == 1
    # Any input kind is accepted, so the error lists what would have been read.
    assert "is not an input pcdcodec reads" in out.stderr
    assert "RGB-D folder" in out.stderr
    assert "ROS 1 bag" in out.stderr
    bad_codec = run("encode", str(sample_dir()), "-o", str(tmp_path / "b.pcdc"), "--color", "h263")
    assert bad_codec.returncode == 1
    assert "unknown codec 'h263'" in bad_codec.stderr
    bad_opt = run("encode", str(sample_dir()), "-o", str(tmp_path / "c.pcdc"), "--depth", "zstd:9")
    assert bad_opt.returncode == 1
    assert "key=value" in bad_opt.stderr


def test_decode_writes_a_tum_folder_that_encodes_again(encoded: Path, tmp_path: Path) -> None:
    out = tmp_path / "decoded"
    result = run("decode", str(encoded), "-o", str(out), "--ply")
    assert result.returncode == 0, result.stderr
    assert len(list((out / "rgb").glob("*.png"))) == 6
    assert len(list((out / "clouds").glob("*.ply"))) == 6
    seq = load_sample(max_frames=6)
    again = pcdcodec.load_folder(out)
    assert again.intrinsics == seq.intrinsics
    for a, b in zip(again, seq, strict=True):
        np.testing.assert_array_equal(a.depth, b.depth)
        assert a.timestamp_ns == b.timestamp_ns
    refused = run("decode", str(encoded), "-o", str(out))
    assert refused.returncode == 1
    assert "not empty" in refused.stderr


def test_decode_threads_reads_ahead_and_writes_the_same_folder(
    encoded: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    folders = {}
    for threads in (None, 2):
        out = tmp_path / f"threads-{threads}"
        extra = [] if threads is None else ["--threads", str(threads)]
        assert main(["decode", str(encoded), "-o", str(out), "-q", *extra]) == 0
        folders[threads] = {
            p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()
        }
    assert len(folders[2]) >= 12
    assert folders[2] == folders[None]
    assert main(["decode", str(encoded), "-o", str(tmp_path / "bad"), "--threads", "-1"]) == 1
    assert "threads must be an int in 0..256" in capsys.readouterr().err


def test_decode_quiet_prints_nothing_but_errors(encoded: Path, tmp_path: Path) -> None:
    out = tmp_path / "quiet"
    result = run("decode", str(encoded), "-o", str(out), "-q")
    assert result.returncode == 0, result.stderr
    assert result.stdout == ""
    assert result.stderr == ""
    assert len(list((out / "depth").glob("*.png"))) == 6
    refused = run("decode", str(encoded), "-o", str(out), "-q")
    assert refused.returncode == 1
    assert "not empty" in refused.stderr  # errors still say what went wrong


def test_verify_and_recover_a_damaged_file(tmp_path: Path) -> None:
    # zerolatency: x264 emits each frame's packet at once, so a cut file keeps frames.
    encoded = tmp_path / "z.pcdc"
    made = run(
        "encode",
        str(sample_dir()),
        "-o",
        str(encoded),
        "--max-frames",
        "6",
        "--color",
        "h264:tune=zerolatency",
    )
    assert made.returncode == 0, made.stderr
    data = encoded.read_bytes()
    cut = tmp_path / "cut.pcdc"
    cut.write_bytes(data[: 3 * len(data) // 4])
    verify = run("verify", str(cut))
    assert verify.returncode == 1
    assert "cut short" in verify.stdout
    fixed = tmp_path / "fixed.pcdc"
    recover = run("recover", str(cut), "-o", str(fixed))
    assert recover.returncode == 0, recover.stderr
    assert run("verify", str(fixed)).returncode == 0
    info = json.loads(run("info", str(fixed), "--json").stdout)
    assert info["indexed"] is True
    assert 0 < info["frames"] <= 6


def test_not_a_recording(tmp_path: Path) -> None:
    junk = tmp_path / "junk.pcdc"
    junk.write_bytes(b"hello world")
    for command in ("info", "verify"):
        out = run(command, str(junk))
        assert out.returncode == 1
        assert out.stderr.startswith("error:")
        assert "not a pcdcodec recording" in out.stderr
    missing = run("info", str(tmp_path / "missing.pcdc"))
    assert missing.returncode == 1
    assert "does not exist" in missing.stderr


def test_export_and_import_the_paper_layout(encoded: Path, tmp_path: Path) -> None:
    out = tmp_path / "paper"
    exported = run("export", str(encoded), str(out), "--layout", "paper")
    assert exported.returncode == 0, exported.stderr
    assert (out / "depth.lz4").exists()
    back = tmp_path / "back.pcdc"
    imported = run("import", str(out), "-o", str(back))
    assert imported.returncode == 0, imported.stderr
    with pcdcodec.open(back) as a, pcdcodec.open(encoded) as b:
        assert len(a) == len(b)
        np.testing.assert_array_equal(a[3].depth, b[3].depth)
        np.testing.assert_array_equal(a[3].color, b[3].color)
    unknown = run("export", str(encoded), str(tmp_path / "p2"), "--layout", "ros1")
    assert unknown.returncode == 1
    assert "unknown layout 'ros1'" in unknown.stderr


def test_info_tells_a_ros2_mcap_bag_from_a_recording() -> None:
    from tests.conftest import SHARED_DATA

    bag = SHARED_DATA / "bags" / "ros2-converted" / "spot_ros2_mcap" / "spot_ros2_mcap.mcap"
    if not bag.is_file():
        pytest.skip("the ROS 2 MCAP bag of ../shared/data is not present")
    out = run("info", str(bag))
    assert out.returncode == 0, out.stderr
    assert "damaged" not in out.stdout + out.stderr
    assert "RosbagSource" in out.stdout


def test_encode_into_a_missing_folder_names_the_folder(tmp_path: Path) -> None:
    out = run("encode", str(sample_dir()), "-o", str(tmp_path / "nope" / "x.pcdc"))
    assert out.returncode != 0
    assert f"create {str(tmp_path / 'nope')!r} first" in out.stderr
    assert "partial" not in out.stderr


def test_decode_keeps_a_color_camera_and_depth_only_readable(tmp_path: Path) -> None:
    """A decoded folder encodes again when the recording had a color camera of its own (its
    camera.json left it out, and the folder was refused as unregistered color) or no color
    (an empty rgb.txt made it a folder with no pairs)."""
    from pcdcodec.cli import main

    seq = load_sample(max_frames=2)
    color_cam = pcdcodec.CameraIntrinsics(320, 240, 260.0, 261.0, 160.0, 120.0)
    d2c = np.eye(4)
    d2c[:3, 3] = (0.025, -0.001, 0.003)
    two = tmp_path / "two.pcdc"
    with pcdcodec.open(
        two,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color_intrinsics=color_cam,
        depth_to_color=d2c,
    ) as rec:
        for f in seq:
            rec.write(f.color[::2, ::2].copy(), f.depth, f.timestamp_ns)
    alone = tmp_path / "alone.pcdc"
    with pcdcodec.open(
        alone, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=None
    ) as rec:
        for f in seq:
            rec.write(None, f.depth, f.timestamp_ns)
    for name in ("two", "alone"):
        out = tmp_path / name
        assert main(["decode", str(tmp_path / f"{name}.pcdc"), "-o", str(out), "-q"]) == 0
        source = pcdcodec.open_source(out)
        with source:
            frames = list(source)
        assert len(frames) == 2
        for got, want in zip(frames, seq, strict=True):
            np.testing.assert_array_equal(got.depth, want.depth)
        if name == "two":
            assert source.color_intrinsics == color_cam
            np.testing.assert_array_equal(source.depth_to_color, d2c)
            assert frames[0].color is not None
            assert frames[0].color.shape == (240, 320, 3)
        else:
            assert not source.has_color
            assert frames[0].color is None
            assert not (out / "rgb.txt").exists()


def test_folder_flags_on_a_bag_are_named_as_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--depth-only on a bag was refused as "--color apply to RGB-D folders", a flag not
    given (and another flag's name); it reads the bag's depth alone. A folder's own flags are
    refused under their own names."""
    from pcdcodec.cli import main

    from .test_rosbag import _image, _small, _store, write_bag

    store = _store(False)
    depth = _small(1)[0][1]
    bag = write_bag(
        tmp_path / "a.bag",
        [("/cam/depth/image_raw", 10**9, _image(store, False, 10**9, depth, "16UC1"))],
        store=store,
    )
    assert main(["info", str(bag), "--depth-only"]) == 0  # a bag's depth alone
    captured = capsys.readouterr()
    assert "--color " not in captured.out + captured.err
    assert main(["info", str(bag), "--depth-pattern", "d*.png"]) == 1
    assert "--depth-pattern applies to RGB-D folders" in capsys.readouterr().err


def test_info_on_a_recording_refuses_input_flags(
    encoded: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """info REC.pcdc --camera tum-ros --depth-scale 5000 printed the recording's own camera
    and scale, silently ignoring both flags."""
    from pcdcodec.cli import main

    assert main(["info", str(encoded), "--camera", "tum-ros", "--depth-scale", "5000"]) == 1
    err = capsys.readouterr().err
    assert "--camera --depth-scale describe how to read an input" in err
    assert main(["info", str(encoded), "--camera", "tum-ros"]) == 1
    assert "--camera describes how to read an input" in capsys.readouterr().err
    assert main(["info", str(encoded)]) == 0


def test_options_go_anywhere_among_a_commands_arguments() -> None:
    from pcdcodec.cli import build_parser, parse_args

    args = parse_args(["export", "run.pcdc", "--layout", "paper", "out/"])
    assert (args.command, args.input, args.output_pos, args.layout) == (
        "export",
        "run.pcdc",
        "out/",
        "paper",
    )
    args = parse_args(["archive", "a/", "--verify", "b.bag", "-o", "out"])
    assert args.src == ["a/", "b.bag"]
    assert args.verify
    # Every command can be parsed this way (argparse refuses some layouts for it).
    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    assert commands
    for name in commands:
        with pytest.raises(SystemExit) as done:
            parse_args([name, "--help"])
        assert done.value.code == 0, name
    # Every command takes an option before, between and after its positional arguments.
    intermixed: dict[str, tuple[list[str], dict[str, Any]]] = {
        "demo": (["--frames", "2", "-o", "out"], {"frames": 2, "output": "out"}),
        "encode": (
            ["--fps", "15", "in/", "-o", "x.pcdc", "--camera", "tum-ros"],
            {"src": ["in/"], "fps": 15.0, "output": "x.pcdc", "camera": "tum-ros"},
        ),
        "decode": (
            ["-q", "x.pcdc", "--ply", "-o", "out/", "--threads", "2"],
            {"input": "x.pcdc", "ply": True, "threads": 2},
        ),
        "info": (
            ["--json", "a.bag", "--depth-topic", "/d"],
            {"input": "a.bag", "json": True, "depth_topic": "/d"},
        ),
        "verify": (["x.pcdc"], {"input": "x.pcdc"}),
        "recover": (
            ["--overwrite", "x.pcdc", "-o", "y.pcdc"],
            {"input": "x.pcdc", "output": "y.pcdc", "overwrite": True},
        ),
        "join": (
            ["a.pcdc", "--overwrite", "b.pcdc", "-o", "c.pcdc", "d.pcdc"],
            {"parts": ["a.pcdc", "b.pcdc", "d.pcdc"], "output": "c.pcdc", "overwrite": True},
        ),
        "export": (
            ["--to", "rosbag2", "x.pcdc", "--cloud", "out/", "-q"],
            {"input": "x.pcdc", "output_pos": "out/", "to": "rosbag2", "cloud": True},
        ),
        "import": (
            ["-o", "x.pcdc", "paper/", "--depth", "zstd"],
            {"input": "paper/", "output": "x.pcdc", "depth": "zstd"},
        ),
        "bench": (
            ["--frames", "3", "in/", "--no-rd"],
            {"src": "in/", "frames": 3, "no_rd": True},
        ),
        "archive": (
            ["--workers", "2", "a/", "-o", "out", "b.bag", "--json", "c.mkv"],
            {"src": ["a/", "b.bag", "c.mkv"], "workers": 2, "output": "out", "json": True},
        ),
        "view": (
            ["--every", "2", "x.pcdc", "--max-frames", "5", "--threads", "3"],
            {"input": "x.pcdc", "every": 2, "max_frames": 5, "threads": 3},
        ),
        "codecs": (["--kind", "depth"], {"kind": "depth"}),
        "record": (
            ["--serial", "1", "-o", "x.pcdc", "--serial", "2", "--fps", "30"],
            {"serial": ["1", "2"], "output": "x.pcdc", "fps": 30},
        ),
    }
    assert sorted(intermixed) == sorted(commands)
    for name, (words, want) in intermixed.items():
        args = parse_args([name, *words])
        assert args.command == name
        assert {k: getattr(args, k) for k in want} == want, name


def test_encode_and_export_quiet_print_nothing_but_errors(encoded: Path, tmp_path: Path) -> None:
    made = run(
        "encode", str(sample_dir()), "-o", str(tmp_path / "q.pcdc"), "--max-frames", "3", "-q"
    )
    assert made.returncode == 0, made.stderr
    assert (made.stdout, made.stderr) == ("", "")
    assert (tmp_path / "q.pcdc").is_file()
    for extra in (["--to", "rosbag1"], ["--layout", "paper"]):
        target = tmp_path / f"out-{extra[1]}"
        target = target.with_suffix(".bag") if extra[1] == "rosbag1" else target
        exported = run("export", str(encoded), str(target), *extra, "-q")
        assert exported.returncode == 0, exported.stderr
        assert (exported.stdout, exported.stderr) == ("", "")
        assert target.exists()
    refused = run("encode", str(sample_dir()), "-o", str(tmp_path / "q.pcdc"), "-q")
    assert refused.returncode == 1
    assert "error:" in refused.stderr  # errors still say what went wrong


def test_verify_recover_and_join_quiet_print_only_problems(encoded: Path, tmp_path: Path) -> None:
    checked = run("verify", str(encoded), "-q")
    assert (checked.returncode, checked.stdout, checked.stderr) == (0, "", "")
    copy = tmp_path / "copy.pcdc"
    recovered = run("recover", str(encoded), "-o", str(copy), "-q")
    assert (recovered.returncode, recovered.stdout, recovered.stderr) == (0, "", "")
    joined = run("join", str(encoded), "-o", str(tmp_path / "joined.pcdc"), "-q")
    assert (joined.returncode, joined.stdout, joined.stderr) == (0, "", "")
    damaged = tmp_path / "damaged.pcdc"
    data = bytearray(encoded.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged.write_bytes(bytes(data))
    bad = run("verify", str(damaged), "-q")
    assert bad.returncode == 1
    assert bad.stdout == ""
    assert "problem(s)" in bad.stderr  # the problems are said, on stderr


def test_decode_ply_holds_the_float32_cloud(encoded: Path, tmp_path: Path) -> None:
    import open3d as o3d

    out = tmp_path / "clouds"
    result = run("decode", str(encoded), "-o", str(out), "--ply", "--pcd", "-q")
    assert result.returncode == 0, result.stderr
    with pcdcodec.open(encoded) as rec:
        frame = rec[2]
        points, colors = frame.to_points()
    assert colors is not None
    ply = out / "clouds" / "000002.ply"
    data = ply.read_bytes()
    head, _, body = data.partition(b"end_header\n")
    assert b"property float x\nproperty float y\nproperty float z\n" in head
    assert b"double" not in head
    assert b"property uchar red" in head
    # 12 bytes of points and 3 of color per point: the float32 cloud, nothing wider.
    assert len(body) == len(points) * 15
    rows = np.frombuffer(
        body,
        dtype=[("p", "<f4", 3), ("c", "u1", 3)],
    )
    np.testing.assert_array_equal(rows["p"], points)
    np.testing.assert_array_equal(rows["c"], colors)
    read = o3d.t.io.read_point_cloud(str(ply))  # other tools read it back the same
    np.testing.assert_array_equal(read.point.positions.numpy(), points)
    pcd = o3d.t.io.read_point_cloud(str(out / "clouds" / "000002.pcd"))
    np.testing.assert_array_equal(pcd.point.positions.numpy(), points)


def test_bench_pairs_an_input_as_encode_does(tmp_path: Path) -> None:
    from tests.conftest import SHARED_DATA

    bag = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
    if not bag.is_file():
        pytest.skip(f"{bag} is not present")
    common = ["bench", str(bag), "--frames", "1", "--no-rd", "--no-plots", "--color", "h264"]
    common += ["--depth", "zstd"]
    # The bag's one color frame is 268 ms from the depth: within 300 ms it pairs, as in encode.
    paired = run(*common, "--max-difference", "300ms")
    assert paired.returncode == 0, paired.stderr
    assert "zstd" in paired.stdout
    refused = run(*common, "--passthrough")
    assert refused.returncode == 1
    assert "pcdcodec encode" in refused.stderr
