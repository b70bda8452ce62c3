"""Bags whose color camera is apart from the depth camera, as realsense-ros publishes by default
(``depth/image_rect_raw`` and ``color/image_raw``, each with its CameraInfo, placed by
``/tf_static``): built from real D435 frames under realsense-ros topic names, ROS 1 and ROS 2."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.errors import InputError
from pcdcodec.geometry.camera import CameraIntrinsics
from pcdcodec.geometry.transform import rigid_from_quaternion

from .conftest import SHARED_DATA, load_colors, load_depths

D435 = SHARED_DATA / "realsense_d435_office"
RS_MCAP = SHARED_DATA / "bags" / "ros2-converted" / "rs_ros2_mcap"
needs_d435 = pytest.mark.skipif(not D435.is_dir(), reason=f"{D435} is not present")

NS = 1_000_000_000
DEPTH = "/camera/depth/image_rect_raw"
COLOR = "/camera/color/image_raw"
ALIGNED = "/camera/aligned_depth_to_color/image_raw"
DEPTH_FRAME = "camera_depth_optical_frame"
COLOR_FRAME = "camera_color_optical_frame"
# A D435's two cameras at 640x480 (the real bag's values, rounded).
DEPTH_CAM = CameraIntrinsics(640, 480, 390.43, 390.43, 331.39, 242.19)
COLOR_CAM = CameraIntrinsics(640, 480, 613.20, 613.42, 319.94, 239.18)
# camera_link -> optical frames: the optical rotation, and the color camera 15 mm to the side
# and turned by a degree, as realsense-ros publishes them on /tf_static.
OPTICAL = (-0.5, 0.5, -0.5, 0.5)
LINK_DEPTH = rigid_from_quaternion([0.0, 0.0, 0.0], OPTICAL)
LINK_COLOR = rigid_from_quaternion([0.0, 0.015, 0.0003], OPTICAL) @ rigid_from_quaternion(
    [0.0, 0.0, 0.0], [0.0, np.sin(np.radians(0.5)), 0.0, np.cos(np.radians(0.5))]
)
WANT_D2C = np.linalg.inv(LINK_COLOR) @ LINK_DEPTH


def _frames(n: int = 3) -> list[tuple[Any, Any]]:
    return list(
        zip(load_colors("realsense_d435", n), load_depths("realsense_d435", n), strict=True)
    )


def realsense_ros_bag(
    path: Path,
    *,
    ros2: bool,
    tf: bool = True,
    aligned: bool = False,
    n: int = 3,
    depth_cam: CameraIntrinsics = DEPTH_CAM,
) -> Path:
    """A bag as realsense-ros records one: depth and color images of real D435 frames, their
    CameraInfo, color 5 ms after depth, ``/tf_static`` placing both optical frames under
    ``camera_link`` (with ``tf``), and ``aligned_depth_to_color`` images (with ``aligned``)."""
    from pcdcodec.ros.bagwriter import BagWriter, MessageBuilder

    msgs = MessageBuilder(ros2, DEPTH_FRAME)
    writer = BagWriter(path, "rosbag2" if ros2 else "rosbag1", "mcap", msgs)
    image, info = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo"
    topics = [(DEPTH, image), (COLOR, image), ("/camera/depth/camera_info", info)]
    topics += [("/camera/color/camera_info", info)]
    if aligned:
        topics += [(ALIGNED, image), ("/camera/aligned_depth_to_color/camera_info", info)]
    for topic, msgtype in topics:
        writer.add(topic, msgtype)
    if tf:
        writer.add("/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
        edges = [("camera_link", DEPTH_FRAME, LINK_DEPTH), ("camera_link", COLOR_FRAME, LINK_COLOR)]
        writer.write("/tf_static", NS, msgs.transforms(NS, edges))
    for k, (color, depth) in enumerate(_frames(n)):
        ts = NS + k * 33_333_333
        msgs.frame_id = DEPTH_FRAME
        h, w = depth_cam.shape
        writer.write(DEPTH, ts, msgs.image(ts, np.ascontiguousarray(depth[:h, :w]), "16UC1"))
        writer.write(
            "/camera/depth/camera_info", ts, msgs.camera_info(ts, depth_cam, "plumb_bob", [0.0] * 5)
        )
        msgs.frame_id = COLOR_FRAME
        if aligned:
            writer.write(ALIGNED, ts, msgs.image(ts, depth, "16UC1"))
            writer.write(
                "/camera/aligned_depth_to_color/camera_info",
                ts,
                msgs.camera_info(ts, COLOR_CAM, "plumb_bob", [0.0] * 5),
            )
        cts = ts + 5_000_000
        writer.write(COLOR, cts, msgs.image(cts, color, "rgb8"))
        writer.write(
            "/camera/color/camera_info",
            cts,
            msgs.camera_info(cts, COLOR_CAM, "plumb_bob", [0.0] * 5),
        )
    writer.close()
    return path


def _bag_name(ros2: bool) -> str:
    return "rs_ros2" if ros2 else "rs.bag"


@needs_d435
@pytest.mark.parametrize("ros2", [False, True])
def test_the_color_camera_apart_is_recorded_with_the_bags_tf(tmp_path: Path, ros2: bool) -> None:
    bag = realsense_ros_bag(tmp_path / _bag_name(ros2), ros2=ros2)
    with pcdcodec.open_source(bag) as src:
        assert (src.depth_topic, src.color_topic) == (DEPTH, COLOR)
        assert src.intrinsics is not None
        assert src.intrinsics.pinhole() == DEPTH_CAM
    out = tmp_path / "rs.pcdc"
    summary = pcdcodec.encode(bag, out, color="ffv1")
    assert summary.frames == 3
    assert summary.dropped == {"color": 0, "depth": 0}
    notes = " ".join(summary.source["notes"])
    assert "camera apart from the depth" in notes
    assert f"from /tf_static ({DEPTH_FRAME} -> camera_link -> {COLOR_FRAME})" in notes
    # Both CameraInfo topics and the /tf_static that placed the cameras are recorded.
    left_out = {item["name"] for item in summary.left_out}
    assert not {"/tf_static", COLOR.rsplit("/", 1)[0] + "/camera_info"} & left_out, left_out
    frames = _frames()
    with pcdcodec.open(out) as rec:
        assert rec.intrinsics == DEPTH_CAM
        assert rec.color_intrinsics == COLOR_CAM
        assert rec.depth_to_color is not None
        np.testing.assert_allclose(rec.depth_to_color, WANT_D2C, atol=1e-9)
        # The cloud takes its colours through the color camera and the bag's extrinsics.
        got_points, got_colors = rec[1].to_points()
        proj = pcdcodec.Projector(
            DEPTH_CAM, 1000.0, color_intrinsics=COLOR_CAM, depth_to_color=WANT_D2C
        )
        want_points, want_colors = proj.to_points(frames[1][1], frames[1][0])
        registered = pcdcodec.Projector(DEPTH_CAM, 1000.0).to_points(frames[1][1], frames[1][0])
    np.testing.assert_array_equal(got_points, want_points)
    assert got_colors is not None
    assert want_colors is not None
    np.testing.assert_array_equal(got_colors, want_colors)  # ffv1: lossless colour
    assert registered[1] is not None
    assert float(np.mean(got_colors != registered[1])) > 0.3  # not the registered colours


@needs_d435
def test_a_color_camera_apart_of_another_size_is_chosen_and_recorded(tmp_path: Path) -> None:
    """realsense-ros records depth and color at their own sizes: a color topic of another size
    with a CameraInfo of its own is the color camera apart, not a reason for depth only."""
    small = CameraIntrinsics(560, 420, 390.43, 390.43, 291.39, 212.19)
    bag = realsense_ros_bag(tmp_path / "rs.bag", ros2=False, depth_cam=small, n=2)
    out = tmp_path / "rs.pcdc"
    summary = pcdcodec.encode(bag, out, color="ffv1")
    assert summary.source["color_topic"] == COLOR
    assert summary.frames == 2
    color, depth = _frames(1)[0]
    with pcdcodec.open(out) as rec:
        assert rec.intrinsics == small
        assert rec.color_intrinsics == COLOR_CAM
        frame = rec[0]
        assert frame.color.shape == (480, 640, 3)
        np.testing.assert_array_equal(frame.depth, depth[:420, :560])
        got = frame.to_points()
    proj = pcdcodec.Projector(small, 1000.0, color_intrinsics=COLOR_CAM, depth_to_color=WANT_D2C)
    want = proj.to_points(depth[:420, :560], color)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


@needs_d435
@pytest.mark.parametrize("ros2", [False, True])
def test_without_tf_the_bag_is_refused_until_depth_to_color_is_given(
    tmp_path: Path, ros2: bool
) -> None:
    bag = realsense_ros_bag(tmp_path / _bag_name(ros2), ros2=ros2, tf=False)
    out = tmp_path / "rs.pcdc"
    with pytest.raises(InputError, match=r"camera apart from the depth.*no /tf or /tf_static.*"
                       r"pass depth_to_color=") as info:  # fmt: skip
        pcdcodec.encode(bag, out, color="ffv1")
    assert str(bag) in str(info.value)
    assert not out.exists()
    # The command line says which flag gives it.
    from pcdcodec.cli import main

    assert main(["encode", str(bag), "-o", str(out), "--color", "ffv1"]) == 1
    assert not out.exists()
    # `info` still describes the bag, and says what is missing.
    with pcdcodec.open_source(bag) as src:
        assert any("depth_to_color is not in the bag" in n for n in src.describe()["notes"])
    d2c = tmp_path / "d2c.txt"
    np.savetxt(d2c, WANT_D2C)
    assert (
        main(["encode", str(bag), "-o", str(out), "--color", "ffv1", "--depth-to-color", str(d2c)])
        == 0
    )
    with pcdcodec.open(out) as rec:
        assert rec.color_intrinsics == COLOR_CAM
        np.testing.assert_allclose(rec.depth_to_color, WANT_D2C, atol=1e-12)


@needs_d435
def test_cli_error_names_the_depth_to_color_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    bag = realsense_ros_bag(tmp_path / "rs.bag", ros2=False, tf=False, n=1)
    assert main(["encode", str(bag), "-o", str(tmp_path / "x.pcdc")]) == 1
    err = capsys.readouterr().err
    assert "pass --depth-to-color FILE" in err
    assert "--color-topic ''" in err


@needs_d435
@pytest.mark.parametrize("ros2", [False, True])
def test_aligned_depth_is_chosen_and_the_choice_is_said(tmp_path: Path, ros2: bool) -> None:
    bag = realsense_ros_bag(tmp_path / _bag_name(ros2), ros2=ros2, aligned=True, n=2)
    summary = pcdcodec.encode(bag, tmp_path / "a.pcdc", color="ffv1")
    assert summary.source["depth_topic"] == ALIGNED
    notes = " ".join(summary.source["notes"])
    assert (
        f"depth topic {ALIGNED!r} is registered to the color camera, chosen over {DEPTH!r}" in notes
    )
    with pcdcodec.open(tmp_path / "a.pcdc") as rec:
        assert rec.intrinsics == COLOR_CAM  # the aligned depth's camera is the color camera's
        assert rec.color_intrinsics is None
    # The depth camera's own images, when asked for: the color camera apart, placed by tf.
    summary = pcdcodec.encode(bag, tmp_path / "d.pcdc", color="ffv1", depth_topic=DEPTH)
    notes = " ".join(summary.source["notes"])
    assert f"depth topic {DEPTH!r} is the depth camera's own images" in notes
    with pcdcodec.open(tmp_path / "d.pcdc") as rec:
        assert rec.intrinsics == DEPTH_CAM
        assert rec.color_intrinsics == COLOR_CAM
        np.testing.assert_allclose(rec.depth_to_color, WANT_D2C, atol=1e-9)


@pytest.mark.skipif(not RS_MCAP.is_dir(), reason=f"{RS_MCAP} is not present")
def test_the_real_ros2_realsense_bag_is_not_recorded_as_registered(tmp_path: Path) -> None:
    """The real D435 frames in a ROS 2 bag: the color topic's CameraInfo (fx 613.2) is not the
    depth's (fx 390.4), and the bag has no tf: refused, then recorded with the transform given."""
    out = tmp_path / "x.pcdc"
    with pytest.raises(InputError, match=r"fx=613\.204.*fx=390\.431.*no /tf or /tf_static"):
        pcdcodec.encode(RS_MCAP, out, max_difference=150_000_000)
    d2c = np.eye(4)
    d2c[0, 3] = 0.0143
    summary = pcdcodec.encode(
        RS_MCAP, out, max_difference=150_000_000, depth_to_color=d2c, color="ffv1"
    )
    assert summary.frames == 1
    assert summary.dropped == {"color": 0, "depth": 1}
    with pcdcodec.open(out) as rec:
        assert rec.intrinsics.fx == pytest.approx(390.43145752)
        assert rec.color_intrinsics is not None
        assert rec.color_intrinsics.fx == pytest.approx(613.20367432)
        assert rec.color_intrinsics.cx == pytest.approx(319.9388427734375)
        np.testing.assert_allclose(rec.depth_to_color, d2c)


# -- the transform between two frames of a tf tree ----------------------------------------------


def _tf(parent: str, child: str, pose: Any) -> Any:
    from types import SimpleNamespace

    from pcdcodec.geometry.transform import matrix_to_quaternion

    q = matrix_to_quaternion(pose[:3, :3])
    t = pose[:3, 3]
    return SimpleNamespace(
        header=SimpleNamespace(frame_id=parent, stamp=SimpleNamespace(sec=1, nanosec=0)),
        child_frame_id=child,
        transform=SimpleNamespace(
            translation=SimpleNamespace(x=t[0], y=t[1], z=t[2]),
            rotation=SimpleNamespace(x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def _between(messages: list[tuple[str, list[Any]]], a: str, b: str) -> tuple[Any, str]:
    from types import SimpleNamespace

    from pcdcodec.ros.tf import frame_to_frame

    conns = {t: SimpleNamespace(topic=t, msgtype="tf2_msgs/msg/TFMessage") for t, _ in messages}

    def read(wanted: list[Any]) -> Any:
        for topic, transforms in messages:
            if conns[topic] in wanted:
                yield conns[topic], 0, SimpleNamespace(transforms=transforms)

    return frame_to_frame(read, list(conns.values()), a, b)


def test_frame_to_frame_follows_both_chains_to_their_common_frame() -> None:
    base_link = rigid_from_quaternion([1.0, 2.0, 0.5], [0.0, 0.0, 0.38268343, 0.92387953])
    static = [
        _tf("camera_link", DEPTH_FRAME, LINK_DEPTH),
        _tf("camera_link", COLOR_FRAME, LINK_COLOR),
    ]
    d2c, where = _between([("/tf_static", static)], DEPTH_FRAME, COLOR_FRAME)
    np.testing.assert_allclose(d2c, WANT_D2C, atol=1e-12)
    assert where == f"from /tf_static ({DEPTH_FRAME} -> camera_link -> {COLOR_FRAME})"
    # The camera moving in the world (odom -> camera_link on /tf) does not matter; the mounting
    # published on /tf with constant values counts.
    moving = [
        ("/tf", [_tf("odom", "camera_link", base_link)]),
        ("/tf", [_tf("odom", "camera_link", np.eye(4))]),
        ("/tf", [_tf("camera_link", COLOR_FRAME, LINK_COLOR)]),
        ("/tf", [_tf("camera_link", COLOR_FRAME, LINK_COLOR)]),
        ("/tf_static", [_tf("camera_link", DEPTH_FRAME, LINK_DEPTH)]),
    ]
    d2c, where = _between(moving, DEPTH_FRAME, COLOR_FRAME)
    np.testing.assert_allclose(d2c, WANT_D2C, atol=1e-12)
    assert where.startswith("from /tf (")
    # A color camera moving relative to the depth camera has no fixed extrinsics.
    shifted = LINK_COLOR.copy()
    shifted[0, 3] += 0.01
    changing = [*moving[:3], ("/tf", [_tf("camera_link", COLOR_FRAME, shifted)]), moving[4]]
    d2c, where = _between(changing, DEPTH_FRAME, COLOR_FRAME)
    assert d2c is None
    assert f"tf moves {COLOR_FRAME!r} in 'camera_link' over time" == where
    # Two trees, two parents, one frame for both: no transform, and why.
    two_trees = [("/tf_static", [static[0], _tf("other_link", COLOR_FRAME, LINK_COLOR)])]
    assert "their trees have the roots" in _between(two_trees, DEPTH_FRAME, COLOR_FRAME)[1]
    two_parents = [("/tf_static", [*static, _tf("other_link", COLOR_FRAME, LINK_COLOR)])]
    assert "several parents" in _between(two_parents, DEPTH_FRAME, COLOR_FRAME)[1]
    assert "both images name the frame" in _between([("/tf_static", static)], "x", "x")[1]
    assert _between([], DEPTH_FRAME, COLOR_FRAME) == (None, "the bag has no /tf or /tf_static")
