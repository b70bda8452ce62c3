"""A bag's camera messages given back message for message: each depth and color message made
into a frame is kept as an envelope (the message without its pixels), and
``Recording.camera_messages`` rebuilds it from the frame; the messages no frame holds are kept
raw (``docs/format.md``, "Format version 4: kept topics")."""

from __future__ import annotations

import json
import struct
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.errors import DecodeError
from pcdcodec.ros import messages as rm
from pcdcodec.ros.envelope import Envelope
from pcdcodec.ros.kept import ENVELOPE_ENCODING, KeptMessage, KeptTopic

from .conftest import SEQUENCES

SET = "realsense_d435"
BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}
#: what the tests leave out of the robot bags, to stay quick: the cloud and the unaligned depth
LEAVE_OUT = [rb.CLOUD, rb.DEPTH]
KINDS = {"ros1": "robot.bag", "ros2-sqlite3": "robot", "ros2-mcap": "robot"}


@pytest.fixture(scope="module")
def frames() -> list[tuple[Any, Any]]:
    if not SEQUENCES[SET].present:
        pytest.skip(f"{SEQUENCES[SET].root} is not present")
    return list(rb.SequenceFrames(SET, 3))


@pytest.fixture(scope="module", params=sorted(KINDS))
def robot_bag(request: Any, frames: Any, tmp_path_factory: Any) -> Path:
    seq = SEQUENCES[SET]
    path = tmp_path_factory.mktemp(request.param) / KINDS[request.param]
    summary = rb.write_robot_bag(
        path, frames, kind=request.param, intrinsics=seq.camera, depth_scale=seq.depth_scale,
        fps=5.0, cloud_hz=5.0, seconds=1.0, extras=False,
    )  # fmt: skip
    return Path(summary.path)


def _messages(path: Path, topics: set[str]) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of ``topics`` in a bag, as stored: (log time, bytes)."""
    from pcdcodec.ros import bagfile

    reader, tmp = bagfile.open_reader(path)
    try:
        out: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
        for c, t, raw in reader.messages([c for c in reader.connections if c.topic in topics]):
            out[c.topic].append((int(t), bytes(raw)))
        return dict(out)
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()


def _given_back(rec: Any) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    times = []
    for m in rec.camera_messages():
        assert m.topic.message_encoding in ("ros1", "cdr")  # the original encoding
        assert "pcdcodec.camera" not in m.topic.metadata
        out[m.topic.topic].append((m.log_time, m.data))
        times.append(m.log_time)
    assert times == sorted(times)  # in log-time order, to merge with kept_messages
    return dict(out)


def _deserialize(data: bytes, msgtype: str, ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        return store.deserialize_ros1(data, msgtype)
    return store.deserialize_cdr(data, msgtype)


def _without_pixels(data: bytes, msgtype: str, ros1: bool) -> tuple[Any, Any]:
    """(every field but the pixels, the pixels) of an image message."""
    msg = _deserialize(data, msgtype, ros1)
    fields = {k: getattr(msg, k) for k in msg.__dataclass_fields__ if k != "data"}
    fields["header"] = (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id)
    if ros1:
        fields["seq"] = msg.header.seq
    return fields, msg


def test_robot_bag_given_back_byte_for_byte_with_a_lossless_color_codec(
    robot_bag: Path, tmp_path: Path
) -> None:
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(robot_bag, out, color="ffv1", exclude_topics=LEAVE_OUT)
    want = _messages(robot_bag, {rb.ALIGNED, rb.COLOR})
    with pcdcodec.open(out) as rec:
        assert {t.topic for t in rec.camera_topics} == {rb.ALIGNED, rb.COLOR}
        assert not {rb.ALIGNED, rb.COLOR} & {t.topic for t in rec.kept_topics}
        assert not {rb.ALIGNED, rb.COLOR} & {m.topic.topic for m in rec.kept_messages()}
        assert not {rb.ALIGNED, rb.COLOR} & set(rec.kept_counts())
        got = _given_back(rec)
        seal = rec.index.metadata["pcdcodec.seal"]
    assert got == want
    assert len(got[rb.COLOR]) == 5
    # The seal counts (and its digest covers) the camera topics' envelopes.
    assert json.loads(seal["kept"])[rb.ALIGNED] == 5


def test_robot_bag_depth_exact_and_color_within_the_codecs_quality(
    robot_bag: Path, tmp_path: Path
) -> None:
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(robot_bag, out, exclude_topics=LEAVE_OUT)  # the default, lossy color
    want = _messages(robot_bag, {rb.ALIGNED, rb.COLOR})
    ros1 = robot_bag.suffix == ".bag"
    with pcdcodec.open(out) as rec:
        got = _given_back(rec)
    assert got[rb.ALIGNED] == want[rb.ALIGNED]
    assert [t for t, _ in got[rb.COLOR]] == [t for t, _ in want[rb.COLOR]]
    for (_, a), (_, b) in zip(got[rb.COLOR], want[rb.COLOR], strict=True):
        fa, ma = _without_pixels(a, "sensor_msgs/msg/Image", ros1)
        fb, mb = _without_pixels(b, "sensor_msgs/msg/Image", ros1)
        assert fa == fb
        assert len(a) == len(b)
        err = np.abs(ma.data.astype(int) - mb.data.astype(int))
        assert 0 < err.mean() < 4  # lossy, and close


def test_the_seal_covers_envelopes(ros1_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(ros1_bag, out, color="ffv1", exclude_topics=[*LEAVE_OUT, "/tf*", "*info"])
    with pcdcodec.open(out) as rec:
        seal = rec.index.metadata["pcdcodec.seal"]
        assert set(json.loads(seal["kept"])) == {rb.ALIGNED, rb.COLOR}
        rec.index.metadata["pcdcodec.seal"] = {**seal, "kept_digest": "sha256:" + "0" * 64}
        with pytest.raises(DecodeError, match="not those sealed"):
            list(rec.camera_messages())


# -- real bags -----------------------------------------------------------------------------


def _bag(name: str) -> Path:
    path = BAGS / name
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


SPOT_DEPTH = "/spot/depth/frontleft/image"


@pytest.mark.parametrize(
    ("name", "depth_topic"),
    [
        ("spot/raw.bag", None),
        ("spot/compressed.bag", None),
        ("spot/compressedDepth.bag", None),
        ("ros2-converted/spot_ros2_sqlite", None),
        ("ros2-converted/spot_ros2_sqlite", SPOT_DEPTH + "/compressed"),
        ("ros2-converted/spot_ros2_mcap", None),
        ("ros2-converted/spot_ros2_mcap", SPOT_DEPTH + "/compressedDepth"),
    ],
)
def test_real_bags_depth_comes_back_as_it_came(
    name: str, depth_topic: str | None, tmp_path: Path
) -> None:
    path = _bag(name)
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(
        path, out, intrinsics=SPOT_CAMERA, color="ffv1", depth_topic=depth_topic
    )
    topic = summary.source["depth_topic"]
    assert depth_topic in (None, topic)
    want = _messages(path, {topic})[topic]
    ros1 = path.suffix == ".bag"
    with pcdcodec.open(out) as rec:
        (camera,) = rec.camera_topics
        got = _given_back(rec)[topic]
    assert [t for t, _ in got] == [t for t, _ in want]
    for (_, a), (_, b) in zip(got, want, strict=True):
        if camera.msgtype.endswith("/Image"):
            assert a == b
            continue
        fa, ma = _without_pixels(a, camera.msgtype, ros1)
        fb, mb = _without_pixels(b, camera.msgtype, ros1)
        assert fa == fb  # header, format
        if "compressedDepth" in mb.format:
            assert bytes(ma.data[:12]) == bytes(mb.data[:12])  # its header, as it came
        da = rm.decode_compressed(ma, "depth", topic)
        db = rm.decode_compressed(mb, "depth", topic)
        assert da.dtype == db.dtype
        assert np.array_equal(da, db)


# -- bags of every kind of camera message, with images no frame holds ----------------------


def _rewrite(src: Path, dst: Path, how: str) -> dict[str, str]:
    """A ROS 1 robot bag's camera with its images changed (``how``): ``compressed`` (JPEG
    color and compressedDepth depth; the third depth image left out, so its color finds no
    partner), or ``quirks`` (the second color image with padded rows; the fourth depth
    image stamped before the third). Returns the topics by role."""
    from rosbags.rosbag1 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    compressed = "sensor_msgs/msg/CompressedImage"
    topics = {"depth": rb.ALIGNED, "color": rb.COLOR, "info": rb.ALIGNED_INFO}
    if how == "compressed":
        topics["depth"] += "/compressedDepth"
        topics["color"] += "/compressed"
    kept = {rb.ALIGNED: "depth", rb.COLOR: "color", rb.ALIGNED_INFO: "info"}
    count = {"depth": 0, "color": 0, "info": 0}
    with Reader(src) as reader, Writer(dst) as writer:
        conns: dict[str, Any] = {}
        for c, t, raw in reader.messages():
            role = kept.get(c.topic)
            if role is None:
                continue
            msg = store.deserialize_ros1(raw, c.msgtype)
            k = count[role]
            count[role] += 1
            msgtype = c.msgtype
            if role == "depth" and how == "compressed":
                if k == 2:
                    continue
                import imagecodecs

                depth = np.frombuffer(msg.data, "<u2").reshape(msg.height, msg.width)
                png = bytes(imagecodecs.png_encode(depth, level=6))
                head = struct.pack("<iff", 0, 12.5, -3.25)  # depth parameters as they come
                make = store.types[compressed]
                data = np.frombuffer(head + png, np.uint8)
                msg = make(msg.header, "16UC1; compressedDepth", data)
                msgtype = compressed
            elif role == "color" and how == "compressed":
                import imagecodecs

                px = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width, 3)
                jpeg = bytes(imagecodecs.jpeg8_encode(px, level=90))
                make = store.types[compressed]
                msg = make(msg.header, "rgb8; jpeg compressed bgr8", np.frombuffer(jpeg, np.uint8))
                msgtype = compressed
            elif role == "color" and how == "quirks" and k == 1:
                rows = np.frombuffer(msg.data, np.uint8).reshape(msg.height, -1)
                padded = np.concatenate([rows, np.zeros((msg.height, 8), np.uint8)], axis=1)
                msg.step = padded.shape[1]
                msg.data = padded.reshape(-1)
            elif role == "depth" and how == "quirks" and k == 3:
                msg.header.stamp.sec -= 1  # before the one logged earlier: skipped
            topic = topics[role]
            if topic not in conns:
                conns[topic] = writer.add_connection(
                    topic, msgtype, typestore=store, callerid="/camera"
                )
            writer.write(conns[topic], t, store.serialize_ros1(msg, msgtype))
    return topics


@pytest.fixture(scope="module")
def ros1_bag(frames: Any, tmp_path_factory: Any) -> Path:
    seq = SEQUENCES[SET]
    path = tmp_path_factory.mktemp("ros1") / "robot.bag"
    rb.write_robot_bag(
        path, frames, kind="ros1", intrinsics=seq.camera, depth_scale=seq.depth_scale,
        fps=5.0, cloud_hz=5.0, seconds=1.0, extras=False,
    )  # fmt: skip
    return path


def test_jpeg_and_compressed_depth_and_a_dropped_image(ros1_bag: Path, tmp_path: Path) -> None:
    bag = tmp_path / "compressed.bag"
    topics = _rewrite(ros1_bag, bag, "compressed")
    out = tmp_path / "x.pcdc"
    summary = pcdcodec.encode(
        bag, out, color="ffv1", depth_topic=topics["depth"], color_topic=topics["color"],
        info_topic=topics["info"],
    )  # fmt: skip
    assert summary.frames == 4
    assert summary.source["dropped"] == {"color": 1, "depth": 0}
    want = _messages(bag, {topics["depth"], topics["color"]})
    with pcdcodec.open(out) as rec:
        got = _given_back(rec)
    assert {t: len(v) for t, v in got.items()} == {topics["depth"]: 4, topics["color"]: 5}
    for role in ("depth", "color"):
        topic = topics[role]
        assert [t for t, _ in got[topic]] == [t for t, _ in want[topic]]
        for (_, a), (_, b) in zip(got[topic], want[topic], strict=True):
            fa, ma = _without_pixels(a, "sensor_msgs/msg/CompressedImage", True)
            fb, mb = _without_pixels(b, "sensor_msgs/msg/CompressedImage", True)
            assert fa == fb
            pa = rm.decode_compressed(ma, role, topic)
            pb = rm.decode_compressed(mb, role, topic)
            if role == "depth":
                assert bytes(ma.data[:12]) == bytes(mb.data[:12])
                assert np.array_equal(pa, pb)
            else:
                err = np.abs(pa.astype(int) - pb.astype(int))
                assert err.mean() < 2  # re-encoded at JPEG quality 95
    # The color image without a partner is kept raw: it comes back byte for byte.
    pairs = zip(got[topics["color"]], want[topics["color"]], strict=True)
    assert sum(a == b for a, b in pairs) == 1


def test_messages_that_cannot_be_rebuilt_exactly_are_kept_raw(
    ros1_bag: Path, tmp_path: Path
) -> None:
    bag = tmp_path / "quirks.bag"
    _rewrite(ros1_bag, bag, "quirks")
    out = tmp_path / "x.pcdc"
    with pcdcodec.open_source(bag) as source:
        kinds = [
            (m.topic.topic, m.topic.message_encoding)
            for m in source.items()
            if isinstance(m, KeptMessage) and m.topic.camera
        ]
    # Raw: the padded color image, the depth image out of order and so its color image
    # without a partner; the rest: envelopes.
    raw = [k for k in kinds if k[1] == "ros1"]
    assert sorted(raw) == [(rb.ALIGNED, "ros1"), (rb.COLOR, "ros1"), (rb.COLOR, "ros1")]
    assert len(kinds) == 10
    pcdcodec.encode(bag, out)  # lossy color: the padded image still comes back exactly
    want = _messages(bag, {rb.ALIGNED, rb.COLOR})
    with pcdcodec.open(out) as rec:
        got = _given_back(rec)
    assert got[rb.ALIGNED] == want[rb.ALIGNED]
    assert got[rb.COLOR][1] == want[rb.COLOR][1]
    assert [t for t, _ in got[rb.COLOR]] == [t for t, _ in want[rb.COLOR]]


def test_an_envelope_that_fits_no_frame_is_an_error(tmp_path: Path) -> None:
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
    topic = KeptTopic(
        "/depth", "sensor_msgs/msg/Image", "ros1msg", "", ENVELOPE_ENCODING,
        {"pcdcodec.camera": "depth", "pcdcodec.encoding": "ros1"},
    )  # fmt: skip
    out = tmp_path / "x.pcdc"
    with pcdcodec.open(out, "w", intrinsics=cam, color=None, kept_topics=[topic]) as w:
        w.write(None, np.ones((6, 8), np.uint16), 1_000)
        env = Envelope(2_000, "image:16UC1:<", b"prefix", length=96)
        w.write_message(KeptMessage(topic, 1_500, env.pack()))
    with pcdcodec.open(out) as rec, pytest.raises(DecodeError, match=r"x\.pcdc.*2000 ns"):
        list(rec.camera_messages())


def test_messages_waiting_beyond_the_memory_bound_wait_in_a_file(
    ros1_bag: Path, tmp_path: Path, monkeypatch: Any
) -> None:
    import tempfile

    from pcdcodec.sources import _bag_envelope

    monkeypatch.setattr(_bag_envelope, "HELD_BYTES", 1000)
    spills = []
    make = tempfile.TemporaryFile

    def spill() -> Any:
        spills.append(make())
        return spills[-1]

    monkeypatch.setattr(_bag_envelope.tempfile, "TemporaryFile", spill)
    bag = tmp_path / "compressed.bag"
    topics = _rewrite(ros1_bag, bag, "compressed")
    options = {"depth_topic": topics["depth"], "color_topic": topics["color"]}
    with pcdcodec.open_source(bag, info_topic=topics["info"], **options) as source:
        items = list(source.items())
    kept = [m for m in items if isinstance(m, KeptMessage)]
    assert [m.log_time for m in kept] == sorted(m.log_time for m in kept)
    assert sum(1 for m in kept if m.topic.camera) == 9
    assert len(spills) == 1
    assert spills[0].closed
    out = tmp_path / "x.pcdc"
    pcdcodec.encode(bag, out, color="ffv1", info_topic=topics["info"], **options)
    want = _messages(bag, {topics["color"]})[topics["color"]]
    with pcdcodec.open(out) as rec:
        got = _given_back(rec)[topics["color"]]
    assert [t for t, _ in got] == [t for t, _ in want]
    assert got[2] == want[2]  # the one without a partner, kept raw: waited in the file
