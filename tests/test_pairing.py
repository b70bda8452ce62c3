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


def _rosbag(path: Path, ros2: bool = False) -> Path:
    from .test_rosbag import _image, _info, _store, write_bag

    store = _store(ros2)
    rng = np.random.default_rng(1)
    depth = rng.integers(0, 4000, (12, 16)).astype(np.uint16)
    color = rng.integers(0, 256, (12, 16, 3)).astype(np.uint8)
    msgs = [("/cam/depth/camera_info", 1, _info(store, ros2, NS, 16, 12))]
    for k, off in enumerate(OFFSETS):
        ts = NS + k * PERIOD
        msgs.append(("/cam/depth/image_raw", ts, _image(store, ros2, ts, depth, "16UC1")))
        if off is not None:
            msgs.append(
                ("/cam/color/image_raw", ts + off, _image(store, ros2, ts + off, color, "rgb8"))
            )
    msgs.sort(key=lambda m: m[1])
    return write_bag(path / ("s2" if ros2 else "s.bag"), msgs, ros2=ros2, store=store)


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


# -- each image keeps its own stamp -------------------------------------------------------


def _listed_ns(path: Path) -> list[int]:
    """The stamps of a TUM list (rgb.txt, depth.txt) as int nanoseconds, read exactly."""
    from decimal import Decimal

    lines = [line.split()[0] for line in path.read_text().splitlines()]
    return [int(Decimal(t) * NS) for t in lines if t and not t.startswith("#")]


def _own_stamps_survive_encode_and_decode(
    path: Path, tmp_path: Path, color: list[int], depth: list[int], **options: Any
) -> None:
    """The source's frames carry each image's own stamp (the frame's time stays the depth's),
    and so do the recording and the rgb.txt/depth.txt that decode writes."""
    from pcdcodec.cli import main

    with pcdcodec.open_source(path, **options) as src:
        frames = list(src)
    assert [f.color_timestamp_ns for f in frames] == color
    assert [f.depth_timestamp_ns for f in frames] == depth
    assert [f.timestamp_ns for f in frames] == depth
    out = tmp_path / "own.pcdc"
    pcdcodec.encode(path, out, color="ffv1", overwrite=True, **options)
    with pcdcodec.open(out) as rec:
        assert [f.color_timestamp_ns for f in rec] == color
        assert [f.depth_timestamp_ns for f in rec] == depth
    decoded = tmp_path / "decoded"
    assert main(["decode", str(out), "-o", str(decoded), "-q"]) == 0
    assert _listed_ns(decoded / "rgb.txt") == color
    assert _listed_ns(decoded / "depth.txt") == depth


def _stamps(offsets: list[int | None]) -> tuple[list[int], list[int]]:
    """The color and depth stamps of the frames paired at the default tolerance."""
    kept = [(NS + k * PERIOD + off, NS + k * PERIOD) for k, off in enumerate(offsets) if off]
    return [c for c, _ in kept], [d for _, d in kept]


@pytest.mark.parametrize("kind", ["rosbag", "rosbag2", "realsense", "azure_kinect"])
def test_each_image_keeps_its_own_stamp_through_pairing(tmp_path: Path, kind: str) -> None:
    options: dict[str, Any] = {}
    path = _rosbag(tmp_path, ros2=True) if kind == "rosbag2" else READERS[kind](tmp_path)
    if kind.startswith("rosbag"):
        options = {"intrinsics": pcdcodec.CameraIntrinsics(16, 12, 10.0, 10.0, 8.0, 6.0)}
    color, depth = _stamps(OFFSETS)
    if kind == "azure_kinect":
        # The file's stamps start at its own start time: compare the offsets within each pair.
        with pcdcodec.open_source(path) as src:
            frames = list(src)
        start = frames[0].depth_timestamp_ns - depth[0]
        color, depth = [c + start for c in color], [d + start for d in depth]
    _own_stamps_survive_encode_and_decode(path, tmp_path, color, depth, **options)
    if kind != "azure_kinect":
        # A stretch read through the frame index keeps them too.
        with pcdcodec.open_source(path, **options) as src:
            later = list(src.frames(2))
        assert [f.color_timestamp_ns for f in later] == color[2:]
        assert [f.depth_timestamp_ns for f in later] == depth[2:]


def test_the_real_realsense_bag_keeps_the_color_images_own_stamp(tmp_path: Path) -> None:
    from .conftest import SHARED_DATA

    bag = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"
    if not bag.exists():
        pytest.skip(f"{bag} is not present")
    # The bag's header stamps (read with rosbags): color 360.713523 s, depth 360.815089 s.
    _own_stamps_survive_encode_and_decode(
        bag, tmp_path, [360_713_523_000], [360_815_089_000], max_difference=150_000_000
    )


# -- depth only, and a source whose every image was dropped -------------------------------


@pytest.mark.parametrize("kind", ["rosbag", "realsense", "azure_kinect"])
def test_every_paired_input_records_depth_only_as_the_no_pairs_error_says(
    tmp_path: Path, kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Pairing within 0 ns drops every image; the error's advice, --depth-only (and its Python
    option), then records each depth image without color."""
    from pcdcodec.cli import main

    path = READERS[kind](tmp_path)
    flags = ["--color", "ffv1", "--fx", "10", "--fy", "10", "--cx", "8", "--cy", "6"]
    out = tmp_path / "d.pcdc"
    assert main(["encode", str(path), "-o", str(out), *flags, "--max-difference", "0ms"]) == 1
    err = capsys.readouterr().err
    assert "every image was dropped" in err
    assert "record depth only (--depth-only on the command line" in err
    assert main(["encode", str(path), "-o", str(out), *flags, "--depth-only"]) == 0
    with pcdcodec.open(out) as rec:
        assert len(rec) == len(OFFSETS)
        assert rec[0].color is None
    option: dict[str, Any] = {"color": False} if kind == "azure_kinect" else {"color_topic": ""}
    camera = {"intrinsics": pcdcodec.CameraIntrinsics(16, 12, 10.0, 10.0, 8.0, 6.0)}
    if kind != "rosbag":
        camera = {}
    with pytest.raises(InputError, match=f"{next(iter(option))}=.* in Python"):
        pcdcodec.encode(path, out, max_difference=0, overwrite=True, **camera)
    with pcdcodec.open_source(path, **option) as src:
        frames = list(src)
        assert not src.has_color
        assert src.color_intrinsics is None
        assert src.dropped == {"color": 0, "depth": 0}
        # the color stream: kept as it came, or listed as left out
        names = [s.name for s in src.left_out] + [t.topic for t in src.kept_topics()]
        assert any("color" in name.lower() for name in names)
    assert len(frames) == len(OFFSETS)
    assert all(f.color is None for f in frames)


def test_topic_flags_name_what_each_input_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    rs, ak = _realsense(tmp_path), _azure(tmp_path)
    out = str(tmp_path / "x.pcdc")
    assert main(["encode", str(ak), "-o", out, "--color-topic", ""]) == 1
    err = capsys.readouterr().err
    assert "--color-topic applies to bags" in err
    assert "its depth alone: --depth-only" in err
    assert main(["encode", str(rs), "-o", out, "--depth-topic", "/d"]) == 1
    assert "--depth-topic applies to ROS bags" in capsys.readouterr().err
    assert main(["encode", str(rs), "-o", out, "--color", "ffv1", "--color-topic", ""]) == 0
    with pcdcodec.open(out) as rec:
        assert rec[0].color is None
    with pytest.raises(InputError, match="has no color topic '/nope'; its color topics: /dev"):
        pcdcodec.open_source(rs, color_topic="/nope")
    # An option a reader does not take is a public InputError naming the file.
    with pytest.raises(InputError) as caught:
        pcdcodec.open_source(rs, color=False)
    assert type(caught.value) is InputError
    assert str(caught.value).startswith(f"{str(rs)!r}: the realsense reader takes no option")


@pytest.mark.parametrize("call", ["write_frames", "write_source"])
def test_writing_a_source_whose_every_image_was_dropped_says_so(tmp_path: Path, call: str) -> None:
    """The README's recipe (open_source, then rec.write_frames(src)) on a bag whose streams lie
    farther apart than the tolerance wrote an empty recording without a word."""
    path = _realsense(tmp_path)
    out = tmp_path / "w.pcdc"
    for tolerance in (0, None):
        options = {} if tolerance is None else {"max_difference": tolerance}
        with pcdcodec.open_source(path, **options) as src:
            rec = pcdcodec.open(
                out,
                "w",
                kept_topics=src.kept_topics(),
                intrinsics=src.intrinsics,
                depth_scale=src.depth_scale,
                color_intrinsics=src.color_intrinsics,
                depth_to_color=src.depth_to_color,
                color="ffv1",
                overwrite=True,
            )
            with rec:
                if tolerance is None:  # a source that pairs its images is written as before
                    assert getattr(rec, call)(src) == DEFAULT[0]
                    continue
                with pytest.raises(InputError, match=r"gave no frames: every image was dropped"):
                    getattr(rec, call)(src)
