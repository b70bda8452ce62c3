"""Kept images and organized clouds stored compressed (``docs/bags.md``): 16-bit images through
a lossless depth codec or as a reference to an equal depth frame, 8-bit images through
lossless JPEG XL, clouds made from a recorded depth frame rebuilt from it; every message given
back byte for byte, and those that would not rebuild exactly kept as they came."""

from __future__ import annotations

import collections
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.errors import DecodeError, InputError
from pcdcodec.recording._kept_pack import CLOUD_ENCODING, IMAGE_ENCODING, unpack
from pcdcodec.ros.kept import KeptMessage, KeptTopic

from .conftest import SEQUENCES

SET = "realsense_d435"
BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}
CAMERA = pcdcodec.CameraIntrinsics(64, 48, 50.0, 50.0, 31.5, 23.5)


@pytest.fixture(scope="module")
def frames() -> list[tuple[Any, Any]]:
    if not SEQUENCES[SET].present:
        pytest.skip(f"{SEQUENCES[SET].root} is not present")
    return list(rb.SequenceFrames(SET, 4))


def _original(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    from rosbags.highlevel import AnyReader

    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    with AnyReader([path]) as reader:
        for c, t, raw in reader.messages():
            out[c.topic].append((t, bytes(raw)))
    return out


def _kept(rec: Any) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = collections.defaultdict(list)
    for m in rec.kept_messages():
        out[m.topic.topic].append((m.log_time, m.data))
    return out


def _channels(path: Path) -> dict[str, collections.Counter[str]]:
    """Messages per kept topic and channel message encoding, as other MCAP tools see them
    (the camera topics' channels, which hold their envelopes, left out)."""
    from mcap.reader import make_reader

    out: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    with open(path, "rb") as f:
        for _schema, channel, _message in make_reader(f).iter_messages():
            if "pcdcodec.kept" in channel.metadata and "pcdcodec.camera" not in channel.metadata:
                out[channel.topic][channel.message_encoding] += 1
    return out


@pytest.mark.parametrize("kind", ["ros1", "ros2-mcap"])
def test_a_robot_bag_comes_back_byte_for_byte_with_images_and_cloud_packed(
    kind: str, frames: Any, tmp_path: Path
) -> None:
    seq = SEQUENCES[SET]
    bag = tmp_path / ("robot.bag" if kind == "ros1" else "robot")
    rb.write_robot_bag(
        bag, frames, kind=kind, intrinsics=seq.camera, depth_scale=seq.depth_scale, seconds=1.0
    )
    out = tmp_path / "robot.pcdc"
    summary = pcdcodec.encode(bag, out)
    original = _original(bag)
    with pcdcodec.Recording(out) as rec:
        kept = _kept(rec)
        topics = {t.topic: t for t in rec.kept_topics}
    # The frames are the aligned depth and the color; every other topic is kept, exactly.
    assert set(kept) == set(original) - {rb.ALIGNED, rb.COLOR}
    for topic, messages in kept.items():
        assert messages == original[topic], topic
    # The other depth image and the cloud are packed, every message of them (each equals
    # what the recording holds); the kept topic says the bag's own encoding.
    channels = _channels(out)
    assert channels[rb.DEPTH] == {IMAGE_ENCODING: 30}
    assert channels[rb.CLOUD] == {CLOUD_ENCODING: 15}
    assert topics[rb.CLOUD].message_encoding == ("ros1" if kind == "ros1" else "cdr")
    assert topics[rb.DEPTH].msgtype == "sensor_msgs/msg/Image"
    written = {k["name"]: k["bytes"] for k in summary.kept}
    raw = {t: sum(len(d) for _, d in m) for t, m in original.items()}
    assert written[rb.DEPTH] < raw[rb.DEPTH] / 1000  # a reference to each recorded frame
    assert written[rb.CLOUD] < raw[rb.CLOUD] / 20  # the colours, losslessly


def test_the_other_depth_topic_is_coded_when_the_recorded_depth_is_lossy(
    frames: Any, tmp_path: Path
) -> None:
    """With a lossy depth codec the frames cannot stand in for the kept depth, nor make the
    cloud: the image is coded on its own (depthac), the cloud kept as it came."""
    seq = SEQUENCES[SET]
    bag = tmp_path / "robot.bag"
    rb.write_robot_bag(
        bag, frames[:2], intrinsics=seq.camera, depth_scale=seq.depth_scale, seconds=0.2,
        extras=False,
    )  # fmt: skip
    out = tmp_path / "robot.pcdc"
    summary = pcdcodec.encode(bag, out, depth="depthac:max_error=0.002")
    with pcdcodec.Recording(out) as rec:
        kept = _kept(rec)
    original = _original(bag)
    for topic, messages in kept.items():
        assert messages == original[topic], topic
    channels = _channels(out)
    assert set(channels[rb.DEPTH]) == {IMAGE_ENCODING}
    assert set(channels[rb.CLOUD]) == {"ros1"}
    written = {k["name"]: k["bytes"] for k in summary.kept}
    raw = sum(len(d) for _, d in original[rb.DEPTH])
    assert written[rb.DEPTH] < raw / 2


def test_real_spot_images_come_back_byte_for_byte(tmp_path: Path) -> None:
    """The Spot bag's mono8 and rgb8 images (big-endian flag set on 8-bit images)."""
    path = BAGS / "spot" / "raw.bag"
    if not path.exists():
        pytest.skip(f"{path} is not present")
    out = tmp_path / "spot.pcdc"
    pcdcodec.encode(path, out, intrinsics=SPOT_CAMERA, color_topic="")
    original = _original(path)
    with pcdcodec.Recording(out) as rec:
        kept = _kept(rec)
    assert len(kept) == 3
    for topic, messages in kept.items():
        assert messages == original[topic], topic
    assert all(set(c) == {IMAGE_ENCODING} for c in _channels(out).values())
    raw = sum(len(d) for t in kept for _, d in original[t])
    assert out.stat().st_size < raw  # the depth frame itself included


def _image_message(ros1: bool, array: np.ndarray[Any, Any], encoding: str, step: int) -> bytes:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = store.types
    header = t["std_msgs/msg/Header"](
        **({"seq": 3} if ros1 else {}),
        stamp=t["builtin_interfaces/msg/Time"](sec=5, nanosec=0),
        frame_id="ir",
    )
    rows = array.reshape(array.shape[0], -1).view(np.uint8)
    data = np.zeros((array.shape[0], step), np.uint8)
    data[:, : rows.shape[1]] = rows
    msg = t["sensor_msgs/msg/Image"](
        header=header, height=array.shape[0], width=array.shape[1], encoding=encoding,
        is_bigendian=0, step=step, data=data.reshape(-1),
    )  # fmt: skip
    if ros1:
        return bytes(store.serialize_ros1(msg, "sensor_msgs/msg/Image"))
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/Image"))


@pytest.mark.parametrize("ros1", [True, False])
def test_images_that_would_not_rebuild_are_kept_as_they_came(ros1: bool, tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    ir16 = rng.integers(0, 4000, (48, 64), dtype=np.uint16)
    ir8 = rng.integers(0, 255, (48, 64), dtype=np.uint8)
    rgb = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
    messages = {
        "/ir16": _image_message(ros1, ir16, "16UC1", 128),
        "/y16": _image_message(ros1, ir16, "Y16", 128),
        "/ir8": _image_message(ros1, ir8, "mono8", 64),
        "/rgb": _image_message(ros1, rgb, "rgb8", 192),
        "/padded": _image_message(ros1, ir8, "mono8", 72),  # rows padded past the pixels
        "/odd": _image_message(ros1, ir8, "yuv422_odd", 64),  # an encoding not packed
    }
    enc = "ros1" if ros1 else "cdr"
    schema = "ros1msg" if ros1 else "ros2msg"
    topics = {n: KeptTopic(n, "sensor_msgs/msg/Image", schema, "# Image", enc) for n in messages}
    out = tmp_path / "x.pcdc"
    with pcdcodec.RecordingWriter(
        out, intrinsics=CAMERA, color=None, kept_topics=list(topics.values())
    ) as w:
        w.write(None, ir16, 5_000_000_000)
        for name, data in messages.items():
            w.write_message(KeptMessage(topics[name], 5_000_000_000 + 1, data))
    with pcdcodec.Recording(out) as rec:
        back = {m.topic.topic: m.data for m in rec.kept_messages()}
        assert rec.kept_topics == list(topics.values())
    assert back == messages
    channels = _channels(out)
    packed = {n for n, c in channels.items() if set(c) == {IMAGE_ENCODING}}
    assert packed == {"/ir16", "/y16", "/ir8", "/rgb"}
    assert set(channels["/padded"]) == set(channels["/odd"]) == {enc}


def _cloud_message(pts: np.ndarray[Any, Any], ns: int) -> bytes:
    from pcdcodec.bench.robot_streams import BagMessages

    return bytes(BagMessages(ros2=False).cloud(rb.CLOUD, rb.DEPTH_FRAME, ns, pts))


def _cloud_of(depth: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    pts = np.zeros(depth.shape, rb.REALSENSE_CLOUD_DTYPE)
    xyz = np.nan_to_num(pcdcodec.Projector(CAMERA, 1000.0).to_organized(depth), nan=0.0)
    for axis, name in enumerate("xyz"):
        pts[name] = xyz[..., axis]
    pts["rgb"] = np.arange(depth.size, dtype=np.uint32).reshape(depth.shape) * 2654435761 >> 8
    return pts


def test_clouds_not_made_from_a_recorded_frame_are_kept_as_they_came(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    depth = rng.integers(300, 3000, (48, 64), dtype=np.uint16)
    depth[::7, ::5] = 0
    made = _cloud_of(depth)
    nudged = made.copy()
    nudged["z"][10, 10] = np.nextafter(nudged["z"][10, 10], np.float32(9), dtype=np.float32)
    nudged["z"][10, 11] = np.nextafter(nudged["z"][10, 11], np.float32(9), dtype=np.float32)
    nudged["z"][10, 11] = np.nextafter(nudged["z"][10, 11], np.float32(9), dtype=np.float32)
    filtered = made.copy()
    filtered["z"][depth > 2500] = 0
    t = 7_000_000_000
    clouds = [
        ("made", _cloud_message(made, t), True),
        ("one ulp", _cloud_message(_nudge(made), t), True),
        ("two ulps", _cloud_message(nudged, t), False),  # z two ulps off at one point
        ("filtered", _cloud_message(filtered, t), False),
        ("no frame", _cloud_message(made, t + 500_000_000), False),  # no frame at its stamp
    ]
    topic = KeptTopic(rb.CLOUD, "sensor_msgs/msg/PointCloud2", "ros1msg", "# cloud", "ros1")
    out = tmp_path / "x.pcdc"
    with pcdcodec.RecordingWriter(out, intrinsics=CAMERA, color=None, kept_topics=[topic]) as w:
        w.write(None, depth, t)
        for k, (_, data, _) in enumerate(clouds):
            w.write_message(KeptMessage(topic, t + 1 + k, data))
    with pcdcodec.Recording(out) as rec:
        back = [m.data for m in rec.kept_messages()]
    assert back == [data for _, data, _ in clouds]
    from mcap.reader import make_reader

    with open(out, "rb") as f:
        encodings = [
            c.message_encoding
            for _, c, _ in make_reader(f).iter_messages(topics=[rb.CLOUD], log_time_order=True)
        ]
    assert encodings == [CLOUD_ENCODING if packed else "ros1" for _, _, packed in clouds]


def _nudge(pts: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """x and y one float32 ulp off at a few points: still this depth's cloud."""
    out = pts.copy()
    for name in "xy":
        out[name][5, 5:9] = np.nextafter(out[name][5, 5:9], np.float32(-9), dtype=np.float32)
    return out


def test_kept_images_raw_keeps_every_message_as_it_came(frames: Any, tmp_path: Path) -> None:
    seq = SEQUENCES[SET]
    bag = tmp_path / "robot.bag"
    rb.write_robot_bag(
        bag, frames[:2], intrinsics=seq.camera, depth_scale=seq.depth_scale, seconds=0.1,
        extras=False,
    )  # fmt: skip
    from pcdcodec.cli import main

    out = tmp_path / "robot.pcdc"
    assert main(["encode", str(bag), "-o", str(out), "--kept-images", "raw", "-q"]) == 0
    assert all(set(c) == {"ros1"} for c in _channels(out).values())
    assert main(["encode", str(bag), "-o", str(tmp_path / "p.pcdc"), "-q"]) == 0
    assert set(_channels(tmp_path / "p.pcdc")[rb.DEPTH]) == {IMAGE_ENCODING}
    with pytest.raises(InputError, match="kept_images must be one of"):
        pcdcodec.encode(bag, tmp_path / "y.pcdc", kept_images="jpeg")


def test_a_damaged_packed_message_is_an_error_not_wrong_bytes() -> None:
    """Every kind of packed message, cut short or with a byte flipped anywhere: the original
    bytes or a DecodeError naming the file, never another exception or other bytes."""
    from pcdcodec.recording._kept_pack import Packer

    rng = np.random.default_rng(3)
    depth = rng.integers(300, 3000, (48, 64), dtype=np.uint16)
    t = 5_000_000_000
    packer = Packer(pcdcodec.get_codec("depthac"), CAMERA, 1000.0)
    packer.saw_frame(t, depth)
    image = KeptTopic("/i", "sensor_msgs/msg/Image", "", "", "ros1")
    image2 = KeptTopic("/i", "sensor_msgs/msg/Image", "", "", "cdr")
    cloud = KeptTopic(rb.CLOUD, "sensor_msgs/msg/PointCloud2", "", "", "ros1")
    originals = [
        (image, _image_message(True, rng.integers(0, 255, (48, 64), np.uint8), "mono8", 64)),
        (image2, _image_message(False, rng.integers(0, 4000, (48, 64), np.uint16), "16UC1", 128)),
        (image, _image_message(True, depth, "16UC1", 128)),  # t = 5 s: the frame itself
        (cloud, _cloud_message(_cloud_of(depth), t)),
    ]
    camera = (CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy, 1000.0)
    frames = {t: depth}.get
    kinds = set()
    for topic, raw in originals:
        packed = packer.pack(KeptMessage(topic, 1, raw))
        assert packed is not None
        kinds.add(packed[5])
        assert unpack(packed, frames, "x", camera) == raw
        cases = [packed[:n] for n in rng.integers(0, len(packed), 20)]
        for pos in rng.integers(0, len(packed), 60):
            cases.append(packed[:pos] + bytes([packed[pos] ^ 0x10]) + packed[pos + 1 :])
        for damaged in cases:
            try:
                back = unpack(damaged, frames, "'where'", camera)
            except DecodeError as exc:
                message = str(exc)
            else:
                message = "'where'" if back == raw else "other bytes"
            assert "'where'" in message
    assert kinds == {1, 2, 3, 4}
    with pytest.raises(DecodeError, match="not in the file"):
        unpack(packer.pack(KeptMessage(image, 1, originals[2][1])) or b"", {}.get, "x", camera)


def test_compressed_images_stay_as_they_came_beside_packed_ones(tmp_path: Path) -> None:
    """A real ROS 2 bag: its raw images (mono8, rgb8) are packed, its CompressedImage topics
    (JPEG, PNG, compressedDepth) are already compressed and stay on their cdr channels."""
    path = BAGS / "ros2-converted" / "spot_ros2_mcap"
    if not path.exists():
        pytest.skip(f"{path} is not present")
    out = tmp_path / "spot.pcdc"
    pcdcodec.encode(path, out, intrinsics=SPOT_CAMERA, color_topic="")
    original = _original(path)
    with pcdcodec.Recording(out) as rec:
        kept = _kept(rec)
        types = {t.topic: t.msgtype for t in rec.kept_topics}
    for topic, messages in kept.items():
        assert messages == original[topic], topic
    channels = _channels(out)
    for topic, kind in types.items():
        want = IMAGE_ENCODING if kind == "sensor_msgs/msg/Image" else "cdr"
        assert set(channels[topic]) == {want}, topic
    assert "sensor_msgs/msg/CompressedImage" in types.values()
    assert "sensor_msgs/msg/Image" in types.values()


def _realsense_cloud(depth: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """A cloud as librealsense deprojects it (realsense-ros's): float32 throughout."""
    f32 = np.float32
    z = depth.astype(np.float32) * f32(0.001)
    u = np.arange(depth.shape[1], dtype=np.float32)
    v = np.arange(depth.shape[0], dtype=np.float32)
    pts = np.zeros(depth.shape, rb.REALSENSE_CLOUD_DTYPE)
    pts["x"] = ((u - f32(CAMERA.cx)) / f32(CAMERA.fx))[None, :] * z
    pts["y"] = ((v - f32(CAMERA.cy)) / f32(CAMERA.fy))[:, None] * z
    pts["z"] = z
    pts["rgb"] = 0x203040
    return pts


@pytest.mark.parametrize(("make", "rule"), [(_cloud_of, 0), (_realsense_cloud, 1)])
def test_a_cloud_is_rebuilt_by_the_rule_that_made_it(make: Any, rule: int) -> None:
    """pcdcodec's projector (float64 divisions) and librealsense's deprojection (float32)
    differ by up to 2 ulps in x and y: each cloud is rebuilt by the rule that needs no
    correction, and comes back bit-exact."""
    from pcdcodec.recording import _kept_pack as kp

    rng = np.random.default_rng(4)
    depth = rng.integers(300, 6000, (48, 64), dtype=np.uint16)
    depth[::5, ::3] = 0
    t = 9_000_000_000
    packer = kp.Packer(pcdcodec.get_codec("depthac"), CAMERA, 1000.0)
    packer.saw_frame(t, depth)
    raw = _cloud_message(make(depth), t)
    topic = KeptTopic(rb.CLOUD, "sensor_msgs/msg/PointCloud2", "", "", "ros1")
    packed = packer.pack(KeptMessage(topic, 1, raw))
    assert packed is not None
    camera = (CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy, 1000.0)
    assert unpack(packed, {t: depth}.get, "x", camera) == raw
    cur = kp._Cursor(packed, kp._HEAD.size)
    cur.section(), cur.section()
    head = kp._CLOUD_HEAD.unpack(cur.take(kp._CLOUD_HEAD.size))
    assert head[-1] == rule
    for _ in "xyz":
        assert cur.section() == b""  # no corrections: an empty section


def test_a_cloud_of_tum_colours_is_packed_by_its_bayer_pattern_and_old_packs_still_read(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A cloud coloured by a TUM frame (a Kinect v1 through OpenNI: demosaiced) packs its
    colours as the Bayer pattern: well under half of what the version 1 layout (lossless JPEG
    XL) took. Messages packed in the version 1 layout still read, byte for byte."""
    from pcdcodec.datasets import load_sample
    from pcdcodec.recording import _kept_pack as kp

    frame = load_sample(1)[0]
    crop = (slice(200, 248), slice(300, 364))  # the camera's 64 x 48, on even rows and columns
    depth = np.ascontiguousarray(np.asarray(frame.depth)[crop])
    color = np.asarray(frame.color)[crop].astype(np.uint32)
    pts = _cloud_of(depth)
    pts["rgb"] = (color[..., 0] << 16) | (color[..., 1] << 8) | color[..., 2]
    t = 7_000_000_000
    raw = _cloud_message(pts, t)
    topic = KeptTopic(rb.CLOUD, "sensor_msgs/msg/PointCloud2", "", "", "ros1")
    camera = (CAMERA.fx, CAMERA.fy, CAMERA.cx, CAMERA.cy, 1000.0)

    def packed() -> bytes:
        packer = kp.Packer(pcdcodec.get_codec("depthac"), CAMERA, 1000.0)
        packer.saw_frame(t, depth)
        out = packer.pack(KeptMessage(topic, 1, raw))
        assert out is not None
        return out

    now = packed()
    with monkeypatch.context() as m:
        m.setattr(kp, "_VERSION", 1)
        m.setattr(kp, "_colour_encode", lambda pixels, check=False: kp._jxl_encode(pixels))
        old = packed()
    assert (now[4], old[4]) == (2, 1)
    assert len(now) < 0.6 * len(old)
    for data in (now, old):
        assert unpack(data, {t: depth}.get, "x", camera) == raw
    newer = now[:4] + bytes([3]) + now[5:]
    with pytest.raises(DecodeError, match="damaged"):
        unpack(newer, {t: depth}.get, "x", camera)
