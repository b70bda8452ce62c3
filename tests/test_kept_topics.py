"""A bag's other topics kept as they came: every message of every topic not made into frames
is in the recording with its bytes, log time, type, definition and connection facts, in its
own MCAP channel, checked like the camera streams (``docs/bags.md``)."""

from __future__ import annotations

import collections
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.errors import DecodeError, IncompleteRecordingWarning, InputError
from pcdcodec.ros.kept import KeptMessage, KeptTopic
from pcdcodec.sources import open_source

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}


def _bag(name: str) -> Path:
    path = BAGS / name
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


def _bag_messages(path: Path, topics: set[str]) -> dict[str, list[tuple[int, bytes]]]:
    from rosbags.highlevel import AnyReader

    from pcdcodec.ros.bagfile import open_reader

    reader, tmp = open_reader(path)
    assert isinstance(reader, AnyReader)
    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    try:
        wanted = [c for c in reader.connections if c.topic in topics]
        for c, t, raw in reader.messages(connections=wanted):
            out[c.topic].append((t, bytes(raw)))
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()
    return dict(out)


@pytest.mark.parametrize(
    "bag", ["spot/raw.bag", "ros2-converted/spot_ros2_sqlite", "ros2-converted/spot_ros2_mcap"]
)
def test_every_other_topic_of_a_real_bag_is_kept_byte_for_byte(bag: str, tmp_path: Path) -> None:
    path = _bag(bag)
    with open_source(path, max_difference=10**12) as src:
        # The camera topics' channels (t.camera) hold the frames' messages: not kept as is.
        kept = [t for t in src.kept_topics() if not t.camera]
        frame_topics = {src.depth_topic, src.color_topic} - {None, ""}
        every = {s.name for s in src.input_streams()}
    assert {t.topic for t in kept} == every - frame_topics
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(path, out, intrinsics=SPOT_CAMERA, max_difference=10**12)
    assert summary.left_out == []
    want = _bag_messages(path, {t.topic for t in kept})
    assert {k["name"]: k["messages"] for k in summary.kept} == {t: len(v) for t, v in want.items()}
    with pcdcodec.open(out) as rec:
        assert rec.format_version == 4
        assert {t.topic for t in rec.kept_topics} == set(want)
        assert rec.kept_topics == kept  # type, definition, encoding, connection facts
        got: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
        for m in rec.kept_messages():
            got[m.topic.topic].append((m.log_time, m.data))
        assert dict(got) == want


def test_kept_channels_are_standard_mcap_with_schemas(tmp_path: Path) -> None:
    """Other MCAP tools see each kept topic in its own encoding with its schema (kept images
    as they came: compressed ones are pcdcodec's own, tests/test_kept_compressed.py)."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    path = _bag("ros2-converted/spot_ros2_mcap")
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(path, out, intrinsics=SPOT_CAMERA, kept_images="raw")
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = [c for c in summary.channels.values() if "pcdcodec.kept" in c.metadata]
        # The camera topics' channels (envelopes, in an encoding of their own, which other
        # tools leave alone, and raw messages) are given back by Recording.camera_messages.
        assert any(c.message_encoding == "pcdcodec.envelope" for c in channels)
        kept = {c.topic: c for c in channels if "pcdcodec.camera" not in c.metadata}
        assert kept
        for ch in kept.values():
            schema = summary.schemas[ch.schema_id]
            assert ch.message_encoding == "cdr"
            assert schema.encoding == "ros2msg"
            assert schema.name == "sensor_msgs/msg/Image" or "CompressedImage" in schema.name
        store = get_typestore(Stores.ROS2_HUMBLE)
        seen = 0
        for _schema, _channel, message in reader.iter_messages(topics=list(kept)):
            msg = store.deserialize_cdr(
                message.data, "sensor_msgs/msg/" + _schema.name.split("/")[-1]
            )
            assert msg.header.frame_id is not None
            seen += 1
        assert seen == len(kept)


def test_an_earlier_reader_refuses_a_file_with_kept_topics(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from pcdcodec.recording import _index

    out = tmp_path / "x.pcdc"
    pcdcodec.encode(_bag("spot/raw.bag"), out, intrinsics=SPOT_CAMERA)
    plain = tmp_path / "plain.pcdc"
    pcdcodec.encode(_bag("spot/raw.bag"), plain, intrinsics=SPOT_CAMERA, keep_topics=False)
    monkeypatch.setattr(_index, "FORMAT_VERSION", 2)  # what pcdcodec read before
    with pytest.raises(DecodeError, match="format version 4, newer"):
        pcdcodec.open(out)
    with pcdcodec.open(plain) as rec:  # nothing kept: written as before, still read
        assert rec.format_version in (1, 2)
        assert rec.kept_topics == []


def test_patterns_choose_the_kept_topics(tmp_path: Path) -> None:
    path = _bag("ros2-converted/spot_ros2_sqlite")
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(
        path,
        out,
        intrinsics=SPOT_CAMERA,
        include_topics="/spot/camera/*",
        exclude_topics=["*mono*"],
    )
    kept = {k["name"] for k in summary.kept}
    assert kept == {
        "/spot/camera/frontleft/image",
        "/spot/camera/frontleft/image/compressed",
        "/spot/camera/hand_color/image",
        "/spot/camera/hand_color/image/compressed",
    }
    left = {k["name"] for k in summary.left_out}
    assert "/spot/camera/hand_mono/image" in left
    assert "/spot/depth/frontleft/image/compressedDepth" in left
    with pcdcodec.open(out) as rec:
        assert {t.topic for t in rec.kept_topics} == kept


def _topic(name: str = "/imu") -> KeptTopic:
    return KeptTopic(name, "sensor_msgs/msg/Imu", "ros2msg", "float64 x\n", "cdr", {"a": "b"})


def _write(path: Path, messages: list[KeptMessage], topics: list[KeptTopic]) -> None:
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
    depth = np.arange(48, dtype=np.uint16).reshape(6, 8)
    with pcdcodec.open(path, "w", intrinsics=cam, color=None, kept_topics=topics) as w:
        for k in range(3):
            w.write(None, depth + k, 1_000_000 * (k + 1))
        for m in messages:
            w.write_message(m)


def test_messages_at_one_time_and_large_streams_are_all_kept(tmp_path: Path) -> None:
    t = _topic()
    # Two messages at one log time, and over 2 MiB of IMU-like samples: several zstd chunks.
    messages = [KeptMessage(t, 5, b"first"), KeptMessage(t, 5, b"second")] + [
        KeptMessage(t, 10 + k, np.sin(np.arange(375) * 0.01 + k * 0.001).tobytes(), 7 + k)
        for k in range(800)
    ]
    out = tmp_path / "x.pcdc"
    _write(out, messages, [t])
    with pcdcodec.open(out) as rec:
        assert rec.format_version == 4
        got = list(rec.kept_messages())
        assert [(m.log_time, m.published, m.data) for m in got] == [
            (m.log_time, m.published, m.data) for m in messages
        ]
        assert rec.kept_counts() == {"/imu": len(messages)}
        assert len(rec) == 3
    # The kept messages are in compressed chunks: the file is smaller than what they hold.
    assert out.stat().st_size < sum(len(m.data) for m in messages)


def test_writer_refuses_what_it_cannot_keep(tmp_path: Path) -> None:
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
    with pytest.raises(InputError, match="name of a channel pcdcodec writes"):
        pcdcodec.open(
            tmp_path / "a.pcdc", "w", intrinsics=cam, kept_topics=[_topic("/camera/depth")]
        )
    with (
        pcdcodec.open(
            tmp_path / "b.pcdc", "w", intrinsics=cam, color=None, kept_topics=[_topic()]
        ) as w,
        pytest.raises(InputError, match="not one of the kept topics"),
    ):
        w.write_message(KeptMessage(_topic("/odom"), 1, b"x"))
    with (
        pcdcodec.open(tmp_path / "c.pcdc", "w", intrinsics=cam, color=None) as w,
        pytest.raises(InputError, match="keeps no other topics"),
    ):
        w.write_message(KeptMessage(_topic(), 1, b"x"))


def test_write_source_refuses_to_drop_a_bags_other_topics(tmp_path: Path) -> None:
    path = _bag("spot/raw.bag")
    with open_source(path, intrinsics=SPOT_CAMERA) as src:
        cam = src.intrinsics
        with (
            pcdcodec.open(tmp_path / "x.pcdc", "w", intrinsics=cam, color=None) as w,
            pytest.raises(InputError, match="not opened to keep"),
        ):
            w.write_source(src)
        with pcdcodec.open(
            tmp_path / "y.pcdc", "w", intrinsics=cam, color=None, kept_topics=src.kept_topics()
        ) as w:
            assert w.write_source(src) == 1
    with pcdcodec.open(tmp_path / "y.pcdc") as rec:
        assert sum(rec.kept_counts().values()) == 3


def _kept_chunk_offset(path: Path) -> int:
    from pcdcodec.recording import _index

    with open(path, "rb") as f:
        index = _index.load(f)
    topic = next(c.topic for c in index.channels.values() if "pcdcodec.kept" in c.metadata)
    return int(index.offsets[topic][0])


def test_a_damaged_kept_chunk_is_an_error_never_wrong_bytes(tmp_path: Path) -> None:
    t = _topic()
    messages = [KeptMessage(t, 10 + k, bytes([k % 251]) * 200) for k in range(50)]
    out = tmp_path / "x.pcdc"
    _write(out, messages, [t])
    at = _kept_chunk_offset(out)
    data = bytearray(out.read_bytes())
    data[at + 80] ^= 0x40  # inside the compressed data
    bad = tmp_path / "bad.pcdc"
    bad.write_bytes(bytes(data))
    with pytest.raises(DecodeError, match=r"bad\.pcdc"), pcdcodec.open(bad) as rec:
        list(rec.kept_messages())


def test_kept_messages_changed_unseen_by_crc_fail_the_seal(tmp_path: Path) -> None:
    """A kept message swapped for another (a valid chunk, wrong content) fails the seal."""
    from pcdcodec.recording import _kept

    t = _topic()
    out = tmp_path / "x.pcdc"
    _write(out, [KeptMessage(t, 10, b"a"), KeptMessage(t, 11, b"b")], [t])
    with pcdcodec.open(out) as rec:
        index = rec.index
        index.metadata["pcdcodec.seal"] = dict(index.metadata["pcdcodec.seal"])
        index.metadata["pcdcodec.seal"]["kept_digest"] = "sha256:" + "0" * 64
        with open(out, "rb") as f, pytest.raises(DecodeError, match="not those sealed"):
            list(_kept.read_kept(f, index, "x"))


def test_a_killed_writer_leaves_its_written_kept_chunks_readable(tmp_path: Path) -> None:
    t = _topic()
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
    depth = np.ones((6, 8), np.uint16)
    out = tmp_path / "x.pcdc"
    w = pcdcodec.open(out, "w", intrinsics=cam, color=None, kept_topics=[t])
    big = [KeptMessage(t, 10 + k, bytes(range(256)) * 20) for k in range(300)]  # > 1 MiB
    for k in range(3):
        w.write(None, depth, 1_000_000 * (k + 1))
    for m in big:
        w.write_message(m)
    w.flush()
    w.abort()
    with pytest.warns(IncompleteRecordingWarning), pcdcodec.open(out) as rec:
        got = list(rec.kept_messages())
    assert 0 < len(got) <= len(big)
    assert [m.data for m in got] == [m.data for m in big[: len(got)]]


def test_opening_lists_kept_messages_from_the_index_without_reading_them(tmp_path: Path) -> None:
    """A damaged kept chunk does not stop the camera from being read: opening lists kept
    messages from the message index (no chunk decompressed), reading them finds the damage."""
    t = _topic()
    messages = [KeptMessage(t, 10 + k, bytes([k % 251]) * 200) for k in range(50)]
    out = tmp_path / "x.pcdc"
    _write(out, messages, [t])
    at = _kept_chunk_offset(out)
    data = bytearray(out.read_bytes())
    data[at + 80] ^= 0x40
    bad = tmp_path / "bad.pcdc"
    bad.write_bytes(bytes(data))
    with pcdcodec.open(bad) as rec:
        assert rec.index.indexed
        assert rec.kept_counts() == {"/imu": 50}
        assert len(rec) == 3
        assert int(rec[2].depth[0, 0]) == 2
        with pytest.raises(DecodeError, match=r"bad\.pcdc"):
            list(rec.kept_messages())


def test_encode_and_info_list_the_kept_topics(tmp_path: Path) -> None:
    import subprocess
    import sys

    path = _bag("ros2-converted/spot_ros2_mcap")
    out = tmp_path / "x.pcdc"
    flags = ["--fx", "200", "--fy", "200", "--cx", "212", "--cy", "120"]

    def cli(*args: str) -> str:
        done = subprocess.run(
            [sys.executable, "-m", "pcdcodec", *args], capture_output=True, text=True, check=True
        )
        return done.stdout

    text = cli("encode", str(path), "-o", str(out), *flags, "--exclude-topic", "*mono*")
    assert "kept         6 other topics" in text
    assert "/spot/depth/frontleft/image/compressedDepth" in text.split("kept")[1]
    assert "/spot/camera/hand_mono/image " in text.split("left out")[1]
    info = cli("info", str(out))
    assert "kept         6 other topics" in info
    assert "[sensor_msgs/msg/CompressedImage, 1 msgs]" in info
