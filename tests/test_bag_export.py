"""Giving the bag back: a recording made from a ROS bag exports as a bag that ROS tools play as
the original. Every kept topic comes back with its own connection (type, definition, connection
facts), every message byte for byte at its log time and in order; a ROS 1 bag converts to ROS 2
(and back) by rosbags' rules; the camera topics come back as they came where the recording
gives them (``camera_messages``), else are built anew under the input's names
(``docs/bags.md``, "Giving the bag back")."""

from __future__ import annotations

import collections
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.cli import main
from pcdcodec.convert.rosbag import export_bag
from pcdcodec.errors import InputError
from pcdcodec.recording.reader import Recording
from pcdcodec.ros.bagfile import open_reader
from pcdcodec.ros.kept import KeptMessage, KeptTopic, kept_topic_of_connection
from pcdcodec.ros.keptwriter import KeptConnections

from .conftest import SEQUENCES

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}
SET = "realsense_d435"
#: The robot bags: kind, file name, split_bytes (a ROS 2 bag of several files).
ROBOT = {
    "ros1": ("ros1", "robot.bag", None),
    "ros2-sqlite3": ("ros2-sqlite3", "robot", None),
    "ros2-mcap": ("ros2-mcap", "robot", None),
    "ros2-mcap-split": ("ros2-mcap", "robot", 1_000_000),
}


def _bag(name: str) -> Path:
    path = BAGS / name
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


def _facts(conn: Any, ros2: bool) -> tuple[Any, ...]:
    """A connection as ROS tools see it: topic, type, definition, md5sum or type hash, and the
    ROS 1 caller id and latching or the ROS 2 serialization and offered QoS profiles."""
    ext = conn.ext
    own = (
        (ext.serialization_format, tuple(ext.offered_qos_profiles))
        if ros2
        else (ext.callerid, ext.latching)
    )
    return (conn.topic, conn.msgtype, conn.msgdef.data, conn.digest, *own)


class Bag:
    """A bag read with rosbags' AnyReader: its kind, each connection's messages (log time,
    bytes, in the bag's order), and every message's (topic, log time) in the bag's order."""

    def __init__(self, path: Path) -> None:
        reader, tmp = open_reader(path)
        try:
            self.ros2 = bool(reader.is2)
            self.messages: dict[tuple[Any, ...], list[tuple[int, bytes]]] = {
                _facts(c, self.ros2): [] for c in reader.connections
            }
            self.types = {c.topic: c.msgtype for c in reader.connections}
            self.order: list[tuple[str, int]] = []
            for c, t, raw in reader.messages():
                self.messages[_facts(c, self.ros2)].append((t, bytes(raw)))
                self.order.append((c.topic, t))
            self.decoded: dict[str, list[Any]] = collections.defaultdict(list)
            wanted = [c for c in reader.connections if c.topic in _DECODED]
            for c, _t, raw in reader.messages(connections=wanted):
                self.decoded[c.topic].append(reader.deserialize(raw, c.msgtype))
        finally:
            reader.close()
            if tmp is not None:
                tmp.cleanup()

    def of(self, topics: set[str]) -> dict[tuple[Any, ...], list[tuple[int, bytes]]]:
        return {k: v for k, v in self.messages.items() if k[0] in topics}

    def counts(self) -> dict[str, int]:
        return dict(collections.Counter(topic for topic, _ in self.order))


#: Topics whose messages are decoded, to compare field values across kinds.
_DECODED = {
    "/camera/imu", "/odom", "/tf", "/tf_static", "/joint_states", "/diagnostics",
    "/camera/color/camera_info", rb.DEPTH, rb.CLOUD, rb.ALIGNED,
    "/spot/camera/hand_color/image", "/spot/depth/frontleft/image", "/thing",
}  # fmt: skip


def _exported_with_rosbags(path: Path) -> None:
    """rosbags' own reader opens the exported bag (a ROS 1 bag by its ``.bag`` name)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        assert reader.message_count == sum(c.msgcount for c in reader.connections) > 0


def _kept_names(rec_path: Path) -> set[str]:
    with pcdcodec.open(rec_path) as rec:
        return {t.topic for t in rec.kept_topics}


def _assert_kept_exact(original: Bag, back: Bag, kept: set[str]) -> None:
    """Every kept topic's connections as they came, every message's bytes and log time in
    order, and the bag's messages in time order."""
    assert kept
    want, got = original.of(kept), back.of(kept)
    assert set(got) == set(want)  # each connection, with its facts
    for facts, messages in want.items():
        assert got[facts] == messages, facts[0]
    times = [t for _, t in back.order]
    assert times == sorted(times)


# -- the real bags --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("spot/raw.bag", ("rosbag1", None)),
        ("spot/compressed.bag", ("rosbag1", None)),
        ("ros2-converted/spot_ros2_sqlite", ("rosbag2", "sqlite3")),
        ("ros2-converted/spot_ros2_mcap", ("rosbag2", "mcap")),
    ],
)
def test_a_real_bag_comes_back_as_it_came(
    name: str, kind: tuple[str, str | None], tmp_path: Path
) -> None:
    path = _bag(name)
    rec_path = tmp_path / "x.pcdc"
    pcdcodec.encode(path, rec_path, intrinsics=SPOT_CAMERA, max_difference=10**12)
    with pcdcodec.open(rec_path) as rec:
        meta = rec.metadata
        depth = rec[0].depth
    assert (meta["bag_format"], meta.get("bag_storage")) == kind
    out = tmp_path / ("back.bag" if kind[0] == "rosbag1" else "back")
    summary = export_bag(rec_path, out)  # as it came
    assert (summary["format"], summary["camera"]) == (kind[0], "as recorded")
    if kind[1] is not None:
        assert [f.suffix for f in out.iterdir() if f.name != "metadata.yaml"] == [
            {"sqlite3": ".db3", "mcap": ".mcap"}[kind[1]]
        ]
    _exported_with_rosbags(out)
    original, back = Bag(path), Bag(out)
    assert back.ros2 == (kind[0] == "rosbag2")
    kept = _kept_names(rec_path)
    _assert_kept_exact(original, back, kept)
    assert summary["kept"] == {t: n for t, n in original.counts().items() if t in kept}
    # The depth topic as recorded: its own message kind and name; a raw Image byte for byte,
    # a PNG one with its depth bit-exact (the PNG encoded again).
    assert back.types == original.types
    assert back.counts() == original.counts()
    had = meta["ros_depth_topic"]
    ((_, a),) = original.of({had}).popitem()[1]
    ((_, b),) = back.of({had}).popitem()[1]
    if had.endswith("/compressed"):
        import imagecodecs

        png = b[b.index(b"\x89PNG") :]
        assert np.array_equal(imagecodecs.png_decode(png), depth)
    else:
        assert a == b


def test_a_topic_of_several_publishers_stays_several_connections(tmp_path: Path) -> None:
    """A ROS 1 topic that two nodes published (two caller ids, one latched) comes back as two
    connections, each with its own messages."""
    from rosbags.rosbag1 import Writer

    from pcdcodec.ros.bagwriter import MessageBuilder

    msgs = MessageBuilder(False, "cam")
    store, string = msgs.store, msgs.types["std_msgs/msg/String"]
    path = tmp_path / "two.bag"
    with Writer(path) as w:
        depth = w.add_connection("/cam/depth", "sensor_msgs/msg/Image", typestore=store)
        a = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store, callerid="/a")
        b = w.add_connection(
            "/chatter", "std_msgs/msg/String", typestore=store, callerid="/b", latching=1
        )
        for k in range(3):
            t = (k + 1) * 10**9
            w.write(depth, t, msgs.image(t, np.full((6, 8), 1000 + k, np.uint16), "16UC1"))
            for conn, name in ((a, "a"), (b, "b")):
                data = store.serialize_ros1(string(data=f"{name}{k}"), "std_msgs/msg/String")
                w.write(conn, t + 1, data)
    rec = tmp_path / "two.pcdc"
    camera = {"width": 8, "height": 6, "fx": 5.0, "fy": 5.0, "cx": 4.0, "cy": 3.0}
    pcdcodec.encode(path, rec, intrinsics=camera)
    export_bag(rec, tmp_path / "back.bag")
    original, back = Bag(path), Bag(tmp_path / "back.bag")
    chatter = original.of({"/chatter"})
    assert sorted(f[4:] for f in chatter) == [("/a", None), ("/b", 1)]
    assert back.of({"/chatter"}) == chatter
    assert back.counts() == original.counts() == {"/cam/depth": 3, "/chatter": 6}


# -- robot bags -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def robot(tmp_path_factory: Any) -> dict[str, tuple[Path, Path]]:
    """Each kind of robot bag (1 s, 5 frames a second of 320 x 240, every extra topic) and its
    recording."""
    if not SEQUENCES[SET].present:
        pytest.skip(f"{SEQUENCES[SET].root} is not present")
    cam = SEQUENCES[SET].camera
    # The middle quarter of the first frames: small bags, quick tests.
    (h, w), (y, x) = (cam.height // 2, cam.width // 2), (cam.height // 4, cam.width // 4)
    frames = [
        (d[y : y + h, x : x + w], c[y : y + h, x : x + w]) for d, c in rb.SequenceFrames(SET, 3)
    ]
    camera = pcdcodec.CameraIntrinsics(w, h, cam.fx, cam.fy, cam.cx - x, cam.cy - y)
    out = {}
    for key, (kind, name, split) in ROBOT.items():
        folder = tmp_path_factory.mktemp(key)
        rb.write_robot_bag(
            folder / name,
            frames,
            kind=kind,
            intrinsics=camera,
            depth_scale=SEQUENCES[SET].depth_scale,
            seconds=1.0,
            fps=5.0,
            cloud_hz=5.0,
            split_bytes=split,
        )
        pcdcodec.encode(folder / name, folder / "run.pcdc")
        out[key] = (folder / name, folder / "run.pcdc")
    return out


@pytest.mark.parametrize("key", sorted(ROBOT))
def test_a_robot_bag_comes_back_as_it_came(
    key: str, robot: dict[str, tuple[Path, Path]], tmp_path: Path
) -> None:
    path, rec_path = robot[key]
    ros1 = key == "ros1"
    with pcdcodec.open(rec_path) as rec:
        meta = rec.metadata
        frames = [f.depth for f in rec]
    assert meta["bag_format"] == ("rosbag1" if ros1 else "rosbag2")
    assert meta.get("bag_storage") == (None if ros1 else key.split("-")[1])
    out = tmp_path / ("back.bag" if ros1 else "back")
    summary = export_bag(rec_path, out)
    assert summary["frames"] == len(frames) == 5
    _exported_with_rosbags(out)
    original, back = Bag(path), Bag(out)
    kept = _kept_names(rec_path)
    assert {"/tf", "/tf_static", "/camera/imu", rb.CLOUD, rb.DEPTH_INFO} <= kept
    _assert_kept_exact(original, back, kept)
    # Every topic of the original, with its type and message count.
    assert back.types == original.types
    assert back.counts() == original.counts()
    # The camera topics as recorded: depth bit-exact in order, the kept CameraInfo not twice.
    assert summary["camera"] == "as recorded"
    assert meta["ros_info_topic"] in kept
    depths = [np.frombuffer(m.data, np.uint16).reshape(m.height, m.width) for m in _decode(out)]
    assert all(np.array_equal(a, b) for a, b in zip(depths, frames, strict=True))
    if key == "ros2-mcap-split":  # several files in, one bag out
        assert len(list(path.rglob("*.mcap"))) > 1
        assert len(list(out.glob("*.mcap"))) == 1


def _decode(path: Path) -> list[Any]:
    """The aligned depth images of a bag."""
    reader, tmp = open_reader(path)
    try:
        conns = [c for c in reader.connections if c.topic == rb.ALIGNED]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()


# -- the camera topics as they came ---------------------------------------------------------


def _camera_messages_from(bag: Path) -> Any:
    """A ``camera_messages`` that gives the frame topics of ``bag`` as they came, as a
    recording that holds them does."""

    def camera_messages(self: Any) -> Iterator[KeptMessage]:
        from rosbags.rosbag2.metadata import dump_qos_v8

        topics = {self.metadata.get("ros_depth_topic"), self.metadata.get("ros_color_topic")}
        reader, tmp = open_reader(bag)
        try:
            conns = [c for c in reader.connections if c.topic in topics]
            for c, t, raw in reader.messages(connections=conns):
                qos = getattr(c.ext, "offered_qos_profiles", None)
                yaml = dump_qos_v8(list(qos)) if qos else ""
                topic = kept_topic_of_connection(c, bool(reader.is2), yaml)
                yield KeptMessage(topic, int(t), bytes(raw))
        finally:
            reader.close()
            if tmp is not None:
                tmp.cleanup()

    return camera_messages


def _record_writes(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, int]]:
    written: list[tuple[str, int]] = []
    write = KeptConnections.write

    def spy(self: KeptConnections, message: KeptMessage) -> None:
        written.append((message.topic.topic, message.log_time))
        write(self, message)

    monkeypatch.setattr(KeptConnections, "write", spy)
    return written


@pytest.mark.parametrize("key", ["ros1", "ros2-mcap", "ros2-sqlite3"])
def test_camera_messages_as_they_came_make_the_whole_bag_exact(
    key: str, robot: dict[str, tuple[Path, Path]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, rec_path = robot[key]
    monkeypatch.setattr(Recording, "camera_messages", _camera_messages_from(path), raising=False)
    written = _record_writes(monkeypatch)
    out = tmp_path / ("back.bag" if key == "ros1" else "back")
    summary = export_bag(rec_path, out)
    assert summary["camera"] == "as recorded"
    assert summary["frames"] == 5
    original, back = Bag(path), Bag(out)
    assert back.messages == original.messages  # every connection, every message, exact
    # Merged by log time, each topic in its order: what was written is the bag's order.
    assert [t for _, t in written] == sorted(t for _, t in written)
    assert sorted(written) == sorted(original.order)
    per_topic = collections.defaultdict(list)
    for topic, t in written:
        per_topic[topic].append(t)
    assert per_topic == {
        topic: [t for top, t in original.order if top == topic] for topic in original.types
    }
    # Options that would build the camera topics anew are refused, naming them.
    with pytest.raises(InputError, match=r"cloud.*kept=False"):
        export_bag(rec_path, tmp_path / "other", cloud=True)
    # Converted to the other kind: the camera topics too.
    other = tmp_path / ("other" if key == "ros1" else "other.bag")
    export_bag(rec_path, other, to="rosbag2" if key == "ros1" else "rosbag1")
    assert Bag(other).counts() == original.counts()


def test_a_recording_without_camera_messages_builds_the_camera_anew(
    robot: dict[str, tuple[Path, Path]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, rec_path = robot["ros1"]
    monkeypatch.setattr(Recording, "camera_messages", lambda self: iter(()), raising=False)
    summary = export_bag(rec_path, tmp_path / "back.bag")
    assert summary["camera"] == "built anew"
    assert Bag(tmp_path / "back.bag").counts() == Bag(path).counts()


# -- converted to the other kind ------------------------------------------------------------


def _same_values(a: Any, b: Any, where: str) -> None:
    """Field by field, ``a`` (the converted message) equals ``b``; a ROS 1 header's ``seq``,
    which ROS 2 has not, is left out."""
    if isinstance(a, np.ndarray):
        assert np.array_equal(a, np.asarray(b)), where
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            _same_values(x, y, f"{where}[{k}]")
    elif hasattr(a, "__dataclass_fields__"):
        for name in a.__dataclass_fields__:
            if name == "seq" and not hasattr(b, "seq"):
                continue
            if name == "seq":
                assert a.seq == 0, where  # ROS 2 has none: ROS 1 gets 0
                continue
            _same_values(getattr(a, name), getattr(b, name), f"{where}.{name}")
    else:
        assert a == b, where


@pytest.mark.parametrize(("key", "to"), [("ros1", "rosbag2"), ("ros2-sqlite3", "rosbag1")])
def test_kept_topics_convert_to_the_other_kind(
    key: str, to: str, robot: dict[str, tuple[Path, Path]], tmp_path: Path
) -> None:
    path, rec_path = robot[key]
    out = tmp_path / ("back" if to == "rosbag2" else "back.bag")
    summary = export_bag(rec_path, out, to=to, storage="sqlite3")
    _exported_with_rosbags(out)
    original, back = Bag(path), Bag(out)
    assert back.ros2 == (to == "rosbag2")
    assert back.types == original.types
    assert back.counts() == original.counts()
    assert set(summary["kept"]) == _kept_names(rec_path)
    for topic in _DECODED & _kept_names(rec_path):
        times = [t for top, t in original.order if top == topic]
        assert [t for top, t in back.order if top == topic] == times
        for k, (a, b) in enumerate(zip(back.decoded[topic], original.decoded[topic], strict=True)):
            _same_values(a, b, f"{topic}[{k}]")
    # Latching: ROS 1's latched /tf_static is transient local in ROS 2, and back.
    (facts,) = (f for f in back.messages if f[0] == "/tf_static")
    if back.ros2:
        assert [q.durability.name for q in facts[5]] == ["TRANSIENT_LOCAL"]
    else:
        assert facts[5] == 1


def test_a_real_ros1_bag_converts_to_ros2(tmp_path: Path) -> None:
    path = _bag("spot/raw.bag")
    rec_path = tmp_path / "x.pcdc"
    pcdcodec.encode(path, rec_path, intrinsics=SPOT_CAMERA)
    out = tmp_path / "back"
    export_bag(rec_path, out, to="rosbag2")
    original, back = Bag(path), Bag(out)
    assert back.ros2
    (a,) = back.decoded["/spot/camera/hand_color/image"]
    (b,) = original.decoded["/spot/camera/hand_color/image"]
    _same_values(a, b, "hand_color")
    assert back.counts() == original.counts()


def _recording_with(path: Path, topic: KeptTopic) -> Path:
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 4.0, 3.0)
    depth = np.arange(48, dtype=np.uint16).reshape(6, 8)
    with pcdcodec.open(path, "w", intrinsics=cam, color=None, kept_topics=[topic]) as w:
        for k in range(3):
            w.write(None, depth + k, 1_000_000 * (k + 1))
        w.write_message(KeptMessage(topic, 1_500_000, b"\x01\x00\x00\x00"))
    return path


def test_what_cannot_go_into_a_bag_is_refused_naming_it(tmp_path: Path) -> None:
    json_topic = KeptTopic("/status", "my_msgs/msg/Status", "jsonschema", "{}", "json", {})
    rec = _recording_with(tmp_path / "json.pcdc", json_topic)
    with pytest.raises(InputError, match=r"'/status'.*serialized as 'json'"):
        export_bag(rec, tmp_path / "a.bag")
    untyped = KeptTopic("/blob", "", "", "", "cdr", {})
    rec = _recording_with(tmp_path / "untyped.pcdc", untyped)
    with pytest.raises(InputError, match=r"'/blob' has no message type"):
        export_bag(rec, tmp_path / "a", to="rosbag2")
    broken = KeptTopic("/thing", "my_msgs/msg/Thing", "ros1msg", "int32[ x\n", "ros1", {})
    rec = _recording_with(tmp_path / "broken.pcdc", broken)
    with pytest.raises(InputError, match=r"definition of topic '/thing'.*cannot be read"):
        export_bag(rec, tmp_path / "b", to="rosbag2")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "broken.pcdc",
        "json.pcdc",
        "untyped.pcdc",
    ]
    # A type of the recording's own, described by its definition: as it came into a ROS 1
    # bag, converted into a ROS 2 one; and left out with kept=False.
    own = KeptTopic("/thing", "my_msgs/msg/Thing", "ros1msg", "int32 x\n", "ros1", {})
    rec = _recording_with(tmp_path / "own.pcdc", own)
    export_bag(rec, tmp_path / "c.bag")
    back = Bag(tmp_path / "c.bag").of({"/thing"})
    assert list(back.values()) == [[(1_500_000, b"\x01\x00\x00\x00")]]
    export_bag(rec, tmp_path / "c2", to="rosbag2")
    (thing,) = Bag(tmp_path / "c2").decoded["/thing"]
    assert (thing.__msgtype__, thing.x) == ("my_msgs/msg/Thing", 1)
    summary = export_bag(rec, tmp_path / "d", to="rosbag2", kept=False)
    assert "kept" not in summary
    assert "/thing" not in Bag(tmp_path / "d").types


# -- long runs: stopped, failed, quiet ------------------------------------------------------


def test_an_interrupted_or_failed_export_leaves_no_damaged_bag(
    robot: dict[str, tuple[Path, Path]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, rec_path = robot["ros2-mcap"]
    out = tmp_path / "back"

    def stop(count: int) -> None:
        if count == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        export_bag(rec_path, out, progress=stop)
    assert list(tmp_path.iterdir()) == []
    export_bag(rec_path, out)
    before = sorted((p.name, p.stat().st_size) for p in out.iterdir())
    calls = []

    def fail(self: KeptConnections, message: KeptMessage) -> None:
        calls.append(message)
        if len(calls) > 100:
            raise OSError("disk gone")

    monkeypatch.setattr(KeptConnections, "write", fail)
    with pytest.raises(OSError, match="disk gone"):
        export_bag(rec_path, out, overwrite=True)
    assert [p.name for p in tmp_path.iterdir()] == ["back"]  # the earlier bag, whole
    assert sorted((p.name, p.stat().st_size) for p in out.iterdir()) == before


def test_the_cli_gives_the_bag_back(
    robot: dict[str, tuple[Path, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, rec_path = robot["ros2-sqlite3"]
    assert main(["export", str(rec_path), str(tmp_path / "a"), "--to", "rosbag", "-q"]) == 0
    assert capsys.readouterr() == ("", "")
    assert list((tmp_path / "a").glob("*.db3"))  # as it came: ROS 2, sqlite3
    assert Bag(tmp_path / "a").counts() == Bag(path).counts()
    assert main(["export", str(rec_path), str(tmp_path / "b"), "--to", "rosbag2"]) == 0
    said = capsys.readouterr().out
    assert "rosbag2, sqlite3" in said
    assert "kept topics: 11, 477 messages" in said
    assert "camera topics as recorded" in said
    argv = ["export", str(rec_path), str(tmp_path / "c.bag"), "--to", "rosbag1", "--no-kept"]
    assert main(argv) == 0
    assert set(Bag(tmp_path / "c.bag").types) == {
        "/camera/depth/image_raw",
        "/camera/color/image_raw",
        "/camera/depth/camera_info",
        "/camera/color/camera_info",
        "/tf",  # the camera's poses, from the input's /tf
    }


def test_a_recording_of_no_bag_exports_as_before(tmp_path: Path) -> None:
    rec = tmp_path / "x.pcdc"
    pcdcodec.encode(SEQUENCES["sample"].root, rec, max_frames=2)
    summary = export_bag(rec, tmp_path / "x.bag")
    assert summary["format"] == "rosbag1"
    assert "kept" not in summary
    assert summary["topics"] == [
        "/camera/depth/image_raw",
        "/camera/color/image_raw",
        "/camera/depth/camera_info",
        "/camera/color/camera_info",
        "/tf",  # the sample's trajectory
    ]
