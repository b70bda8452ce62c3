"""Writing ROS 1 and ROS 2 bags: the messages of one bag flavour built from arrays (images,
compressed images, camera info, tf, organized clouds) and serialized, and the rosbags writers
behind one add/write/close.

Connection headers, message definitions and MD5 sums (ROS 1) or type hashes (ROS 2) come from
the rosbags typestores of ROS 1 Noetic and ROS 2 Humble.
"""

from __future__ import annotations

import heapq
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..geometry.transform import matrix_to_quaternion

__all__ = ["BagWriter", "InTimeOrder", "MessageBuilder", "offered_qos"]

_NS = 1_000_000_000


class MessageBuilder:
    """Builds the messages of one bag flavour (ROS 1 or ROS 2 field names, serializer)."""

    def __init__(self, ros2: bool, frame_id: str) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ros2 = ros2
        self.store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
        if "tf2_msgs/msg/TFMessage" not in self.store.types:
            from rosbags.typesys import get_types_from_msg

            # Noetic's store lacks tf2_msgs; its definition is this one line.
            self.store.register(
                get_types_from_msg(
                    "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
                )
            )
        self.types = self.store.types
        self.frame_id = frame_id
        self.seq = 0

    def serialize(self, msg: Any) -> bytes:
        typename = msg.__msgtype__
        if self.ros2:
            return bytes(self.store.serialize_cdr(msg, typename))
        return bytes(self.store.serialize_ros1(msg, typename))

    def header(self, ns: int) -> Any:
        stamp = self.types["builtin_interfaces/msg/Time"](sec=ns // _NS, nanosec=ns % _NS)
        if self.ros2:
            return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=self.frame_id)
        self.seq += 1
        return self.types["std_msgs/msg/Header"](
            seq=self.seq - 1, stamp=stamp, frame_id=self.frame_id
        )

    def image(self, ns: int, array: npt.NDArray[Any], encoding: str) -> bytes:
        h, w = array.shape[:2]
        data = np.ascontiguousarray(array)
        step = data.nbytes // h
        msg = self.types["sensor_msgs/msg/Image"](
            header=self.header(ns),
            height=h,
            width=w,
            encoding=encoding,
            is_bigendian=0,
            step=step,
            data=data.reshape(-1).view(np.uint8),
        )
        return self.serialize(msg)

    def compressed(self, ns: int, data: bytes, fmt: str) -> bytes:
        msg = self.types["sensor_msgs/msg/CompressedImage"](
            header=self.header(ns), format=fmt, data=np.frombuffer(data, np.uint8)
        )
        return self.serialize(msg)

    def camera_info(self, ns: int, intrinsics: Any, model: str, dist: list[float]) -> bytes:
        info = intrinsics.to_camera_info()
        roi = self.types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        arrays = {
            "d": np.asarray(dist, np.float64),
            "k": np.asarray(info["K"], np.float64),
            "r": np.asarray(info["R"], np.float64),
            "p": np.asarray(info["P"], np.float64),
        }
        if not self.ros2:
            arrays = {k.upper(): v for k, v in arrays.items()}
        msg = self.types["sensor_msgs/msg/CameraInfo"](
            header=self.header(ns),
            height=intrinsics.height,
            width=intrinsics.width,
            distortion_model=model,
            binning_x=0,
            binning_y=0,
            roi=roi,
            **arrays,
        )
        return self.serialize(msg)

    def tf(self, ns: int, pose: npt.NDArray[np.float64], parent: str) -> bytes:
        """A ``tf2_msgs/TFMessage`` placing this camera frame in ``parent`` (camera-to-world)."""
        return self.transforms(ns, [(parent, self.frame_id, pose)])

    def transforms(self, ns: int, edges: list[tuple[str, str, npt.NDArray[np.float64]]]) -> bytes:
        """A ``tf2_msgs/TFMessage`` of ``(parent, child, pose)`` edges, each ``pose`` the rigid
        4 × 4 transform taking the child frame's points into the parent frame."""
        t = self.types
        stamped = []
        for parent, child, pose in edges:
            q = matrix_to_quaternion(pose[:3, :3])
            header = self.header(ns)
            header.frame_id = parent
            stamped.append(
                t["geometry_msgs/msg/TransformStamped"](
                    header=header,
                    child_frame_id=child,
                    transform=t["geometry_msgs/msg/Transform"](
                        translation=t["geometry_msgs/msg/Vector3"](
                            x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3])
                        ),
                        rotation=t["geometry_msgs/msg/Quaternion"](
                            x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
                        ),
                    ),
                )
            )
        return self.serialize(t["tf2_msgs/msg/TFMessage"](transforms=stamped))

    def cloud(self, ns: int, pts: npt.NDArray[Any]) -> bytes:
        field = self.types["sensor_msgs/msg/PointField"]
        h, w = pts.shape
        fields = [
            field(name=n, offset=o, datatype=7, count=1)
            for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))
        ]
        msg = self.types["sensor_msgs/msg/PointCloud2"](
            header=self.header(ns),
            height=h,
            width=w,
            fields=fields,
            is_bigendian=False,
            point_step=pts.dtype.itemsize,
            row_step=pts.dtype.itemsize * w,
            data=pts.reshape(-1).view(np.uint8),
            is_dense=False,
        )
        return self.serialize(msg)


class BagWriter:
    """One flavour of bag writer behind a common add/write/close."""

    def __init__(self, path: Path, fmt: str, storage: str, messages: MessageBuilder) -> None:
        self.messages = messages
        self.conns: dict[str, Any] = {}
        if fmt == "rosbag1":
            from rosbags.rosbag1 import Writer as Writer1

            self.writer: Any = Writer1(path)
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2

            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(path, version=9, storage_plugin=plugin)
        self.writer.open()

    def add(self, topic: str, msgtype: str, *, latched: bool = False) -> None:
        """Add a topic; a ``latched`` one (``/tf_static``) is offered to late subscribers too
        when the bag plays (ROS 1 latching, ROS 2 transient-local durability)."""
        options: dict[str, Any] = {}
        if latched and self.messages.ros2:
            options["offered_qos_profiles"] = [offered_qos(latched=True)]
        elif latched:
            options["latching"] = 1
        self.conns[topic] = self.writer.add_connection(
            topic, msgtype, typestore=self.messages.store, **options
        )

    def write(self, topic: str, ns: int, data: bytes) -> None:
        self.writer.write(self.conns[topic], ns, data)

    def close(self) -> None:
        self.writer.close()

    def abort(self) -> None:
        """Stop writing after a failure (the partial bag is removed by the caller)."""
        self.writer.abort()


def offered_qos(*, reliable: bool = True, latched: bool = False, depth: int = 1) -> Any:
    """An offered QoS profile as ``ros2 bag record`` stores it: keep last ``depth``, reliable
    or best effort, transient local (``latched``, as ``/tf_static`` is published) or volatile."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    never = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_LAST,
        depth,
        QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
        never,
        never,
        QosLiveliness.AUTOMATIC,
        never,
        False,
    )


class InTimeOrder:
    """The messages of a bag, written in time order: those of a frame wait until a frame
    stamped no earlier arrives (a frame's depth may be stamped after its color, or after the
    next frame's color). A message stamped before one already written is logged at that
    one's time (its header keeps its own stamp), so the bag's log times never go back."""

    def __init__(self, bag: BagWriter) -> None:
        self.bag = bag
        self.waiting: list[tuple[int, int, str, bytes]] = []
        self.count = 0
        self.last = -1

    def emit(self, topic: str, ns: int, data: bytes) -> None:
        heapq.heappush(self.waiting, (ns, self.count, topic, data))
        self.count += 1

    def flush(self, until: int | None = None) -> None:
        """Write the waiting messages stamped at or before ``until`` (all with ``None``)."""
        while self.waiting and (until is None or self.waiting[0][0] <= until):
            ns, _, topic, data = heapq.heappop(self.waiting)
            self.last = max(self.last, ns)
            self.bag.write(topic, self.last, data)
