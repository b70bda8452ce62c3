"""What a recording does not hold of its input is named: every source lists the topics, tracks
or cameras it leaves out (``Source.left_out``), and ``encode`` and ``info`` print them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.ros.bagfile import open_reader
from pcdcodec.ros.bagwriter import BagWriter, MessageBuilder
from pcdcodec.sources import open_source

from .conftest import SHARED_DATA

BAGS = SHARED_DATA / "bags"
REALSENSE = BAGS / "realsense" / "single_depth_color_640x480.bag"
MKV = BAGS / "pyk4a_recording.mkv"


def _cli(*args: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "pcdcodec", *args], capture_output=True, text=True, check=False
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def _topics(path: Path) -> dict[str, int]:
    """Every topic of a bag with its message count, as rosbags lists them."""
    reader, tmp = open_reader(path)
    try:
        counts: dict[str, int] = {}
        for c in reader.connections:
            counts[c.topic] = counts.get(c.topic, 0) + c.msgcount
        return counts
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()


def _listed(out: str, items: dict[str, int | None]) -> None:
    """Every left-out item is on a line of ``out`` with its message count."""
    lines = out.splitlines()
    head = [line for line in lines if "left out" in line]
    assert head, out
    assert f"{len(items)} of the input's" in head[0], out
    for name, count in items.items():
        hits = [line for line in lines if line.strip().startswith(name + " ")]
        assert hits, f"{name} not listed:\n{out}"
        if count is not None:
            assert f", {count} msgs]" in hits[0]


# -- RealSense .bag ----------------------------------------------------------------------------


@pytest.mark.skipif(not REALSENSE.exists(), reason=f"{REALSENSE} is not present")
def test_realsense_bag_names_its_70_topics_but_the_8_it_records(tmp_path: Path) -> None:
    topics = _topics(REALSENSE)
    assert len(topics) == 70
    d, c = "/device_0/sensor_0/Depth_0", "/device_0/sensor_1/Color_0"
    kept = {
        f"{d}/image/data",
        f"{c}/image/data",
        f"{d}/info/camera_info",
        f"{c}/info/camera_info",
        f"{d}/tf/0",
        f"{c}/tf/0",
        "/device_0/sensor_0/option/Depth Units/value",
        "/device_0/info",
    }
    want = {t: n for t, n in topics.items() if t not in kept}
    with open_source(REALSENSE) as src:
        # By default every topic not made into frames is kept: nothing is left out.
        assert src.left_out == ()
        assert len({t.topic for t in src.kept_topics()}) == 68
    with open_source(REALSENSE, keep_topics=False) as src:
        got = {s.name: s.count for s in src.left_out}
        types = {s.name: s.type for s in src.left_out}
        # the device's info is recorded whole: every key it holds
        assert "Usb Type Descriptor" in src.metadata["device_info"]
    assert got == want
    assert types["/device_0/sensor_0/Depth_0/image/metadata"] == "diagnostic_msgs/msg/KeyValue"
    assert got["/device_0/sensor_0/Depth_0/image/metadata"] == 36

    # (its one color frame is 268 ms from the depth it would pair with: past the default limit)
    summary = pcdcodec.encode(
        REALSENSE, tmp_path / "rs.pcdc", max_difference=300_000_000, keep_topics=False
    )
    assert {s["name"]: s["messages"] for s in summary.left_out} == want
    assert summary.to_dict()["left_out"] == summary.left_out

    argv = ["encode", str(REALSENSE), "-o", str(tmp_path / "cli.pcdc"), "--max-difference", "300ms"]
    argv += ["--exclude-topic", "*"]
    out = _cli(*argv)
    _listed(out, want)
    _listed(_cli("info", str(REALSENSE), "--exclude-topic", "*"), want)


def test_a_depth_units_option_given_leaves_the_recorded_one_out(tmp_path: Path) -> None:
    from .camera_file_fuzz import rs_spec, write_bag

    path = tmp_path / "small.bag"
    write_bag(rs_spec(), path)
    units = "/device_0/sensor_0/option/Depth Units/value"
    with open_source(path, keep_topics=False) as src:
        assert [s.name for s in src.left_out] == ["/file_version"]
    with open_source(path, depth_scale=5000, keep_topics=False) as src:
        assert [s.name for s in src.left_out] == [units, "/file_version"]
    with open_source(path, depth_scale=5000) as src:  # kept, then, as it came
        assert src.left_out == ()
        assert {units, "/file_version"} <= {t.topic for t in src.kept_topics()}


# -- ROS 1 and ROS 2 bags ----------------------------------------------------------------------

_KEPT = {"depth_topic", "color_topic", "info_topic", "cloud_topic"}


@pytest.mark.parametrize(
    "bag",
    [
        "spot/raw.bag",
        "spot/compressed.bag",
        "ros2-converted/rs_ros2_mcap",
        "ros2-converted/spot_ros2_sqlite",
        "ros2-converted/spot_ros2_mcap",
    ],
)
def test_real_bags_list_every_topic_they_do_not_read(bag: str, tmp_path: Path) -> None:
    path = BAGS / bag
    if not path.exists():
        pytest.skip(f"{path} is not present")
    topics = _topics(path)
    options: dict[str, Any] = {"max_difference": 10**9}
    if bag == "ros2-converted/rs_ros2_mcap":
        # Its color camera is apart from the depth, and the bag has no tf: the transform given.
        options["depth_to_color"] = np.eye(4)
    with open_source(path, **options) as src:
        kept = {t.topic for t in src.kept_topics()}
        assert src.left_out == ()  # by default every other topic is kept
    options["keep_topics"] = False
    with open_source(path, **options) as src:
        read = {getattr(src, k) for k in _KEPT} - {None, ""}
        read |= {src.metadata.get("ros_color_info_topic")} - {None}
        got = {s.name: s.count for s in src.left_out}
        h, w = src._shape or (0, 0)
        camera = None if src.intrinsics else pcdcodec.CameraIntrinsics(w, h, 300, 300, w / 2, h / 2)
    want = {t: n for t, n in topics.items() if t not in read}
    assert got == want
    assert set(want) <= kept
    summary = pcdcodec.encode(path, tmp_path / "x.pcdc", intrinsics=camera, **options)
    assert {s["name"]: s["messages"] for s in summary.left_out} == want
    if bag == "ros2-converted/rs_ros2_mcap":
        # Depth, color and both CameraInfo topics: the bag holds nothing else.
        assert want == {}, want
        assert "left out" not in _cli("info", str(path))
    else:
        assert want, "each of these bags holds topics that are not recorded"
        _listed(_cli("info", str(path), "--exclude-topic", "*"), want)


_T0 = 1_700_000_000 * 1_000_000_000


def _imu(b: MessageBuilder, ns: int) -> bytes:
    t = b.types
    vec = t["geometry_msgs/msg/Vector3"]
    msg = t["sensor_msgs/msg/Imu"](
        header=b.header(ns),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=vec(x=0.0, y=0.0, z=0.1),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vec(x=0.0, y=0.0, z=9.8),
        linear_acceleration_covariance=np.zeros(9),
    )
    return b.serialize(msg)


def _rs_ros_bag(path: Path, ros2: bool, tf_static: bool = False) -> Path:
    """A bag as realsense-ros publishes one: depth, color, infrared, IMU and camera infos."""
    b = MessageBuilder(ros2, "camera_depth_optical_frame")
    w = BagWriter(path, "rosbag2" if ros2 else "rosbag1", "mcap", b)
    topics = {
        "/camera/depth/image_rect_raw": "sensor_msgs/msg/Image",
        "/camera/depth/camera_info": "sensor_msgs/msg/CameraInfo",
        "/camera/color/image_raw": "sensor_msgs/msg/Image",
        "/camera/infra1/image_rect_raw": "sensor_msgs/msg/Image",
        "/camera/imu": "sensor_msgs/msg/Imu",
    }
    for topic, msgtype in topics.items():
        w.add(topic, msgtype)
    if tf_static:
        w.add("/tf_static", "tf2_msgs/msg/TFMessage")
        w.write("/tf_static", _T0, b.tf(_T0, np.eye(4), "camera_link"))
    cam = pcdcodec.CameraIntrinsics(8, 6, 5.0, 5.0, 3.5, 2.5)
    rng = np.random.default_rng(3)
    for k in range(3):
        t = _T0 + k * 33_333_333
        w.write(
            "/camera/depth/image_rect_raw",
            t,
            b.image(t, rng.integers(1, 4000, (6, 8)).astype(np.uint16), "16UC1"),
        )
        w.write("/camera/depth/camera_info", t, b.camera_info(t, cam, "plumb_bob", [0.0] * 5))
        w.write(
            "/camera/color/image_raw",
            t,
            b.image(t, rng.integers(0, 256, (6, 8, 3)).astype(np.uint8), "rgb8"),
        )
        w.write(
            "/camera/infra1/image_rect_raw",
            t,
            b.image(t, rng.integers(0, 256, (6, 8)).astype(np.uint8), "mono8"),
        )
        for j in range(4):
            w.write("/camera/imu", t + j * 5_000_000, _imu(b, t + j * 5_000_000))
    w.close()
    return path


@pytest.mark.parametrize("ros2", [False, True], ids=["ros1", "ros2-mcap"])
def test_synthetic_bag_names_infrared_and_imu(ros2: bool, tmp_path: Path) -> None:
    path = _rs_ros_bag(tmp_path / ("bag" if ros2 else "x.bag"), ros2)
    want = {"/camera/imu": 12, "/camera/infra1/image_rect_raw": 3}
    with open_source(path) as src:
        assert src.left_out == ()
        assert set(want) <= {t.topic for t in src.kept_topics()}
    with open_source(path, keep_topics=False) as src:
        assert src.color_topic == "/camera/color/image_raw"
        got = src.left_out
    assert {s.name: s.count for s in got} == want
    assert {s.name: s.type for s in got}["/camera/imu"] == "sensor_msgs/msg/Imu"
    summary = pcdcodec.encode(path, tmp_path / "x.pcdc", keep_topics=False)
    assert summary.frames == 3
    assert {s["name"]: s["messages"] for s in summary.left_out} == want
    none = ("--exclude-topic", "*")
    _listed(_cli("encode", str(path), "-o", str(tmp_path / "cli.pcdc"), *none), want)
    _listed(_cli("info", str(path), *none), want)
    info = _cli("info", str(path), "--json", *none)
    import json

    assert {s["name"] for s in json.loads(info)["left_out"]} == set(want)


def test_tf_that_gives_the_camera_no_pose_is_left_out(tmp_path: Path) -> None:
    """A /tf_static that only mounts the camera gives no poses: once read, it is named."""
    path = _rs_ros_bag(tmp_path / "tf.bag", False, tf_static=True)
    with open_source(path, keep_topics=False) as src:
        assert "/tf_static" not in {s.name for s in src.left_out}  # read for poses
        frames = list(src)
        assert all(f.pose is None for f in frames)
        assert "/tf_static" in {s.name for s in src.left_out}
    summary = pcdcodec.encode(path, tmp_path / "x.pcdc", keep_topics=False)
    assert "/tf_static" in {s["name"] for s in summary.left_out}


# -- Azure Kinect .mkv -------------------------------------------------------------------------


@pytest.mark.skipif(not MKV.exists(), reason=f"{MKV} is not present")
def test_azure_kinect_names_its_infrared_and_imu_tracks(tmp_path: Path) -> None:
    with open_source(MKV) as src:
        assert src.left_out == ()  # by default its other tracks and attachments are kept
    with open_source(MKV, keep_topics=False) as src:
        got = {s.name: (s.type, s.count) for s in src.left_out}
        assert len(src) == 1  # the frame count, from the file's blocks
    assert got == {"IMU": ("subtitle", 1), "IR": ("video b16g", 1)}
    summary = pcdcodec.encode(MKV, tmp_path / "k.pcdc", keep_topics=False)
    assert {s["name"] for s in summary.left_out} == {"IR", "IMU"}
    want = {"IR": 1, "IMU": 1}
    # (the calibration, read for the cameras, is recorded: never left out)
    none = ("--exclude-topic", "/k4a/i*")
    _listed(_cli("encode", str(MKV), "-o", str(tmp_path / "cli.pcdc"), *none), want)
    info = _cli("info", str(MKV), *none)
    _listed(info, want)
    assert "frames       1" in info


def _mkv_with_ir(path: Path, captures: int) -> Path:
    from .camera_file_fuzz import _bih, _block, _track, mkv_spec

    spec = mkv_spec(captures)
    spec.tracks.append(
        _track(3, 0x0111_2222_3333_4444, "IR", _bih(320, 288, 16, b"b16g", 320 * 288 * 2), 320, 288)
    )
    for cluster in spec.clusters:
        cluster[1].append(_block(3, 0, bytes(320 * 288 * 2)))
    path.write_bytes(spec.to_bytes())
    return path


def test_synthetic_mkv_counts_its_frames_and_its_infrared_blocks(tmp_path: Path) -> None:
    path = _mkv_with_ir(tmp_path / "ir.mkv", 4)
    with open_source(path, keep_topics=False) as src:
        assert src.frame_count == 4
        assert [(s.name, s.count) for s in src.left_out] == [("IR", 4)]
        assert len(list(src)) == 4
    assert "frames       4" in _cli("info", str(path))


# -- several cameras: a rig bag, and a camera of a rig's recording ---------------------------


def test_rig_bag_leaves_out_what_no_camera_reads(tmp_path: Path) -> None:
    from pcdcodec.recording import encode_rig

    from .test_rig_ingest import _cameras, write_rig_bag

    cams = _cameras()[:2]
    path = write_rig_bag(tmp_path / "rig.bag", cams, ros2=False)
    # Add an IMU topic: read by no camera.
    extra = tmp_path / "rig_imu.bag"
    _copy_with_imu(path, extra)
    summary = encode_rig([extra], tmp_path / "rig.pcdc")
    assert summary.left_out == {
        str(extra): [{"name": "/imu", "type": "sensor_msgs/msg/Imu", "messages": 2}]
    }
    for cam in summary.cameras.values():  # a camera does not call the others' topics lost
        assert "left_out" not in cam.source
    out = _cli("encode", str(extra), "-o", str(tmp_path / "cli.pcdc"))
    _listed(out, {"/imu": 2})
    assert "/cam_wrist/depth/image_raw" not in out.split("left out")[1]


def _copy_with_imu(src: Path, dst: Path) -> None:
    """``src`` (a ROS 1 bag) written again with two /imu messages added."""
    from rosbags.rosbag1 import Reader, Writer

    b = MessageBuilder(False, "imu_link")
    with Reader(src) as reader, Writer(dst) as writer:
        conns: dict[int, Any] = {}
        for c in reader.connections:
            conns[c.id] = writer.add_connection(c.topic, c.msgtype, typestore=b.store)
        imu = writer.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=b.store)
        first = True
        for c, t, raw in reader.messages():
            if first:
                for k in range(2):
                    writer.write(imu, t + k, _imu(b, t + k))
                first = False
            writer.write(conns[c.id], t, raw)


def test_a_camera_of_a_rig_recording_leaves_the_others_out(tmp_path: Path) -> None:
    from pcdcodec.recording import encode_rig

    from .test_rig_ingest import _cameras, write_rig_bag

    cams = _cameras()[:2]
    bag = write_rig_bag(tmp_path / "rig.bag", cams, ros2=False)
    rig = tmp_path / "rig.pcdc"
    encode_rig([bag], rig)
    with open_source(rig, camera="cam_head") as src:
        assert [(s.name, s.count) for s in src.left_out] == [("camera cam_wrist", 3)]
    summary = pcdcodec.encode(rig, tmp_path / "head.pcdc", camera="cam_head")
    assert summary.left_out == [{"name": "camera cam_wrist", "type": "camera", "messages": 3}]


def test_inputs_that_hold_nothing_else_leave_nothing_out(tmp_path: Path) -> None:
    rec = tmp_path / "one.pcdc"
    summary = pcdcodec.encode(_rs_ros_bag(tmp_path / "b.bag", False), rec, keep_topics=False)
    assert summary.left_out
    with open_source(rec) as src:
        assert src.left_out == ()
    assert "left out" not in _cli("info", str(rec))


# -- info of a recording: poses, ratio, the effective gop --------------------------------------


def test_info_shows_poses_ratio_and_the_effective_gop(tmp_path: Path) -> None:
    import json

    from pcdcodec.datasets import load_sample

    seq = load_sample()
    path = tmp_path / "posed.pcdc"
    rng = np.random.default_rng(0)
    with pcdcodec.RecordingWriter(
        path, intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, fps=30.0
    ) as w:
        for k, f in enumerate(list(seq)[:12]):
            pose = np.eye(4)
            pose[:3, 3] = rng.normal(size=3)
            w.write(f.color, f.depth, 1_000_000_000 + k * 33_333_333, pose=pose if k else None)
    info = json.loads(_cli("info", str(path), "--json"))
    assert info["poses"]["count"] == 11  # every frame but the first
    assert info["poses"]["first_ns"] == 1_033_333_333
    assert info["poses"]["span_s"] == round(10 * 33_333_333 / 1e9, 3)
    h, w_ = seq.intrinsics.shape
    assert info["raw_rgbd_bytes"] == 12 * w_ * h * 5
    assert info["ratio_raw_rgbd"] == round(12 * w_ * h * 5 / path.stat().st_size, 2)
    assert info["codecs"]["color"]["gop"] is None  # as stored: the default
    assert info["color_gop"]["gop"] == 10  # a third of a second at 30 fps
    assert info["color_gop"]["keyframes"] >= 2
    text = _cli("info", str(path))
    assert "poses      11 of 12 frames" in text
    assert f"{info['ratio_raw_rgbd']:g}x against raw RGB-D" in text
    assert "gop 10 " in text

    set_gop = tmp_path / "gop3.pcdc"
    pcdcodec.encode(path, set_gop, color="h264:gop=3")
    info = json.loads(_cli("info", str(set_gop), "--json"))
    assert info["color_gop"] == {"gop": 3, "configured": 3, "keyframes": 4}
    assert info["poses"]["count"] == 11  # re-encoding keeps them


# -- folders -----------------------------------------------------------------------------------


def test_a_folder_names_its_files_that_are_not_recorded(tmp_path: Path) -> None:
    from .test_archive import make_input

    folder = make_input(tmp_path / "tum", count=4)
    (folder / "accelerometer.txt").write_text("# accelerometer data\n1.0 0.1 9.8 0.2\n")
    (folder / "notes").mkdir()
    with open_source(folder) as src:
        assert [(s.name, s.type) for s in src.left_out] == [
            ("accelerometer.txt", "file"),
            ("notes", "folder"),
        ]
        assert {"rgb", "depth", "associations.txt", "camera.json"} <= src.recorded_streams()
    summary = pcdcodec.encode(folder, tmp_path / "f.pcdc")
    assert [s["name"] for s in summary.left_out] == ["accelerometer.txt", "notes"]
    _listed(_cli("info", str(folder)), {"accelerometer.txt": None, "notes": None})


def test_tum_folder_leaves_out_its_accelerometer_only() -> None:
    tum = SHARED_DATA / "tum_fr1_rpy"
    if not tum.exists():
        pytest.skip(f"{tum} is not present")
    with open_source(tum, depth_scale=5000) as src:
        names = {s.name for s in src.left_out}
        assert src.poses is not None  # groundtruth.txt is read: poses
    assert "accelerometer.txt" in names
    assert names.isdisjoint({"rgb", "depth", "rgb.txt", "depth.txt", "groundtruth.txt"})
    assert names <= {"accelerometer.txt", "README.md"}  # the data's README, where present


def test_7scenes_folder_reads_its_camera_and_pose_files() -> None:
    scenes = SHARED_DATA / "7scenes_redkitchen"
    if not scenes.exists():
        pytest.skip(f"{scenes} is not present")
    with open_source(scenes) as src:
        assert {"rgb", "depth", "pose", "camera-intrinsics.txt"} <= src.recorded_streams()
        assert {s.name for s in src.left_out} <= {"README.md"}


# -- live RealSense, played back from a .bag -----------------------------------------------------


@pytest.mark.skipif(not REALSENSE.exists(), reason=f"{REALSENSE} is not present")
def test_live_playback_names_the_bags_topics_it_does_not_record(tmp_path: Path) -> None:
    pytest.importorskip("pyrealsense2")
    from pcdcodec.sources import realsense_live
    from pcdcodec.sources.realsense import RealSenseBagSource

    with RealSenseBagSource(REALSENSE, keep_topics=False) as bag:
        want = {s.name: s.count for s in bag.left_out}
        color = {t for t in bag.recorded_streams() if "/Color_0/" in t}
    with realsense_live(playback=REALSENSE) as live:
        assert {s.name: s.count for s in live.left_out} == want
        assert live.describe()["left_out"] == [s.to_dict() for s in live.left_out]
    with realsense_live(playback=REALSENSE, color=False) as live:
        got = {s.name for s in live.left_out}
    assert got == set(want) | color | {"/device_0/sensor_0/Depth_0/tf/0"}
    out = _cli("record", "-o", str(tmp_path / "live.pcdc"), "--playback", str(REALSENSE))
    _listed(out, want)


def test_info_of_a_rig_gives_each_cameras_poses_and_gop(tmp_path: Path) -> None:
    import json

    from pcdcodec.recording import encode_rig

    from .test_rig_ingest import _cameras, write_rig_bag

    cams = _cameras()[:2]
    bag = write_rig_bag(tmp_path / "rig.bag", cams, ros2=False)
    rig = tmp_path / "rig.pcdc"
    encode_rig([bag], rig)
    info = json.loads(_cli("info", str(rig), "--json"))
    raw = 0
    for cam, spec in zip(info["cameras"], cams, strict=True):
        assert cam["poses"]["count"] == 0  # /tf_static mounts them: no trajectory
        assert cam["color_gop"]["gop"] == 10  # the default at 30 fps
        assert cam["color_gop"]["configured"] is None
        h, w = spec.depths[0].shape
        assert cam["raw_rgbd_bytes"] == len(spec.times) * w * h * 5
        raw += cam["raw_rgbd_bytes"]
    assert info["raw_rgbd_bytes"] == raw
    assert info["ratio_raw_rgbd"] == round(raw / rig.stat().st_size, 2)
    text = _cli("info", str(rig))
    assert text.count("gop 10 ") == 2
    assert text.count("poses      none") == 2
    assert f"{info['ratio_raw_rgbd']:g}x against raw RGB-D" in text
