"""Bags cut into time segments: the frame index, reading one stretch by log time, and archive
segments of a bag that join into what one writer gives."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.archive import segment_plan
from pcdcodec.errors import DecodeError
from pcdcodec.registry import parse_codec_spec
from pcdcodec.sources.base import FrameIndex
from pcdcodec.sources.rosbag import RosbagSource

from .test_archive import make_input
from .test_rosbag import NS, ROS2, SPOT, _image, _info, _small, _store, write_bag

needs_bags = pytest.mark.skipif(not SPOT.is_dir(), reason=f"{SPOT} is not present")


def assert_same_frames(got: list[Any], expected: list[Any]) -> None:
    assert [f.timestamp_ns for f in got] == [f.timestamp_ns for f in expected]
    for g, e in zip(got, expected, strict=True):
        assert g.depth.dtype == e.depth.dtype
        np.testing.assert_array_equal(g.depth, e.depth)
        if e.color is None:
            assert g.color is None
        else:
            np.testing.assert_array_equal(g.color, e.color)


def assert_every_stretch_reads_alone(path: Path, **options: Any) -> int:
    """The index lists exactly the frames iteration gives, and every stretch of it read on its
    own (in a fresh source, as an archive worker does) gives those frames."""
    with pcdcodec.open_source(path, **options) as source:
        full = list(source)
        index = source.frame_index()
    assert isinstance(index, FrameIndex)
    assert len(index) == len(full) > 0
    assert index.timestamps.tolist() == [f.timestamp_ns for f in full]
    n = len(full)
    cuts = sorted({0, 1, n // 3, n // 2, n - 1, n})
    with pcdcodec.open_source(path, **options) as fresh:
        for a, b in itertools.pairwise(cuts):
            part = index.slice(a, b)
            assert part.first == a
            assert_same_frames(list(fresh.frames_at(part)), full[a:b])
        assert_same_frames(list(fresh.frames(n // 2, n - 1)), full[n // 2 : n - 1])
        assert_same_frames(list(fresh.frames_at(index)), full)
    return n


def awkward_bag(path: Path, ros2: bool) -> Path:
    """Color and depth whose header stamps trail their log times by 40 to 50 ms (more than a
    frame), with color jitter, a color frame missing, a depth frame missing, a repeated depth
    stamp and a depth stamp going back: pairing at any cut depends on state from before it."""
    store = _store(ros2)
    (color, depth), (color2, depth2) = _small(2)
    rng = np.random.default_rng(3)
    msgs = [("/cam/depth/camera_info", 1, _info(store, ros2, NS, 160, 120))]
    for k in range(24):
        ts = NS + k * 33_000_000
        lag = int(rng.integers(40_000_000, 50_000_000))
        d = depth if k % 2 else depth2
        if k != 9:
            msgs.append(("/cam/depth/image_raw", ts + lag, _image(store, ros2, ts, d, "16UC1")))
        if k == 5:  # the same stamp again, then one going back: both skipped
            msgs.append(("/cam/depth/image_raw", ts + lag + 1, _image(store, ros2, ts, d, "16UC1")))
            back = _image(store, ros2, ts - 1_000_000, d, "16UC1")
            msgs.append(("/cam/depth/image_raw", ts + lag + 2, back))
        if k != 14:
            cts = ts + int(rng.integers(-8_000_000, 8_000_000))
            c = color if k % 3 else color2
            msgs.append(("/cam/color/image_raw", cts + lag, _image(store, ros2, cts, c, "rgb8")))
    msgs.sort(key=lambda m: m[1])
    return write_bag(path, msgs, ros2=ros2)


@pytest.mark.parametrize("ros2", [False, True])
def test_awkward_image_bag_stretches_read_alone(tmp_path: Path, ros2: bool) -> None:
    bag = awkward_bag(tmp_path / ("s2" if ros2 else "s.bag"), ros2)
    with pcdcodec.open_source(bag) as source:
        frames = list(source)
        assert source.dropped == {"color": 1, "depth": 1}
        assert source.out_of_order == 2
    assert len(frames) == 22
    assert assert_every_stretch_reads_alone(bag) == 22
    assert assert_every_stretch_reads_alone(bag, color_topic="") == 23  # depth only
    assert assert_every_stretch_reads_alone(bag, max_frames=10) == 10


def test_ros1_index_from_first_bytes_equals_one_from_whole_messages(tmp_path: Path) -> None:
    """Uncompressed ROS 1 bags are indexed from each message's first bytes; compressed ones
    (and ROS 2 bags) from the messages read whole. Both give the same index."""
    from rosbags.rosbag1 import Reader, Writer

    from pcdcodec.ros import bagindex as _bagindex

    bag = awkward_bag(tmp_path / "plain.bag", False)
    packed = tmp_path / "lz4.bag"
    writer = Writer(packed)
    writer.set_compression(Writer.CompressionFormat.LZ4)
    with Reader(bag) as reader, writer:
        conns = {
            c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
            for c in reader.connections
        }
        for c, t, raw in reader.messages():
            writer.write(conns[c.id], t, raw)
        images = [c for c in reader.connections if "image" in c.topic]
        fast = _bagindex.ros1_index_stamps(reader, images)
        whole = [(c, t, _bagindex.ros1_stamp(raw)) for c, t, raw in reader.messages(images)]
    assert fast == whole
    with Reader(packed) as reader:
        assert _bagindex.ros1_index_stamps(reader, reader.connections) is None
    with RosbagSource(bag) as a, RosbagSource(packed) as b:
        np.testing.assert_array_equal(a.frame_index().rows, b.frame_index().rows)
    assert assert_every_stretch_reads_alone(packed) == 22


@pytest.mark.parametrize(("to", "storage"), [("rosbag1", "mcap"), ("rosbag2", "sqlite3")])
def test_pointcloud2_bag_stretches_read_alone(tmp_path: Path, to: str, storage: str) -> None:
    seq = make_input(tmp_path / "seq", 0, 5)
    bag = tmp_path / ("c.bag" if to == "rosbag1" else "c2")
    pcdcodec.export_bag(seq, bag, to=to, storage=storage, images=False, cloud=True)
    assert assert_every_stretch_reads_alone(bag) == 5


@needs_bags
@pytest.mark.parametrize(
    "bag",
    [
        SPOT / "raw.bag",
        SPOT / "compressed.bag",
        SPOT / "compressedDepth.bag",
        ROS2 / "spot_ros2_sqlite",
        ROS2 / "spot_ros2_mcap",
        ROS2 / "rs_ros2_mcap",
    ],
    ids=lambda p: p.name,
)
def test_real_bags_stretches_read_alone(bag: Path) -> None:
    # The RealSense re-packaging's one color frame is 30 ms from either depth frame.
    options = {"color_topic": ""} if bag.name == "rs_ros2_mcap" else {}
    assert assert_every_stretch_reads_alone(bag, **options) >= 1


def test_an_index_from_another_bag_is_refused(tmp_path: Path) -> None:
    a = awkward_bag(tmp_path / "a.bag", False)
    seq = make_input(tmp_path / "seq", 0, 3)
    b = tmp_path / "b.bag"
    pcdcodec.export_bag(seq, b, images=True, camera_info=True)
    with RosbagSource(a) as source:
        index = source.frame_index()
    with RosbagSource(b, color_topic="") as other, pytest.raises(DecodeError, match="index"):
        list(other.frames_at(index.slice(0, 3)))


def test_segment_plan() -> None:
    mb = 1_000_000
    # Too short for two segments: one task.
    assert segment_plan(300, 3000 * mb) == [(0, None)]
    assert segment_plan(None, 10**12) == [(0, None)]
    assert segment_plan(20, 10, segment_frames=20) == [(0, None)]
    # By default at least 300 frames; 10 MB frames: 1,000 frames are 10 GB, cut into 4 of 250
    # ... rounded to the 30-frame keyframe interval: 270, 270, 270, 190.
    plan = segment_plan(1000, 1000 * 10 * mb, keyframes=30)
    assert plan == [(0, 270), (270, 540), (540, 810), (810, 1000)]
    # Small frames: about 1 GB per segment (0.1 MB frames: 10,000 frames).
    plan = segment_plan(25_000, 25_000 * mb // 10, keyframes=30)
    assert len(plan) == 3
    assert all((b or 0) % 30 == 0 for _, b in plan[:-1])
    assert max((b or 0) - a for a, b in plan) <= 10_020
    # Given: at most that many frames, on keyframes where a segment spans a keyframe interval.
    assert segment_plan(100, 0, segment_frames=45, keyframes=30) == [
        (0, 30),
        (30, 60),
        (60, 90),
        (90, 100),
    ]
    assert segment_plan(6, 0, segment_frames=4, keyframes=30) == [(0, 3), (3, 6)]


def test_archive_segments_of_a_bag_equal_one_writer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.archive import archive

    bag = tmp_path / "lab" / "long.bag"
    bag.parent.mkdir()
    seq = make_input(tmp_path / "seq", 0, 9)
    pcdcodec.export_bag(seq, bag, images=True, camera_info=True)
    color = parse_codec_spec("h264:gop=3", "color")
    reference = tmp_path / "one.pcdc"
    pcdcodec.encode(bag, reference, color=color)

    read_alone: list[int] = []
    original = RosbagSource.frames_at

    def recording(self: RosbagSource, index: FrameIndex) -> Any:
        read_alone.append(index.first)
        return original(self, index)

    monkeypatch.setattr(RosbagSource, "frames_at", recording)
    out = tmp_path / "out"
    summary = archive(
        [bag.parent],
        out,
        workers=1,
        processes=False,
        color=color,
        segment_frames=3,
        verify=True,
        progress=False,
    )
    assert summary.ok, summary.to_text()
    (item,) = summary.items
    assert item.state == "verified"
    assert item.segments == 3
    assert item.frames == 9
    assert sorted(read_alone) == [0, 3, 6]  # every segment read through the index
    with pcdcodec.open(out / "lab" / "long.pcdc") as joined, pcdcodec.open(reference) as one:
        assert joined.verify().ok
        assert len(joined) == len(one) == 9
        np.testing.assert_array_equal(joined.timestamps, one.timestamps)
        # Every segment starts on a keyframe, and keyframes stay at most a keyframe interval
        # (3 frames) apart, as from the one writer.
        assert {0, 3, 6} <= set(joined.keyframes)
        for keys in (joined.keyframes, one.keyframes):
            assert keys[0] == 0
            assert max(np.diff([*keys, 9])) <= 3
        for a, b in zip(joined, one, strict=True):
            assert a.depth.dtype == b.depth.dtype
            np.testing.assert_array_equal(a.depth, b.depth)
            assert a.color is not None
            assert b.color is not None
            assert pcdcodec.metrics.psnr(a.color, b.color) > 35


def test_a_short_bag_stays_one_task_without_an_index(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.archive import archive

    bag = tmp_path / "short.bag"
    pcdcodec.export_bag(make_input(tmp_path / "seq", 0, 4), bag, images=True)

    def no_index(self: RosbagSource) -> FrameIndex:
        raise AssertionError("a bag shorter than a segment needs no index")

    monkeypatch.setattr(RosbagSource, "frame_index", no_index)
    summary = archive([bag], tmp_path / "out", workers=1, processes=False, progress=False)
    assert summary.ok, summary.to_text()
    assert summary.items[0].segments == 1
    assert summary.items[0].frames == 4


RS_BAG = SPOT.parent / "realsense" / "single_depth_color_640x480.bag"


def long_realsense_bag(dst: Path, frames: int) -> Path:
    """The real RealSense recording with its depth and color images repeated ``frames`` times
    at 30 Hz (their header stamps rewritten), color 3 ms late in stamp and logged up to a frame
    late, and one color frame missing: every other message is copied as recorded."""
    import struct

    from rosbags.rosbag1 import Reader, Writer

    writer = Writer(dst)
    writer.set_compression(Writer.CompressionFormat.LZ4)  # as the recording is
    with Reader(RS_BAG) as reader, writer:
        conns, images, messages = {}, {}, []
        for c in reader.connections:
            conns[c.id] = writer.add_connection(
                c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest
            )
        for c, t, raw in reader.messages():
            if c.topic.endswith("image/data"):
                images.setdefault("Depth" if "Depth" in c.topic else "Color", (c.id, raw))
            else:
                messages.append((t, c.id, raw))
        base, period = 1_700_000_000 * NS, 33_333_333
        for k in range(frames):
            for kind, stamp, log in (
                ("Depth", base + k * period, 1_000_000 + k * period),
                (
                    "Color",
                    base + k * period + 3_000_000,
                    1_000_000 + k * period + (k % 3) * 15_000_000,
                ),
            ):
                if kind == "Color" and k == frames // 2:
                    continue
                cid, raw = images[kind]
                buf = bytearray(raw)
                struct.pack_into("<III", buf, 0, k, stamp // NS, stamp % NS)
                messages.append((log, cid, bytes(buf)))
        for t, cid, raw in sorted(messages, key=lambda m: m[0]):
            writer.write(conns[cid], t, raw)
    return dst


@pytest.mark.skipif(not RS_BAG.is_file(), reason=f"{RS_BAG} is not present")
def test_realsense_bag_segments(tmp_path: Path) -> None:
    from pcdcodec.archive import archive
    from pcdcodec.sources.realsense import RealSenseBagSource

    bag = long_realsense_bag(tmp_path / "rs.bag", 7)
    with pcdcodec.open_source(bag) as source:
        assert isinstance(source, RealSenseBagSource)
    # The depth frame whose color is missing finds no partner within 20 ms (the rule of every
    # reader): 6 frames, with any tolerance under a frame period.
    assert assert_every_stretch_reads_alone(bag) == 6
    assert assert_every_stretch_reads_alone(bag, max_difference=4_000_000) == 6
    with pcdcodec.open_source(bag) as source:
        assert len(list(source)) == 6
        assert source.dropped == {"color": 0, "depth": 1}

    reference = tmp_path / "one.pcdc"
    pcdcodec.encode(bag, reference, color="ffv1")
    out = tmp_path / "out"
    summary = archive(
        [bag], out, workers=1, processes=False, color="ffv1", segment_frames=3, progress=False
    )
    assert summary.ok, summary.to_text()
    assert summary.items[0].segments == 2
    with pcdcodec.open(out / "rs.pcdc") as joined, pcdcodec.open(reference) as one:
        assert joined.verify().ok
        np.testing.assert_array_equal(joined.timestamps, one.timestamps)
        assert joined.color_intrinsics == one.color_intrinsics
        for a, b in zip(joined, one, strict=True):
            np.testing.assert_array_equal(a.depth, b.depth)
            np.testing.assert_array_equal(a.color, b.color)  # ffv1 is lossless
