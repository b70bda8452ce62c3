"""Bags written as a robot with a RealSense records them (pcdcodec.bench.robot_bags), from the real
RealSense D435 frames: every topic at its rate, stamps before log times, the realsense-ros cloud
layout with z bit-exact, connection headers and QoS, split ROS 2 bags, and pcdcodec reading them."""

from __future__ import annotations

import itertools
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.errors import InputError

from .conftest import SEQUENCES

SET = "realsense_d435"
NS = 1_000_000_000
#: messages in a 1-second bag at 30 fps with the default rates
EXPECTED = {
    rb.COLOR: 30, rb.COLOR_INFO: 30, rb.DEPTH: 30, rb.DEPTH_INFO: 30, rb.ALIGNED: 30,
    rb.ALIGNED_INFO: 30, rb.CLOUD: 15, "/tf_static": 1, "/camera/imu": 200, "/tf": 100,
    "/odom": 50, "/joint_states": 100, "/diagnostics": 1,
}  # fmt: skip
#: how each bag kind is written: (kind, file name, split_bytes)
BAGS = {
    "ros1": ("ros1", "robot.bag", None),
    "ros2-sqlite3": ("ros2-sqlite3", "robot", None),
    "ros2-mcap-split": ("ros2-mcap", "robot", 40_000_000),
}


@pytest.fixture(scope="module")
def frames() -> list[tuple[Any, Any]]:
    if not SEQUENCES[SET].present:
        pytest.skip(f"{SEQUENCES[SET].root} is not present")
    return list(rb.SequenceFrames(SET, 4))


def _write(path: Path, frames: Any, **options: Any) -> rb.RobotBagSummary:
    seq = SEQUENCES[SET]
    return rb.write_robot_bag(
        path, frames, intrinsics=seq.camera, depth_scale=seq.depth_scale, **options
    )


@pytest.fixture(scope="module", params=sorted(BAGS))
def bag(request: Any, frames: Any, tmp_path_factory: Any) -> tuple[str, rb.RobotBagSummary]:
    kind, name, split = BAGS[request.param]
    path = tmp_path_factory.mktemp(request.param) / name
    return request.param, _write(path, frames, kind=kind, seconds=1.0, split_bytes=split)


def _read(path: Path) -> Any:
    """Every message: (connection, log time, message), the big camera messages included."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        conns = list(reader.connections)
        msgs = [(c, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
    return conns, msgs


@pytest.fixture(scope="module")
def contents(bag: Any) -> Any:
    return _read(bag[1].path)


def _ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * NS + int(msg.header.stamp.nanosec)


def test_every_topic_at_its_rate(bag: Any, contents: Any) -> None:
    _, summary = bag
    conns, msgs = contents
    assert {c.topic: c.msgcount for c in conns} == EXPECTED
    assert summary.topics == EXPECTED
    assert {c.topic: c.msgtype for c in conns} == {t: v[0] for t, v in rb.TOPICS.items()}
    counted: dict[str, int] = defaultdict(int)
    for c, _, _ in msgs:
        counted[c.topic] += 1
    assert counted == EXPECTED
    assert 0.95 < summary.duration_s < 1.05
    assert summary.bytes == sum(f.stat().st_size for f in summary.files) + (
        0 if summary.kind == "ros1" else (summary.path / "metadata.yaml").stat().st_size
    )


def test_stamps_increase_and_come_before_log_times(contents: Any) -> None:
    _, msgs = contents
    logs = [t for _, t, _ in msgs]
    assert logs == sorted(logs)
    stamps: dict[str, list[int]] = defaultdict(list)
    for c, t, msg in msgs:
        ns = _ns(msg.transforms[0]) if c.topic in ("/tf", "/tf_static") else _ns(msg)
        assert 0 < t - ns < 60_000_000, c.topic  # a few ms before it was logged
        stamps[c.topic].append(ns)
    for topic, ns in stamps.items():
        assert all(b > a for a, b in itertools.pairwise(ns)), topic
    # color and depth of a frame are stamped within 2 ms of each other
    pairs = zip(stamps[rb.COLOR], stamps[rb.DEPTH], strict=True)
    assert all(0 < c - d < 2_000_000 for c, d in pairs)


def test_cloud_is_realsense_layout_and_z_is_depth_over_scale(contents: Any) -> None:
    _, msgs = contents
    scale = SEQUENCES[SET].depth_scale
    depths = {_ns(m): m for c, _, m in msgs if c.topic == rb.DEPTH}
    colors = {_ns(m): m for c, _, m in msgs if c.topic == rb.COLOR}
    clouds = [m for c, _, m in msgs if c.topic == rb.CLOUD]
    assert clouds
    for cloud in clouds[:3]:
        fields = [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields]
        assert fields == [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 16, 7, 1)]
        assert (cloud.height, cloud.width) == (480, 640)
        assert (cloud.point_step, cloud.row_step) == (20, 20 * 640)
        assert cloud.header.frame_id == rb.DEPTH_FRAME
        assert not cloud.is_bigendian
        pts = np.frombuffer(cloud.data, rb.REALSENSE_CLOUD_DTYPE).reshape(480, 640)
        image = depths[_ns(cloud)]  # the depth image of the cloud's stamp
        depth = np.frombuffer(image.data, "<u2").reshape(480, 640)
        valid = depth > 0
        want = (depth[valid] / scale).astype(np.float32)
        assert np.array_equal(pts["z"][valid].view(np.uint32), want.view(np.uint32))
        assert not pts["z"][~valid].any()
        assert not pts["x"][~valid].any()
        color = min(colors.items(), key=lambda kv: abs(kv[0] - _ns(cloud)))[1]
        rgb = np.frombuffer(color.data, np.uint8).reshape(480, 640, 3).astype(np.uint32)
        assert np.array_equal(pts["rgb"], rgb[..., 0] << 16 | rgb[..., 1] << 8 | rgb[..., 2])


def test_camera_frames_and_cameras(contents: Any) -> None:
    _, msgs = contents
    first = {}
    for c, _, m in msgs:
        first.setdefault(c.topic, m)
    assert first[rb.COLOR].encoding == "rgb8"
    assert first[rb.DEPTH].encoding == "16UC1"
    assert first[rb.ALIGNED].encoding == "16UC1"
    for topic, frame in (
        (rb.COLOR, rb.COLOR_FRAME), (rb.COLOR_INFO, rb.COLOR_FRAME), (rb.DEPTH, rb.DEPTH_FRAME),
        (rb.DEPTH_INFO, rb.DEPTH_FRAME), (rb.ALIGNED, rb.COLOR_FRAME),
        (rb.ALIGNED_INFO, rb.COLOR_FRAME),
    ):  # fmt: skip
        assert first[topic].header.frame_id == frame, topic
    k = SEQUENCES[SET].camera
    info = first[rb.COLOR_INFO]
    assert [float(v) for v in getattr(info, "k", getattr(info, "K", None))] == [
        k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1
    ]  # fmt: skip
    edges = {(e.header.frame_id, e.child_frame_id) for e in first["/tf_static"].transforms}
    assert {("base_link", "camera_link"), ("camera_color_frame", rb.COLOR_FRAME)} <= edges
    assert ("camera_depth_frame", rb.DEPTH_FRAME) in edges
    assert [str(e.child_frame_id) for e in first["/tf"].transforms] == ["base_link"]
    assert len(first["/joint_states"].name) == 7


def test_imu_feels_gravity_and_odometry_is_smooth(contents: Any) -> None:
    _, msgs = contents
    acc = np.array(
        [
            [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
            for c, _, m in msgs
            if c.topic == "/camera/imu"
        ]
    )
    assert np.allclose(acc.mean(axis=0), [0, -9.80665, 0], atol=0.1)  # optical y points down
    assert 0.005 < acc[:, 0].std() < 0.1  # seeded noise, not constant
    xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for c, _, m in msgs
                   if c.topic == "/odom"])  # fmt: skip
    steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert (steps > 0).all()
    assert (steps < 0.02).all()


def test_connection_headers_and_qos(bag: Any, contents: Any) -> None:
    name, _ = bag
    conns, _ = contents
    by_topic = {c.topic: c for c in conns}
    if name == "ros1":
        assert by_topic["/tf_static"].ext.latching == 1
        assert by_topic["/tf_static"].ext.callerid == "/camera/realsense2_camera_manager"
        assert by_topic[rb.COLOR].ext.callerid == "/camera/realsense2_camera_manager"
        assert not by_topic["/odom"].ext.latching
    else:
        from rosbags.interfaces import QosDurability, QosReliability

        (static,) = by_topic["/tf_static"].ext.offered_qos_profiles
        assert static.durability == QosDurability.TRANSIENT_LOCAL
        (imu,) = by_topic["/camera/imu"].ext.offered_qos_profiles
        assert imu.reliability == QosReliability.BEST_EFFORT
        assert by_topic[rb.COLOR].ext.offered_qos_profiles[0].durability == QosDurability.VOLATILE


def test_split_bag_lists_every_file(bag: Any) -> None:
    name, summary = bag
    if name != "ros2-mcap-split":
        assert len(summary.files) == 1
        return
    from ruamel.yaml import YAML

    meta = YAML(typ="safe").load((summary.path / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    names = [f"robot_{i}.mcap" for i in range(len(summary.files))]
    assert len(names) > 3
    assert info["relative_file_paths"] == names
    assert sorted(p.name for p in summary.path.iterdir()) == sorted([*names, "metadata.yaml"])
    assert [f["path"] for f in info["files"]] == names
    assert info["message_count"] == sum(EXPECTED.values())
    assert sum(f["message_count"] for f in info["files"]) == sum(EXPECTED.values())


def test_pcdcodec_reads_the_frames(bag: Any, frames: Any) -> None:
    _, summary = bag
    # Both depth topics are there: pcdcodec picks the one aligned to color on its own.
    with pcdcodec.open_source(summary.path) as source:
        assert source.depth_topic == rb.ALIGNED
        assert source.color_topic == rb.COLOR
        assert source.depth_scale == 1000.0
        got = list(source)
    assert len(got) == 30  # the 4 frames, looped
    for i, frame in enumerate(got[:6]):
        assert np.array_equal(frame.depth, frames[i % 4][0])
        assert np.array_equal(frame.color, frames[i % 4][1])
    with pcdcodec.open_source(summary.path, depth_topic=rb.DEPTH) as source:
        assert source.depth_topic == rb.DEPTH
        assert np.array_equal(next(iter(source)).depth, frames[0][0])


def test_camera_only_unsplit_mcap_and_lz4(frames: Any, tmp_path: Path) -> None:
    mcap = _write(tmp_path / "mcap", frames[:2], kind="ros2-mcap", extras=False, cloud_hz=10)
    want = {t: 2 for t in list(EXPECTED)[:6]} | {rb.CLOUD: 1, "/tf_static": 1}
    assert mcap.topics == want
    assert mcap.files == (tmp_path / "mcap" / "mcap.mcap",)
    assert {c.topic: c.msgcount for c in _read(mcap.path)[0]} == want
    lz4 = _write(tmp_path / "a.bag", frames[:2], compression="lz4", extras=False)
    plain = _write(tmp_path / "b.bag", frames[:2], extras=False)
    assert lz4.bytes < plain.bytes
    _, msgs = _read(lz4.path)
    depth = next(m for c, _, m in msgs if c.topic == rb.DEPTH)
    assert np.array_equal(np.frombuffer(depth.data, "<u2").reshape(480, 640), frames[0][0])


def test_bad_options_are_refused(frames: Any, tmp_path: Path) -> None:
    for options, word in (
        ({"kind": "ros3"}, "ros3"),
        ({"kind": "ros1", "split_bytes": 10**6}, "split_bytes"),
        ({"kind": "ros2-mcap", "compression": "lz4"}, "lz4"),
        ({"cloud_hz": 60.0}, "cloud_hz"),
        ({"seconds": -1.0}, "-1.0"),
    ):
        with pytest.raises(InputError, match=word):
            _write(tmp_path / "x.bag", frames[:1], **options)
        assert not (tmp_path / "x.bag").exists()
    (tmp_path / "there.bag").write_bytes(b"")
    with pytest.raises(InputError, match="exists"):
        _write(tmp_path / "there.bag", frames[:1])
    # An iterator runs out and cannot be looped; the partial bag is removed.
    with pytest.raises(InputError, match="no frames"):
        _write(tmp_path / "y.bag", iter(frames[:1]), seconds=0.1)
    assert not (tmp_path / "y.bag").exists()
    small = [(d[:10], c) for d, c in frames[:1]]
    with pytest.raises(InputError, match="frame 0: depth"):
        _write(tmp_path / "z.bag", small)
