"""The messages of the bags :mod:`pcdcodec.bench.robot_bags` writes: their serialization (one
header per topic and frame, ROS 1 sequence numbers per topic), and the streams beside the camera
(IMU, odometry, tf, joint states, diagnostics) with values a robot's sensors give: a smooth
figure of eight driven in the odom frame, gravity in the accelerometer, noise from seeded
generators. Each stream yields ``(log_ns, topic, serialized message)`` in log-time order, its
header stamps a few milliseconds before the log time.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from ..geometry.camera import CameraIntrinsics
from ..geometry.transform import matrix_to_quaternion
from ..ros.bagwriter import MessageBuilder

__all__ = [
    "COLOR_FRAME",
    "DEPTH_FRAME",
    "IMU_FRAME",
    "OPTICAL",
    "BagMessages",
    "extra_streams",
    "static_tf",
]

_NS = 1_000_000_000
_G = 9.80665
COLOR_FRAME, DEPTH_FRAME = "camera_color_optical_frame", "camera_depth_optical_frame"
IMU_FRAME = "camera_imu_optical_frame"
#: The optical frame's axes (x right, y down, z forward) in its camera frame (x forward, z up).
OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_JOINTS = [f"panda_joint{i}" for i in range(1, 8)]


class BagMessages:
    """Serialized messages of one bag flavour, each header with its own frame and, in ROS 1,
    its topic's own sequence number."""

    def __init__(self, ros2: bool) -> None:
        self.builder = MessageBuilder(ros2, "")
        self.ros2 = ros2
        self.t = self.builder.types
        self.seq: dict[str, int] = defaultdict(int)

    def header(self, topic: str, frame_id: str, ns: int) -> Any:
        stamp = self.t["builtin_interfaces/msg/Time"](sec=ns // _NS, nanosec=ns % _NS)
        if self.ros2:
            return self.t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
        self.seq[topic] += 1
        return self.t["std_msgs/msg/Header"](
            seq=self.seq[topic] - 1, stamp=stamp, frame_id=frame_id
        )

    def vec(self, v: Any) -> Any:
        return self.t["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(self, q: Any) -> Any:
        x, y, z, w = (float(c) for c in q)
        return self.t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def image(self, topic: str, frame: str, ns: int, array: npt.NDArray[Any], enc: str) -> bytes:
        h, w = array.shape[:2]
        data = np.ascontiguousarray(array).reshape(-1).view(np.uint8)
        msg = self.t["sensor_msgs/msg/Image"](
            header=self.header(topic, frame, ns), height=h, width=w, encoding=enc,
            is_bigendian=0, step=data.size // h, data=data,
        )  # fmt: skip
        return self.builder.serialize(msg)

    def camera_info(self, topic: str, frame: str, ns: int, k: CameraIntrinsics) -> bytes:
        info = k.to_camera_info()
        arrays = {name: np.asarray(info[name], np.float64) for name in ("D", "K", "R", "P")}
        roi = self.t["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        msg = self.t["sensor_msgs/msg/CameraInfo"](
            header=self.header(topic, frame, ns), height=k.height, width=k.width,
            distortion_model=info["distortion_model"], binning_x=0, binning_y=0, roi=roi,
            **{(n.lower() if self.ros2 else n): a for n, a in arrays.items()},
        )  # fmt: skip
        return self.builder.serialize(msg)

    def cloud(self, topic: str, frame: str, ns: int, pts: npt.NDArray[Any]) -> bytes:
        field = self.t["sensor_msgs/msg/PointField"]
        fields = [
            field(name=n, offset=offset, datatype=7, count=1)
            for n, offset in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))
        ]
        h, w = pts.shape
        msg = self.t["sensor_msgs/msg/PointCloud2"](
            header=self.header(topic, frame, ns), height=h, width=w, fields=fields,
            is_bigendian=False, point_step=pts.dtype.itemsize,
            row_step=pts.dtype.itemsize * w, data=pts.reshape(-1).view(np.uint8),
            is_dense=False,
        )  # fmt: skip
        return self.builder.serialize(msg)

    def tf(self, topic: str, ns: int, edges: list[tuple[str, str, Any, Any]]) -> bytes:
        """A TFMessage of ``(parent, child, translation, quaternion xyzw)`` edges."""
        t = self.t
        msg = t["tf2_msgs/msg/TFMessage"](
            transforms=[
                t["geometry_msgs/msg/TransformStamped"](
                    header=self.header(topic, parent, ns),
                    child_frame_id=child,
                    transform=t["geometry_msgs/msg/Transform"](
                        translation=self.vec(xyz), rotation=self.quat(q)
                    ),
                )
                for parent, child, xyz, q in edges
            ]
        )
        return self.builder.serialize(msg)

    def serialize(self, msg: Any) -> bytes:
        return self.builder.serialize(msg)


class _Motion:
    """The robot's smooth figure of eight in the odom frame: position, heading, body-frame
    velocity and acceleration at time ``s`` (seconds), all analytic."""

    def __init__(self, phase: float = 0.0) -> None:
        self.phase = phase

    def at(self, s: float) -> dict[str, Any]:
        s += self.phase
        x, y = 1.5 * math.sin(0.2 * s), 0.75 * math.sin(0.4 * s)
        vx, vy = 0.3 * math.cos(0.2 * s), 0.3 * math.cos(0.4 * s)
        ax, ay = -0.06 * math.sin(0.2 * s), -0.12 * math.sin(0.4 * s)
        speed2 = vx * vx + vy * vy
        yaw = math.atan2(vy, vx)
        yaw_rate = (vx * ay - vy * ax) / speed2
        c, s_ = math.cos(yaw), math.sin(yaw)
        accel_body = (c * ax + s_ * ay, -s_ * ax + c * ay, 0.0)
        q = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        return {"xyz": (x, y, 0.0), "q": q, "speed": math.sqrt(speed2), "yaw_rate": yaw_rate,
                "accel": accel_body}  # fmt: skip


def _ticks(start: int, end: int, hz: float) -> Iterator[int]:
    period = _NS / hz
    i = 0
    while (ns := start + round(i * period)) < end:
        yield ns
        i += 1


def extra_streams(msgs: BagMessages, start: int, end: int, seed: int) -> list[Iterator[Any]]:
    """The streams besides the camera, each in log-time order: ``(log_ns, topic, data)``."""
    motion = _Motion()

    def imu() -> Iterator[Any]:
        rng = np.random.default_rng(seed + 1)
        cov = np.zeros(9)
        for ns in _ticks(start, end, 200.0):
            m = motion.at((ns - start) / _NS)
            f = m["accel"]  # specific force in the body frame (x forward, z up) ...
            body = np.array([f[0], f[1], f[2] + _G])
            accel = body @ OPTICAL + rng.normal(0, 0.02, 3)  # ... in the optical frame
            gyro = np.array([0.0, 0.0, m["yaw_rate"]]) @ OPTICAL + rng.normal(0, 0.002, 3)
            stamp = ns - 1_000_000 - int(rng.integers(0, 400_000))
            msg = msgs.t["sensor_msgs/msg/Imu"](
                header=msgs.header("/camera/imu", IMU_FRAME, stamp),
                orientation=msgs.quat((0, 0, 0, 0)),
                orientation_covariance=np.array([-1.0, *[0.0] * 8]),  # no orientation
                angular_velocity=msgs.vec(gyro),
                angular_velocity_covariance=cov + np.eye(3).reshape(-1) * 0.002**2,
                linear_acceleration=msgs.vec(accel),
                linear_acceleration_covariance=cov + np.eye(3).reshape(-1) * 0.02**2,
            )
            yield ns, "/camera/imu", msgs.serialize(msg)

    def tf() -> Iterator[Any]:
        for ns in _ticks(start, end, 100.0):
            m = motion.at((ns - start) / _NS)
            edge = ("odom", "base_link", m["xyz"], m["q"])
            yield ns, "/tf", msgs.tf("/tf", ns - 2_000_000, [edge])

    def odom() -> Iterator[Any]:
        rng = np.random.default_rng(seed + 2)
        t = msgs.t
        pose_cov = np.diag([1e-3, 1e-3, 1e6, 1e6, 1e6, 5e-3]).reshape(-1)
        twist_cov = np.diag([1e-4, 1e-4, 1e6, 1e6, 1e6, 1e-3]).reshape(-1)
        for ns in _ticks(start + 3_000_000, end, 50.0):
            m = motion.at((ns - start) / _NS)
            speed = m["speed"] + rng.normal(0, 0.003)
            msg = t["nav_msgs/msg/Odometry"](
                header=msgs.header("/odom", "odom", ns - 3_000_000),
                child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](
                    pose=t["geometry_msgs/msg/Pose"](
                        position=t["geometry_msgs/msg/Point"](x=m["xyz"][0], y=m["xyz"][1], z=0.0),
                        orientation=msgs.quat(m["q"]),
                    ),
                    covariance=pose_cov,
                ),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](
                    twist=t["geometry_msgs/msg/Twist"](
                        linear=msgs.vec((speed, 0.0, 0.0)),
                        angular=msgs.vec((0.0, 0.0, m["yaw_rate"] + rng.normal(0, 0.002))),
                    ),
                    covariance=twist_cov,
                ),
            )
            yield ns, "/odom", msgs.serialize(msg)

    def joints() -> Iterator[Any]:
        rng = np.random.default_rng(seed + 3)
        centre = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.8])
        amp = np.array([0.6, 0.3, 0.4, 0.35, 0.5, 0.3, 0.7])
        w = np.array([0.5, 0.7, 0.4, 0.6, 0.9, 0.8, 1.1])
        gravity = np.array([0.0, -25.0, 0.5, 12.0, 0.8, 1.5, 0.1])
        for ns in _ticks(start + 1_000_000, end, 100.0):
            s = (ns - start) / _NS
            msg = msgs.t["sensor_msgs/msg/JointState"](
                header=msgs.header("/joint_states", "", ns - 1_000_000),
                name=_JOINTS,
                position=centre + amp * np.sin(w * s) + rng.normal(0, 1e-5, 7),
                velocity=amp * w * np.cos(w * s) + rng.normal(0, 1e-3, 7),
                effort=gravity * np.cos(amp * np.sin(w * s)) + rng.normal(0, 0.05, 7),
            )
            yield ns, "/joint_states", msgs.serialize(msg)

    def diagnostics() -> Iterator[Any]:
        rng = np.random.default_rng(seed + 4)
        t = msgs.t
        for i, ns in enumerate(_ticks(start + 500_000_000, end, 1.0)):

            def kv(key: str, value: str) -> Any:
                return t["diagnostic_msgs/msg/KeyValue"](key=key, value=value)

            rate = 30.0 + rng.normal(0, 0.05)
            volts = 25.2 - 0.001 * i + rng.normal(0, 0.01)
            status = t["diagnostic_msgs/msg/DiagnosticStatus"]
            msg = t["diagnostic_msgs/msg/DiagnosticArray"](
                header=msgs.header("/diagnostics", "", ns - 2_000_000),
                status=[
                    status(level=0, name="realsense2_camera: /camera/color/image_raw topic status",
                           message="Desired frequency met", hardware_id="000000000001",
                           values=[kv("Events in window", str(round(rate * 5))),
                                   kv("Actual frequency (Hz)", f"{rate:.6f}"),
                                   kv("Target frequency (Hz)", "30.000000")]),
                    status(level=0, name="base: Battery", message="OK", hardware_id="battery0",
                           values=[kv("Voltage (V)", f"{volts:.3f}"),
                                   kv("Charge (%)", f"{95 - 0.01 * i:.1f}")]),
                ],
            )  # fmt: skip
            yield ns, "/diagnostics", msgs.serialize(msg)

    return [imu(), tf(), odom(), joints(), diagnostics()]


def static_tf(msgs: BagMessages, start: int) -> Iterator[Any]:
    optical = tuple(matrix_to_quaternion(OPTICAL.T))
    zero, same = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
    edges = [
        ("base_link", "camera_link", (0.25, 0.0, 0.45), same),
        ("camera_link", "camera_depth_frame", zero, same),
        ("camera_depth_frame", DEPTH_FRAME, zero, optical),
        ("camera_link", "camera_color_frame", zero, same),
        ("camera_color_frame", COLOR_FRAME, zero, optical),
        ("camera_link", "camera_gyro_frame", (-0.0117, -0.0055, 0.0052), same),
        ("camera_gyro_frame", IMU_FRAME, zero, optical),
    ]
    yield start, "/tf_static", msgs.tf("/tf_static", start - 50_000_000, edges)
