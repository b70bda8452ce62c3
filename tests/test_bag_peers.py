"""The peers a whole bag's recording is measured against (pcdcodec.bench.bag_peers): the bag
under MCAP zstd chunks and as a ROS 1 bag with lz4 chunks keep every message; Cloudini gives
organized clouds made from real frames back within its 1 mm."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pcdcodec.bench import bag_peers
from pcdcodec.datasets import load_sample
from pcdcodec.errors import CodecUnavailableError, InputError
from pcdcodec.geometry.projector import Projector
from pcdcodec.ros.bagfile import open_reader
from pcdcodec.ros.bagwriter import BagWriter, MessageBuilder
from pcdcodec.ros.clouds import cloud_array

from .conftest import SHARED_DATA

BAGS = SHARED_DATA / "bags"
REAL_BAGS = {
    "realsense-ros1-lz4": BAGS / "realsense" / "single_depth_color_640x480.bag",
    "spot-ros1": BAGS / "spot" / "raw.bag",
    "spot-ros2-sqlite3": BAGS / "ros2-converted" / "spot_ros2_sqlite",
    "spot-ros2-mcap": BAGS / "ros2-converted" / "spot_ros2_mcap",
}
CLOUD = "/camera/depth/color/points"
NS = 1_000_000_000


def _real(name: str) -> Path:
    path = REAL_BAGS[name]
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


def _bag_messages(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, type, log time, bytes) of every message, read by rosbags, sorted."""
    reader, tmp = open_reader(path)
    try:
        rows = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages()]
        return sorted(rows)
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()


def _mcap_messages(path: Path) -> tuple[Any, list[tuple[str, str, int, bytes]], list[Any]]:
    """The header, (topic, schema, log time, bytes) of every message sorted, and the chunk
    indexes of an MCAP file."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f)
        rows = []
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            name = schema.name.replace("/msg/", "/") if schema else ""
            rows.append((channel.topic, name, message.log_time, bytes(message.data)))
            assert message.publish_time == message.log_time
        summary = reader.get_summary()
        assert summary is not None
        return reader.get_header(), sorted(rows), summary.chunk_indexes


@pytest.mark.parametrize("name", list(REAL_BAGS))
def test_mcap_zstd_keeps_every_message_of_a_real_bag(name: str, tmp_path: Path) -> None:
    bag = _real(name)
    out = tmp_path / "bag.mcap"
    result = bag_peers.mcap_zstd(bag, out)
    want = _bag_messages(bag)
    header, got, chunks = _mcap_messages(out)
    assert [(t, ty.replace("/msg/", "/"), lt, b) for t, ty, lt, b in want] == got
    assert result.messages == len(want)
    assert result.bytes_out == out.stat().st_size < result.bytes_in
    assert result.bytes_in == bag_peers.bag_bytes(bag)
    assert result.ratio == result.bytes_in / result.bytes_out
    assert chunks
    assert {c.compression for c in chunks} == {"zstd"}
    assert all(c.uncompressed_size < bag_peers.ROS_CHUNK_BYTES + 4 * 2**20 for c in chunks)
    ros1 = name.endswith("ros1") or name.endswith("lz4")
    assert header.profile == ("ros1" if ros1 else "ros2")


def test_mcap_zstd_keeps_schemas_encodings_and_connection_headers(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    bag = _real("realsense-ros1-lz4")
    bag_peers.mcap_zstd(bag, tmp_path / "bag.mcap")
    reader, tmp = open_reader(bag)
    want = {
        c.topic: (c.msgtype.replace("/msg/", "/"), c.msgdef.data, c.digest, c.ext)
        for c in reader.connections
    }
    reader.close()
    assert tmp is None
    with (tmp_path / "bag.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert len(summary.channels) == len(want) == 70
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        msgtype, text, md5, ext = want[channel.topic]
        assert (schema.name, schema.encoding, channel.message_encoding) == (
            msgtype,
            "ros1msg",
            "ros1",
        )
        assert schema.data.decode() == text
        assert channel.metadata["md5sum"] == md5
        assert channel.metadata.get("callerid") == ext.callerid
        assert channel.metadata.get("latching") == (
            None if ext.latching is None else str(ext.latching)
        )


def test_mcap_zstd_level_is_the_one_asked(tmp_path: Path) -> None:
    bag = _real("spot-ros1")
    low = bag_peers.mcap_zstd(bag, tmp_path / "1.mcap")
    high = bag_peers.mcap_zstd(bag, tmp_path / "19.mcap", level=bag_peers.ZSTD_MAX_LEVEL)
    assert (low.peer, high.peer) == ("mcap zstd 1", "mcap zstd 19")
    # zstd 19 shrinks these images by more than a third over zstd 1 (the writer's own is 3).
    assert high.bytes_out < 0.7 * low.bytes_out
    assert _mcap_messages(tmp_path / "1.mcap")[1] == _mcap_messages(tmp_path / "19.mcap")[1]
    with pytest.raises(InputError, match="zstd level must be from -7 to 22, got 23"):
        bag_peers.mcap_zstd(bag, tmp_path / "23.mcap", level=23)
    assert not (tmp_path / "23.mcap").exists()


def test_mcap_zstd_reads_a_split_ros2_bag(tmp_path: Path) -> None:
    """A ROS 2 bag of several MCAP files: every file's messages, in the files' order."""
    import yaml

    split = tmp_path / "split"
    split.mkdir()
    parts = []
    for i in range(2):
        part = tmp_path / f"part{i}"
        bag = BagWriter(part, "rosbag2", "mcap", MessageBuilder(True, "camera"))
        bag.add("/tf", "tf2_msgs/msg/TFMessage")
        for k in range(3):
            ns = (10 * i + k + 1) * NS
            bag.write("/tf", ns, bag.messages.tf(ns, np.eye(4), "world"))
        bag.close()
        (part / f"part{i}.mcap").rename(split / f"split_{i}.mcap")
        parts.append(part)
    meta = yaml.safe_load((parts[0] / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["relative_file_paths"] = ["split_0.mcap", "split_1.mcap"]
    (split / "metadata.yaml").write_text(yaml.safe_dump(meta))
    result = bag_peers.mcap_zstd(split, tmp_path / "out.mcap")
    _, got, _ = _mcap_messages(tmp_path / "out.mcap")
    assert result.messages == 6
    assert [t for _, _, t, _ in got] == [s * NS for s in (1, 2, 3, 11, 12, 13)]


def test_an_mcap_bag_is_read_one_chunk_at_a_time(tmp_path: Path) -> None:
    """Memory stays bounded whatever the bag's length: reading holds one chunk, not all."""
    import contextlib
    import tracemalloc

    from pcdcodec.bench.bag_stream import open_bag

    sample = load_sample()
    frames = [sample[i] for i in range(8)]
    bag = bag_peers.write_cloud_bag(
        tmp_path / "clouds",
        [f.depth for f in frames],
        [f.color for f in frames],
        sample.intrinsics,
        sample.depth_scale,
    )
    size = bag_peers.bag_bytes(bag)
    assert size > 78_000_000  # eight 9.8 MB clouds
    tracemalloc.start()
    try:
        with contextlib.ExitStack() as stack:
            count = sum(1 for _ in open_bag(bag, stack).records)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert count == 16
    assert peak < 0.5 * size  # a few copies of one cloud


def test_a_missing_bag_is_named(tmp_path: Path) -> None:
    missing = tmp_path / "nothere.bag"
    with pytest.raises(InputError, match=r"nothere\.bag"):
        bag_peers.mcap_zstd(missing, tmp_path / "out.mcap")
    with pytest.raises(InputError, match=r"nothere\.bag"):
        bag_peers.ros1_lz4(missing, tmp_path / "out.bag")
    assert list(tmp_path.iterdir()) == []


def _chunk_compressions(path: Path) -> set[str]:
    """The compression every chunk of a ROS 1 bag names in its record header."""
    import struct

    data = path.read_bytes()
    found = set()
    pos = data.index(b"\n") + 1
    while pos + 4 <= len(data):
        (hlen,) = struct.unpack_from("<I", data, pos)
        header = data[pos + 4 : pos + 4 + hlen]
        fields = {}
        i = 0
        while i < len(header):
            (flen,) = struct.unpack_from("<I", header, i)
            key, _, value = header[i + 4 : i + 4 + flen].partition(b"=")
            fields[key] = value
            i += 4 + flen
        (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
        if fields.get(b"op") == b"\x05":
            found.add(fields[b"compression"].decode())
        pos += 8 + hlen + dlen
    return found


def test_ros1_lz4_keeps_every_message_of_a_ros1_bag(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Reader

    bag = _real("realsense-ros1-lz4")
    out = tmp_path / "lz4.bag"
    result = bag_peers.ros1_lz4(bag, out)
    with Reader(bag) as a, Reader(out) as b:
        want = sorted((c.topic, c.msgtype, t, bytes(r)) for c, t, r in a.messages())
        got = sorted((c.topic, c.msgtype, t, bytes(r)) for c, t, r in b.messages())
        defs_a = {(c.topic, c.msgdef.data, c.digest, c.ext) for c in a.connections}
        defs_b = {(c.topic, c.msgdef.data, c.digest, c.ext) for c in b.connections}
    assert want == got
    assert defs_a == defs_b
    assert result.messages == len(want) == 135
    assert _chunk_compressions(out) == {"lz4"}


def test_ros1_lz4_converts_a_ros2_bag(tmp_path: Path) -> None:
    """A ROS 2 bag comes out as ROS 1 with every message: the same images, stamps and times."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    bag = _real("spot-ros2-sqlite3")
    out = tmp_path / "lz4.bag"
    result = bag_peers.ros1_lz4(bag, out)
    reader, tmp = open_reader(bag)
    want = {}
    for c, t, raw in reader.messages():
        msg = reader.deserialize(raw, c.msgtype)
        want[(c.topic, t)] = msg
    want_types = {(c.topic, c.msgtype) for c in reader.connections}
    reader.close()
    assert tmp is None
    store = get_typestore(Stores.ROS1_NOETIC)
    with Reader(out) as b:
        types = {(c.topic, c.msgtype) for c in b.connections}
        got = {(c.topic, t): store.deserialize_ros1(raw, c.msgtype) for c, t, raw in b.messages()}
    assert types == want_types
    assert got.keys() == want.keys()
    assert result.messages == len(want) == 9
    for key, msg in want.items():
        back = got[key]
        for name in dataclasses.asdict(msg):
            a, b = getattr(msg, name), getattr(back, name)
            if name == "header":  # ROS 1's has a seq besides
                assert (b.stamp.sec, b.stamp.nanosec, b.frame_id) == (
                    a.stamp.sec,
                    a.stamp.nanosec,
                    a.frame_id,
                )
            elif isinstance(a, np.ndarray):
                assert np.array_equal(a, b), (key, name)
            else:
                assert a == b, (key, name)
    assert _chunk_compressions(out) == {"lz4"}


# ----------------------------------------------------------------------------- Cloudini


def _cloud_bag(path: Path, fmt: str, storage: str) -> list[np.ndarray[Any, Any]]:
    """A bag of two organized XYZRGB clouds from the sample's real frames, and a /tf topic
    beside them; returns the clouds written."""
    sample = load_sample()  # real TUM frames, color paired with depth
    depths, colors = [sample[i].depth for i in (0, 7)], [sample[i].color for i in (0, 7)]
    bag_peers.write_cloud_bag(
        path, depths, colors, sample.intrinsics, sample.depth_scale, fmt=fmt, storage=storage, hz=1
    )
    projector = Projector(sample.intrinsics, depth_scale=sample.depth_scale)
    return [cloud_array(projector, d, c) for d, c in zip(depths, colors, strict=True)]


@pytest.mark.parametrize(
    ("fmt", "storage"), [("rosbag2", "mcap"), ("rosbag2", "sqlite3"), ("rosbag1", "")]
)
def test_cloudini_gives_clouds_back_within_a_millimetre(
    fmt: str, storage: str, tmp_path: Path
) -> None:
    pytest.importorskip("pureini")
    bag = tmp_path / ("clouds.bag" if fmt == "rosbag1" else "clouds")
    clouds = _cloud_bag(bag, fmt, storage)
    out = tmp_path / "cloudini.mcap"
    result = bag_peers.cloudini(bag, out)
    assert result.messages == 4
    assert result.peer == "cloudini 1 mm"
    back = list(bag_peers.cloudini_clouds(out))
    assert [(b.topic, b.log_time) for b in back] == [(CLOUD, NS), (CLOUD, 2 * NS)]
    reader, tmp = open_reader(bag)  # the clouds as the bag holds them: the ones compared
    held = [
        reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == CLOUD
    ]
    reader.close()
    assert tmp is None
    assert [bytes(m.data) for m in held] == [c.tobytes() for c in clouds]
    for want, got in zip(clouds, back, strict=True):
        pts = got.points
        assert pts.shape == want.shape == (480, 640)
        assert pts.dtype.itemsize == 32
        for axis in "xyz":
            a, b = want[axis], pts[axis]
            assert np.array_equal(np.isnan(a), np.isnan(b))
            valid = ~np.isnan(a)
            assert valid.sum() > 100_000
            err = np.abs(a[valid].astype(np.float64) - b[valid])
            assert err.max() <= 0.0005 + 1e-6  # half the 1 mm step
        # Packed colour is kept bit for bit.
        assert np.array_equal(want["rgb"], pts["rgb"].view(np.uint32))
    # Every other topic is kept byte for byte, and the whole is smaller than under zstd alone.
    zstd = bag_peers.mcap_zstd(bag, tmp_path / "z.mcap")
    _, plain, _ = _mcap_messages(tmp_path / "z.mcap")
    _, coded, _ = _mcap_messages(out)
    assert [r for r in coded if r[0] == "/tf"] == [r for r in plain if r[0] == "/tf"]
    assert {r[1] for r in coded if r[0] == CLOUD} == {
        "point_cloud_interfaces/CompressedPointCloud2"
    }
    assert result.bytes_out < zstd.bytes_out


def test_cloudini_as_its_converter_quantizes_packed_colour(tmp_path: Path) -> None:
    """``exact_fields=()`` does what cloudini_rosbag_converter does: ``rgb`` is a float32 field
    too, quantized at 1 mm, and PCL-style packed colour comes back black."""
    pytest.importorskip("pureini")
    bag = tmp_path / "clouds"
    clouds = _cloud_bag(bag, "rosbag2", "mcap")
    kept = bag_peers.cloudini(bag, tmp_path / "kept.mcap")
    lost = bag_peers.cloudini(bag, tmp_path / "lost.mcap", exact_fields=())
    assert lost.bytes_out < kept.bytes_out
    for want, got in zip(clouds, bag_peers.cloudini_clouds(tmp_path / "lost.mcap"), strict=True):
        assert want["rgb"].any()
        assert not got.points["rgb"].view(np.uint32).any()


def test_cloudini_without_pureini_says_what_to_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "pureini", None)
    with pytest.raises(CodecUnavailableError, match=r'pip install "pcdcodec\[peers\]"'):
        bag_peers.cloudini(tmp_path / "any.bag", tmp_path / "out.mcap")
    with pytest.raises(CodecUnavailableError, match="pureini"):
        list(bag_peers.cloudini_clouds(tmp_path / "out.mcap"))
