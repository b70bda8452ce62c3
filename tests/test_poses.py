"""Camera poses: rigid-transform checks, interpolation, folder poses, and poses in recordings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec import InputError
from pcdcodec.datasets import open_folder, sample_dir
from pcdcodec.geometry.transform import (
    as_rigid,
    interpolate_poses,
    matrix_to_quaternion,
    quaternion_to_matrix,
    rigid_from_quaternion,
)

from .conftest import SHARED_DATA


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    r = a[:3, :3].T @ b[:3, :3]
    return float(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def test_quaternion_round_trip_and_rigid_checks() -> None:
    rng = np.random.default_rng(4)
    for q in rng.normal(size=(50, 4)):
        r = quaternion_to_matrix(q)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(quaternion_to_matrix(matrix_to_quaternion(r)), r, atol=1e-12)
    with pytest.raises(InputError, match="pose must be a 4x4 rigid transform, got shape"):
        as_rigid(np.eye(3), "pose")
    scaled = np.diag([2.0, 2.0, 2.0, 1.0])
    with pytest.raises(InputError, match=r"pose is not a rigid transform.*det = 8"):
        as_rigid(scaled, "pose")
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(InputError, match="det = -1"):
        as_rigid(mirror, "pose")
    bottom = np.eye(4)
    bottom[3, 0] = 1.0
    with pytest.raises(InputError, match=r"last row of pose must be \[0, 0, 0, 1\]"):
        as_rigid(bottom, "pose")
    with pytest.raises(InputError, match="must be finite"):
        as_rigid(np.full((4, 4), np.nan), "pose")


def test_interpolation_is_linear_in_translation_and_geodesic_in_rotation() -> None:
    a = rigid_from_quaternion([0, 0, 0], [0, 0, 0, 1])
    b = rigid_from_quaternion([1.0, 2.0, -3.0], [0, np.sin(0.4), 0, np.cos(0.4)])  # 0.8 rad
    mid, quarter, outside, exact = interpolate_poses([0, 100], [a, b], [50, 25, 101, 100])
    assert mid is not None
    assert quarter is not None
    np.testing.assert_allclose(mid[:3, 3], [0.5, 1.0, -1.5])
    np.testing.assert_allclose(quarter[:3, 3], [0.25, 0.5, -0.75])
    assert _angle(a, mid) == pytest.approx(0.4)
    assert _angle(a, quarter) == pytest.approx(0.2)
    assert outside is None
    assert exact is not None
    np.testing.assert_array_equal(exact, b)
    assert interpolate_poses([0, 100], [a, b], [50], max_gap=99) == [None]


def test_tum_sample_poses_are_interpolated_at_the_depth_stamps() -> None:
    source = open_folder(sample_dir())
    assert source.poses is not None
    assert all(p is not None for p in source.poses)
    # Frame 0: depth 1305031229.528784 lies between these two groundtruth lines.
    rows = {}
    for line in (sample_dir() / "groundtruth.txt").read_text().splitlines():
        if line.startswith(("1305031229.5232", "1305031229.5332")):
            rows[line.split()[0]] = [float(v) for v in line.split()[1:]]
    (t0, r0), (t1, r1) = sorted((float(k), v) for k, v in rows.items())
    a = (1305031229.528784 - t0) / (t1 - t0)
    expected = (1 - a) * np.array(r0[:3]) + a * np.array(r1[:3])
    pose = source.poses[0]
    assert pose is not None
    np.testing.assert_allclose(pose[:3, 3], expected, atol=1e-9)
    p0, p1 = rigid_from_quaternion(r0[:3], r0[3:]), rigid_from_quaternion(r1[:3], r1[3:])
    assert _angle(p0, pose) == pytest.approx(a * _angle(p0, p1), abs=1e-7)
    frames = list(source)
    assert frames[0].pose is not None
    np.testing.assert_array_equal(frames[0].pose, pose)


@pytest.mark.skipif(
    not (SHARED_DATA / "7scenes_redkitchen" / "pose").is_dir(), reason="7-Scenes is not present"
)
def test_7scenes_poses() -> None:
    root = SHARED_DATA / "7scenes_redkitchen"
    source = open_folder(root, max_frames=3, depth_scale=1000.0)  # millimetres, per its README
    assert source.poses is not None
    for (_, _, depth), pose in zip(source.pairs, source.poses, strict=True):
        name = depth.name.split(".")[0]
        assert pose is not None
        np.testing.assert_array_equal(pose, np.loadtxt(root / "pose" / f"{name}.pose.txt"))


def test_recording_stores_poses_as_frame_transforms(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    source = open_folder(sample_dir(), max_frames=4)
    path = tmp_path / "poses.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=source.intrinsics, depth_scale=source.depth_scale, color="ffv1"
    ) as rec:
        rec.write_frames(source)
        depth = np.zeros((480, 640), np.uint16)
        scaled = np.diag([2.0, 2.0, 2.0, 1.0])
        with pytest.raises(InputError, match="pose is not a rigid transform"):
            rec.write(np.zeros((480, 640, 3), np.uint8), depth, 10**18, pose=scaled)
    assert source.poses is not None
    with pcdcodec.open(path) as rec:
        assert rec.format_version == 1  # poses need no new version: old readers skip them
        assert rec.has_poses
        for frame, want in zip(rec, source.poses, strict=True):
            assert frame.pose is not None
            assert want is not None
            np.testing.assert_allclose(frame.pose, want, atol=1e-12)
    # Any MCAP + ROS 2 tool reads them: decode with rosbags from the schema in the file.
    store = get_typestore(Stores.ROS2_HUMBLE)
    with path.open("rb") as f:
        reader = make_reader(f)
        messages = list(reader.iter_messages(topics=["/camera/pose"]))
        schema = messages[0][0]
        assert schema is not None
        assert schema.name == "foxglove_msgs/msg/FrameTransform"
        main = schema.data.decode().split("=" * 80)[0]
        store.register(get_types_from_msg(main, "foxglove_msgs/msg/FrameTransform"))
        first = store.deserialize_cdr(messages[0][2].data, "foxglove_msgs/msg/FrameTransform")
    assert len(messages) == 4
    assert first.parent_frame_id == "world"
    assert first.child_frame_id == "camera"
    pose0 = source.poses[0]
    assert pose0 is not None
    t = first.translation
    np.testing.assert_allclose([t.x, t.y, t.z], pose0[:3, 3])
    q = first.rotation
    np.testing.assert_allclose(
        quaternion_to_matrix([q.x, q.y, q.z, q.w]), pose0[:3, :3], atol=1e-12
    )


@pytest.mark.parametrize("to", ["rosbag1", "rosbag2"])
def test_bag_export_writes_poses_to_tf(tmp_path: Path, to: str) -> None:
    from rosbags.highlevel import AnyReader

    source = open_folder(sample_dir(), max_frames=3)
    rec = tmp_path / "p.pcdc"
    with pcdcodec.open(
        rec, "w", intrinsics=source.intrinsics, depth_scale=source.depth_scale, color="ffv1"
    ) as w:
        w.write_frames(source)
    out = tmp_path / ("p.bag" if to == "rosbag1" else "p")
    summary = pcdcodec.export_bag(rec, out, to=to)
    assert "/tf" in summary["topics"]
    assert source.poses is not None
    with AnyReader([out]) as reader:
        conns = [c for c in reader.connections if c.topic == "/tf"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    assert len(msgs) == 3
    for msg, pose in zip(msgs, source.poses, strict=True):
        (tf,) = msg.transforms
        assert pose is not None
        assert tf.header.frame_id == "world"
        t, q = tf.transform.translation, tf.transform.rotation
        np.testing.assert_allclose([t.x, t.y, t.z], pose[:3, 3])
        np.testing.assert_allclose(
            quaternion_to_matrix([q.x, q.y, q.z, q.w]), pose[:3, :3], atol=1e-12
        )


# -- poses from a bag's /tf and /tf_static ------------------------------------------------------


@pytest.mark.parametrize(("to", "storage"), [("rosbag1", "mcap"), ("rosbag2", "mcap"),
                                             ("rosbag2", "sqlite3")])  # fmt: skip
def test_bag_round_trip_keeps_poses(tmp_path: Path, to: str, storage: str) -> None:
    source = open_folder(sample_dir(), max_frames=4)
    rec = tmp_path / "p.pcdc"
    with pcdcodec.open(
        rec, "w", intrinsics=source.intrinsics, depth_scale=source.depth_scale, color="ffv1"
    ) as w:
        w.write_frames(source)
    bag = tmp_path / ("p.bag" if to == "rosbag1" else "p")
    pcdcodec.export_bag(rec, bag, to=to, storage=storage)
    back = tmp_path / "back.pcdc"
    summary = pcdcodec.encode(bag, back, color="ffv1")
    assert any("poses from tf" in note for note in summary.source["notes"])
    assert source.poses is not None
    with pcdcodec.open(back) as got:
        assert got.has_poses
        frames = list(got)
    assert len(frames) == 4
    for frame, want in zip(frames, source.poses, strict=True):
        assert frame.pose is not None
        assert want is not None
        # The bag holds the rotation as a float64 quaternion: equal to its precision.
        np.testing.assert_allclose(frame.pose, want, rtol=0, atol=1e-12)
    # Frames read from the middle of the bag (through its index) carry the same poses.
    with pcdcodec.open_source(bag) as src:
        later = list(src.frames(2))
    assert [f.timestamp_ns for f in later] == [f.timestamp_ns for f in frames[2:]]
    for f, g in zip(later, frames[2:], strict=True):
        assert f.pose is not None
        assert g.pose is not None
        np.testing.assert_allclose(f.pose, g.pose, rtol=0, atol=1e-12)


def _tf_bag(
    path: Path,
    frames: list[int],
    tf: list[tuple[str, int, str, str, np.ndarray]],
    *,
    ros2: bool,
    camera: str = "cam",
    damaged: frozenset[int] = frozenset(),
) -> Path:
    """A bag of small depth images at ``frames`` (ns) in frame ``camera``, and transforms
    ``(topic, stamp, parent, child, 4x4 pose of child in parent)``."""
    from rosbags.typesys import get_types_from_msg

    from .test_rosbag import _header, _image, _store, write_bag

    store = _store(ros2)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        store.register(
            get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
            )
        )
    t = store.types
    messages: list[tuple[str, int, object]] = []
    depth = np.full((6, 8), 1000, np.uint16)
    for ns in frames:
        image = _image(store, ros2, ns, depth, "16UC1")
        image.header.frame_id = camera
        messages.append(("/cam/depth", ns, image))
    for k, (topic, ns, parent, child, pose) in enumerate(tf):
        q = matrix_to_quaternion(pose[:3, :3])
        stamped = t["geometry_msgs/msg/TransformStamped"](
            header=_header(store, ros2, ns, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](*map(float, pose[:3, 3])),
                rotation=t["geometry_msgs/msg/Quaternion"](*map(float, q)),
            ),
        )
        if k in damaged:  # nanoseconds past a second: a damaged stamp
            stamped.header.stamp.nanosec = 1_500_000_000
        messages.append((topic, ns, t["tf2_msgs/msg/TFMessage"](transforms=[stamped])))
    messages.sort(key=lambda m: m[1])
    return write_bag(path, messages, ros2=ros2, store=store)


def _rz(angle: float, t: tuple[float, float, float]) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = t
    return m


@pytest.mark.parametrize("ros2", [False, True])
def test_tf_chain_is_composed_and_interpolated_at_frame_stamps(tmp_path: Path, ros2: bool) -> None:
    from pcdcodec.geometry.transform import slerp

    ms = 1_000_000
    base_in_odom = [_rz(0.1 * k, (k * 0.5, 0.0, 0.0)) for k in range(3)]
    odom_in_map = _rz(0.3, (1.0, 2.0, 0.0))
    cam_on_base = _rz(-0.2, (0.1, 0.0, 0.4))
    tf = [
        ("/tf_static", 1, "map", "odom", odom_in_map),
        ("/tf_static", 1, "/base", "/cam", cam_on_base),  # tf1's leading slashes
        *[("/tf", 100 * ms * k + 50 * ms, "odom", "base", p) for k, p in enumerate(base_in_odom)],
        ("/tf", 10 * ms, "elsewhere", "other", np.eye(4)),  # another tree: ignored
    ]
    # Frames: on a sample, between two (interpolated), before the first and after the last.
    frames = [150 * ms, 200 * ms, 20 * ms, 400 * ms]
    bag = _tf_bag(tmp_path / ("t" if ros2 else "t.bag"), sorted(frames), tf, ros2=ros2)
    with pcdcodec.open_source(bag, intrinsics=pcdcodec.CameraIntrinsics(8, 6, 5, 5, 4, 3)) as src:
        got = {f.timestamp_ns: f.pose for f in src}
        notes = src.describe()["notes"]
    assert got[20 * ms] is None
    assert got[400 * ms] is None
    assert any("'cam' in 'map' (map -> odom -> base -> cam)" in n for n in notes)
    want = odom_in_map @ base_in_odom[1] @ cam_on_base
    np.testing.assert_allclose(got[150 * ms], want, rtol=0, atol=1e-12)
    q = slerp(
        matrix_to_quaternion(base_in_odom[1][:3, :3]),
        matrix_to_quaternion(base_in_odom[2][:3, :3]),
        0.5,
    )
    half = rigid_from_quaternion((base_in_odom[1][:3, 3] + base_in_odom[2][:3, 3]) / 2, q)
    np.testing.assert_allclose(got[200 * ms], odom_in_map @ half @ cam_on_base, atol=1e-12)


def test_tf_that_does_not_place_the_camera_gives_no_poses_and_says_why(tmp_path: Path) -> None:
    ms = 1_000_000
    camera = pcdcodec.CameraIntrinsics(8, 6, 5, 5, 4, 3)
    cases = {
        "several parents (a, b)": [
            ("/tf", 10 * ms, "a", "cam", np.eye(4)),
            ("/tf", 10 * ms, "b", "cam", np.eye(4)),
        ],
        "static transforms only": [("/tf_static", 1, "base", "cam", np.eye(4))],
        "no transform to the camera frame 'cam'": [("/tf", 10 * ms, "map", "x", np.eye(4))],
        "gap": [
            ("/tf", 0, "map", "cam", np.eye(4)),
            ("/tf", 600 * ms, "map", "cam", np.eye(4)),  # more than 0.5 s apart
        ],
    }
    for k, (why, tf) in enumerate(cases.items()):
        bag = _tf_bag(tmp_path / f"{k}.bag", [10 * ms, 300 * ms], tf, ros2=False)
        with pcdcodec.open_source(bag, intrinsics=camera) as src:
            poses = [f.pose for f in src]
            notes = src.describe()["notes"]
        assert poses == [None, None], why
        if why != "gap":
            assert any(why in n for n in notes), (why, notes)


@pytest.mark.parametrize("ros2", [False, True])
def test_tf_samples_with_damaged_stamps_are_ignored_and_counted(tmp_path: Path, ros2: bool) -> None:
    ms = 1_000_000
    poses = [_rz(0.1 * k, (k * 0.5, 0.0, 0.0)) for k in range(3)]
    tf = [("/tf", 100 * ms * k, "map", "cam", p) for k, p in enumerate(poses)]
    bag = _tf_bag(
        tmp_path / ("d" if ros2 else "d.bag"), [100 * ms], tf, ros2=ros2, damaged=frozenset({0})
    )
    with pcdcodec.open_source(bag, intrinsics=pcdcodec.CameraIntrinsics(8, 6, 5, 5, 4, 3)) as src:
        (frame,) = list(src)
        notes = src.describe()["notes"]
    assert frame.pose is not None
    np.testing.assert_allclose(frame.pose, poses[1], rtol=0, atol=1e-12)
    assert any("1 transforms from 'map' to 'cam'" in n and "damaged stamp" in n for n in notes)
