"""One pairing rule for every reader: ROS bags, RealSense .bag, Azure Kinect .mkv and TUM lists
pair color with depth within the same tolerance (20 ms by default, ``max_difference``,
``--max-difference``) and report the same images left without a partner."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.errors import InputError
from pcdcodec.sources.base import detect_kind

NS = 1_000_000_000
PERIOD = 33_333_000
#: color minus depth time per frame (ns); frame 2 has no color image
OFFSETS: list[int | None] = [5_000_000, 5_000_000, None, 5_000_000, 12_000_000]
#: (frames, dropped) at the default tolerance (20 ms) and at 10 ms
DEFAULT = (4, {"color": 0, "depth": 1})
TIGHT = (3, {"color": 1, "depth": 2})


def _rosbag(path: Path) -> Path:
    from .test_rosbag import _image, _info, _store, write_bag

    store = _store(False)
    rng = np.random.default_rng(1)
    depth = rng.integers(0, 4000, (12, 16)).astype(np.uint16)
    color = rng.integers(0, 256, (12, 16, 3)).astype(np.uint8)
    msgs = [("/cam/depth/camera_info", 1, _info(store, False, NS, 16, 12))]
    for k, off in enumerate(OFFSETS):
        ts = NS + k * PERIOD
        msgs.append(("/cam/depth/image_raw", ts, _image(store, False, ts, depth, "16UC1")))
        if off is not None:
            msgs.append(
                ("/cam/color/image_raw", ts + off, _image(store, False, ts + off, color, "rgb8"))
            )
    msgs.sort(key=lambda m: m[1])
    return write_bag(path / "s.bag", msgs)


def _realsense(path: Path) -> Path:
    from .camera_file_fuzz import rs_spec, write_bag

    spec = rs_spec(frames=len(OFFSETS))
    colors = [r for r in spec.records if r.topic.endswith("Color_0/image/data")]
    depths = [r for r in spec.records if r.topic.endswith("Depth_0/image/data")]
    for k, (off, c, d) in enumerate(zip(OFFSETS, colors, depths, strict=True)):
        d.msg.header.stamp.sec, d.msg.header.stamp.nanosec = divmod(NS + k * PERIOD, NS)
        if off is None:
            spec.records.remove(c)
        else:
            c.msg.header.stamp.sec, c.msg.header.stamp.nanosec = divmod(NS + k * PERIOD + off, NS)
    write_bag(spec, path / "rs.bag")
    return path / "rs.bag"


def _azure(path: Path) -> Path:
    from .camera_file_fuzz import _block, mkv_spec

    spec = mkv_spec(len(OFFSETS))
    for off, cluster in zip(OFFSETS, spec.clusters, strict=True):
        blocks = cluster[1]
        color = next(b for b in blocks if b[0] == 0xA3 and b[1][0] & 0x7F == 1)
        if off is None:
            blocks.remove(color)
        else:
            blocks[blocks.index(color)] = _block(1, off // 1000, color[1][4:])
    out = path / "ak.mkv"
    out.write_bytes(spec.to_bytes())
    return out


def _tum(path: Path) -> Path:
    import cv2

    root = path / "tum"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    rng = np.random.default_rng(2)
    rgb, depth = [], []
    for k, off in enumerate(OFFSETS):
        ts = NS + k * PERIOD
        cv2.imwrite(
            str(root / "depth" / f"{k}.png"), rng.integers(1, 4000, (12, 16)).astype(np.uint16)
        )
        depth.append(f"{ts / NS:.6f} depth/{k}.png")
        if off is not None:
            cv2.imwrite(
                str(root / "rgb" / f"{k}.png"), rng.integers(0, 256, (12, 16, 3)).astype(np.uint8)
            )
            rgb.append(f"{(ts + off) / NS:.6f} rgb/{k}.png")
    (root / "depth.txt").write_text("\n".join(depth) + "\n")
    (root / "rgb.txt").write_text("\n".join(rgb) + "\n")
    return root


READERS = {"rosbag": _rosbag, "realsense": _realsense, "azure_kinect": _azure, "folder": _tum}


def _read(path: Path, **options: Any) -> tuple[int, dict[str, int]]:
    if path.is_dir():
        options["depth_scale"] = 1000.0  # the lists are not TUM's own: no dataset scale
    with pcdcodec.open_source(path, **options) as src:
        frames = list(src)
        return len(frames), src.dropped


@pytest.mark.parametrize("kind", list(READERS))
def test_every_reader_pairs_within_the_same_limit_and_reports_drops(
    tmp_path: Path, kind: str
) -> None:
    path = READERS[kind](tmp_path)
    assert detect_kind(path) == kind
    assert _read(path) == DEFAULT
    assert _read(path, max_difference=10_000_000) == TIGHT
    assert _read(path, max_difference=40_000_000)[0] == 4  # still each image once


@pytest.mark.parametrize("kind", ["realsense", "folder"])
def test_cli_max_difference_takes_a_unit(
    tmp_path: Path, kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    path = READERS[kind](tmp_path)
    out = tmp_path / "x.pcdc"
    flags = ["--color", "ffv1", "--fx", "10", "--fy", "10", "--cx", "8", "--cy", "6"]
    flags += ["--depth-scale", "1000"]
    assert main(["encode", str(path), "-o", str(out), *flags, "--max-difference", "10ms"]) == 0
    printed = capsys.readouterr().out
    assert "dropped      1 color and 2 depth images without a partner" in printed
    with pcdcodec.open(out) as rec:
        assert len(rec) == 3
    assert main(["encode", str(path), "-o", str(out), *flags, "--overwrite"]) == 0
    assert "dropped      0 color and 1 depth" in capsys.readouterr().out
    assert main(["encode", str(path), "-o", str(out), *flags, "--max-difference", "10"]) == 1
    assert "--max-difference '10' is not a duration with its unit" in capsys.readouterr().err


def test_the_error_of_no_pairs_names_the_cli_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    path = _rosbag(tmp_path)
    out = tmp_path / "x.pcdc"
    with pytest.raises(InputError, match=r"--max-difference 150ms on the command line, max_diff"):
        pcdcodec.encode(path, out, max_difference=0)
    assert main(["encode", str(path), "-o", str(out), "--max-difference", "0"]) == 1
    assert "a larger pairing tolerance (--max-difference 150ms" in capsys.readouterr().err


def test_a_max_difference_of_seconds_is_refused_with_the_unit() -> None:
    from pcdcodec.sync import as_max_difference, parse_duration

    assert parse_duration("150ms") == parse_duration("0.15s") == 150_000_000
    assert parse_duration("500us") == 500_000
    for bad in ("150", "-1ms", "2h", "0.5ns"):
        with pytest.raises(InputError):
            parse_duration(bad)
    with pytest.raises(pcdcodec.InputTypeError, match="20 ms is 20_000_000"):
        as_max_difference(0.02)
