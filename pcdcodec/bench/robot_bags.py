"""ROS bags as a robot with a RealSense camera records them, made from real RGB-D frames, for
tests and benchmarks of whole-bag compression.

:func:`write_robot_bag` writes a ROS 1 bag or a ROS 2 bag (sqlite3 or mcap storage, optionally
split into several files as ``ros2 bag record --max-bag-size`` splits it) holding:

* the camera under realsense-ros names: ``/camera/color/image_raw`` (rgb8),
  ``/camera/depth/image_rect_raw`` and ``/camera/aligned_depth_to_color/image_raw`` (16UC1),
  each with its ``camera_info``; an organized ``/camera/depth/color/points`` cloud (x, y, z and
  packed rgb as float32 at offsets 0, 4, 8 and 16, ``point_step`` 20, as realsense-ros writes
  it; holes are x = y = z = 0, as its ordered cloud holds them) at ``cloud_hz``;
* ``/tf_static`` (latched / transient local): ``base_link -> camera_link`` and realsense-ros's
  frames below it; ``/tf`` (odom -> base_link, 100 Hz), ``/odom`` (50 Hz), ``/camera/imu``
  (200 Hz, gravity in the accelerometer), ``/joint_states`` (a 7-joint arm, 100 Hz) and
  ``/diagnostics`` (1 Hz), when ``extras`` is true.

The frames are real; the motion is not: the robot drives a smooth figure of eight, whatever the
camera saw, and sensor noise comes from a seeded generator, so a bag is the same every time.
Header stamps lie a few milliseconds before each message's log time, and messages are logged in
time order. The frames of the datasets at hand are registered (depth on the color camera's
pixel grid), so the "unaligned" depth holds the same pixels as the aligned one: it differs in
its frame (``camera_depth_optical_frame``), its camera_info (``depth_intrinsics``, by default
the same camera) and its stamps, and the tf tree puts both optical frames at ``camera_link``.

Frames are read as they are written and never all held: memory stays bounded however long the
bag, and ``seconds`` longer than the frames loops them.
"""

from __future__ import annotations

import heapq
import math
import operator
import shutil
from collections import defaultdict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import Projector
from ..ros.bagwriter import offered_qos
from .robot_streams import COLOR_FRAME, DEPTH_FRAME, BagMessages, extra_streams, static_tf

__all__ = [
    "ALIGNED",
    "ALIGNED_INFO",
    "CLOUD",
    "COLOR",
    "COLOR_FRAME",
    "COLOR_INFO",
    "DEPTH",
    "DEPTH_FRAME",
    "DEPTH_INFO",
    "KINDS",
    "REALSENSE_CLOUD_DTYPE",
    "TOPICS",
    "RobotBagSummary",
    "SequenceFrames",
    "write_robot_bag",
]

KINDS = ("ros1", "ros2-sqlite3", "ros2-mcap")
_NS = 1_000_000_000
_CAMERA_NODE = "/camera/realsense2_camera_manager"  # realsense-ros's nodelet manager (ROS 1)

COLOR, COLOR_INFO = "/camera/color/image_raw", "/camera/color/camera_info"
DEPTH, DEPTH_INFO = "/camera/depth/image_rect_raw", "/camera/depth/camera_info"
ALIGNED = "/camera/aligned_depth_to_color/image_raw"
ALIGNED_INFO = "/camera/aligned_depth_to_color/camera_info"
CLOUD = "/camera/depth/color/points"

#: topic -> (message type, ROS 1 callerid, whether it is an extra, not a camera topic)
TOPICS: dict[str, tuple[str, str, bool]] = {
    COLOR: ("sensor_msgs/msg/Image", _CAMERA_NODE, False),
    COLOR_INFO: ("sensor_msgs/msg/CameraInfo", _CAMERA_NODE, False),
    DEPTH: ("sensor_msgs/msg/Image", _CAMERA_NODE, False),
    DEPTH_INFO: ("sensor_msgs/msg/CameraInfo", _CAMERA_NODE, False),
    ALIGNED: ("sensor_msgs/msg/Image", _CAMERA_NODE, False),
    ALIGNED_INFO: ("sensor_msgs/msg/CameraInfo", _CAMERA_NODE, False),
    CLOUD: ("sensor_msgs/msg/PointCloud2", _CAMERA_NODE, False),
    "/tf_static": ("tf2_msgs/msg/TFMessage", _CAMERA_NODE, False),
    "/camera/imu": ("sensor_msgs/msg/Imu", _CAMERA_NODE, True),
    "/tf": ("tf2_msgs/msg/TFMessage", "/ekf_localization", True),
    "/odom": ("nav_msgs/msg/Odometry", "/base_controller", True),
    "/joint_states": ("sensor_msgs/msg/JointState", "/joint_state_publisher", True),
    "/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", "/diagnostic_aggregator", True),
}

#: realsense-ros's organized cloud: PCL's "xyz" (padded to 16 bytes), then "rgb" as FLOAT32
#: holding the bytes b, g, r, 0 (read here as uint32 ``r << 16 | g << 8 | b``).
REALSENSE_CLOUD_DTYPE = np.dtype(
    {"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
     "offsets": [0, 4, 8, 16], "itemsize": 20}
)  # fmt: skip


@dataclass(frozen=True)
class RobotBagSummary:
    """What :func:`write_robot_bag` wrote: the messages of each topic, the bytes on disk (every
    file of the bag), the span of the log times in seconds and the storage files."""

    path: Path
    kind: str
    topics: dict[str, int]
    bytes: int
    duration_s: float
    files: tuple[Path, ...]


class SequenceFrames:
    """The ``(depth, color)`` frames of one of the shared sequences (see
    :data:`pcdcodec.bench.sequences.SEQUENCES`), read from disk on each pass, at most ``count``
    of them. Iterating again starts over, so the frames can be looped without holding them."""

    def __init__(self, name: str, count: int | None = None) -> None:
        from .sequences import SEQUENCES

        if name not in SEQUENCES:
            raise InputError(f"unknown sequence {name!r}; expected one of {sorted(SEQUENCES)}")
        self.sequence = SEQUENCES[name]
        self.count = count

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self.sequence.camera

    @property
    def depth_scale(self) -> float:
        return self.sequence.depth_scale

    def __len__(self) -> int:
        from ..sources import open_source

        seq = self.sequence
        with open_source(seq.root, **seq.reader_options()) as source:
            n = operator.length_hint(source)
        return n if self.count is None else min(n, self.count)

    def __iter__(self) -> Iterator[tuple[npt.NDArray[np.uint16], npt.NDArray[np.uint8]]]:
        from ..sources import open_source

        seq = self.sequence
        with open_source(seq.root, **seq.reader_options()) as source:
            for i, frame in enumerate(source):
                if self.count is not None and i >= self.count:
                    return
                if frame.color is None:
                    raise InputError(f"{seq.root}: frame {i} has no color")
                yield frame.depth, frame.color


_QOS: dict[str, dict[str, Any]] = {"/tf_static": {"latched": True}, "/tf": {"depth": 100}}
_QOS["/camera/imu"] = {"reliable": False, "depth": 5}


class _Sink:
    """A ROS 1 bag, or a ROS 2 bag of one or several files (a new file once ``split_bytes``
    of messages went into the current one), behind one add/write/close."""

    def __init__(self, path: Path, kind: str, store: Any, split: int | None, compression: Any):
        self.path, self.kind, self.store, self.split = path, kind, store, split
        self.compression = compression
        self.topics: list[tuple[str, str, str]] = []
        self.files: list[Path] = []
        self.metadata: list[dict[str, Any]] = []
        self.filled = 0
        if split is not None:
            path.mkdir(parents=True)
        self.writer = self._open()

    def _open(self) -> Any:
        if self.kind == "ros1":
            from rosbags.rosbag1 import Writer as Writer1

            writer: Any = Writer1(self.path)
            if self.compression is not None:
                writer.set_compression(self.compression)
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2

            plugin = StoragePlugin.MCAP if self.kind == "ros2-mcap" else StoragePlugin.SQLITE3
            where = self.path
            if self.split is not None:  # rosbags writes one file: each split in its own folder
                where = self.path / f"{self.path.name}_{len(self.files)}"
            writer = Writer2(where, version=9, storage_plugin=plugin)
        writer.open()
        self.conns = {
            topic: self._add(writer, topic, msgtype, callerid)
            for topic, msgtype, callerid in self.topics
        }
        return writer

    def _add(self, writer: Any, topic: str, msgtype: str, callerid: str) -> Any:
        if self.kind == "ros1":
            latching = 1 if topic == "/tf_static" else None
            return writer.add_connection(
                topic, msgtype, typestore=self.store, callerid=callerid, latching=latching
            )
        qos = offered_qos(**_QOS.get(topic, {}))
        return writer.add_connection(
            topic, msgtype, typestore=self.store, offered_qos_profiles=[qos]
        )

    def add(self, topic: str, msgtype: str, callerid: str) -> None:
        self.topics.append((topic, msgtype, callerid))
        self.conns[topic] = self._add(self.writer, topic, msgtype, callerid)

    def write(self, topic: str, ns: int, data: bytes) -> None:
        if self.split is not None and self.filled >= self.split:
            self._close_split()
            self.writer = self._open()
        self.writer.write(self.conns[topic], ns, data)
        self.filled += len(data)

    def _close_split(self) -> None:
        from ruamel.yaml import YAML

        self.writer.close()
        folder = self.writer.path
        info = YAML(typ="safe").load((folder / "metadata.yaml").read_text())
        info = info["rosbag2_bagfile_information"]
        name = info["relative_file_paths"][0]
        shutil.move(str(folder / name), str(self.path / name))
        shutil.rmtree(folder)
        self.files.append(self.path / name)
        self.metadata.append(info)
        self.filled = 0

    def close(self) -> list[Path]:
        if self.split is None:
            self.writer.close()
            if self.kind == "ros1":
                return [self.path]
            return sorted(p for p in self.path.iterdir() if p.name != "metadata.yaml")
        self._close_split()
        self._write_metadata()
        return self.files

    def _write_metadata(self) -> None:
        """One metadata.yaml listing every file, as ``ros2 bag record`` leaves a split bag."""
        from ruamel.yaml import YAML

        parts = self.metadata
        start = min(p["starting_time"]["nanoseconds_since_epoch"] for p in parts)
        end = max(
            p["starting_time"]["nanoseconds_since_epoch"] + p["duration"]["nanoseconds"]
            for p in parts
        )
        counts: dict[str, int] = defaultdict(int)
        for part in parts:
            for topic in part["topics_with_message_count"]:
                counts[topic["topic_metadata"]["name"]] += topic["message_count"]
        merged = dict(parts[0])
        merged["relative_file_paths"] = [p["relative_file_paths"][0] for p in parts]
        merged["files"] = [p["files"][0] for p in parts]
        merged["starting_time"] = {"nanoseconds_since_epoch": start}
        merged["duration"] = {"nanoseconds": end - start}
        merged["message_count"] = sum(p["message_count"] for p in parts)
        merged["topics_with_message_count"] = [
            {**t, "message_count": counts[t["topic_metadata"]["name"]]}
            for t in parts[0]["topics_with_message_count"]
        ]
        yaml = YAML(typ="safe")
        yaml.default_flow_style = False
        with (self.path / "metadata.yaml").open("w", encoding="utf8") as out:
            yaml.dump({"rosbag2_bagfile_information": merged}, out)

    def abort(self) -> None:
        self.writer.abort()


def _frames(frames: Iterable[Any], count: int) -> Iterator[tuple[int, Any, Any]]:
    """``count`` frames ``(i, depth, color)``, starting ``frames`` over when it runs out."""
    i = 0
    while i < count:
        before = i
        for depth, color in frames:
            yield i, depth, color
            i += 1
            if i == count:
                return
        if i == before:
            raise InputError("write_robot_bag was given no frames (or an exhausted iterator)")


def _camera(
    msgs: BagMessages, frames: Iterable[Any], count: int, start: int, fps: float, cloud_hz: float,
    color_k: CameraIntrinsics, depth_k: CameraIntrinsics, depth_scale: float, seed: int,
) -> Iterator[Any]:  # fmt: skip
    """The camera's messages in log-time order: a frame's messages wait in a small heap until
    no later frame can be logged before them."""
    rng = np.random.default_rng(seed)
    projector = Projector(depth_k, depth_scale)
    ratio = cloud_hz / fps
    period = _NS / fps
    lag = min(8_000_000, int(period / 4))  # the least time from a stamp to its log
    waiting: list[tuple[int, int, str, bytes]] = []
    n = 0
    for i, depth, color in _frames(frames, count):
        depth = np.asarray(depth)
        color = np.asarray(color)
        if depth.dtype != np.uint16 or depth.shape != depth_k.shape:
            raise InputError(
                f"frame {i}: depth must be uint16 of {depth_k.shape}, got {depth.dtype} "
                f"{depth.shape}"
            )
        if color.dtype != np.uint8 or color.shape != (*color_k.shape, 3):
            raise InputError(
                f"frame {i}: color must be uint8 of {(*color_k.shape, 3)}, got {color.dtype} "
                f"{color.shape}"
            )
        t = start + round(i * period) + int(rng.integers(0, 200_000))
        ct = t + 1_000_000 + int(rng.integers(0, 200_000))  # color exposure ends a bit later

        def late(base: int, share: float) -> int:
            return base + lag + int(share * 2 * lag) + int(rng.integers(0, lag // 4))

        log_c, log_d, log_a = late(ct, 0.5), late(t, 0.0), late(t, 1.0)
        out = [
            (log_c, COLOR, msgs.image(COLOR, COLOR_FRAME, ct, color, "rgb8")),
            (log_c, COLOR_INFO, msgs.camera_info(COLOR_INFO, COLOR_FRAME, ct, color_k)),
            (log_d, DEPTH, msgs.image(DEPTH, DEPTH_FRAME, t, depth, "16UC1")),
            (log_d, DEPTH_INFO, msgs.camera_info(DEPTH_INFO, DEPTH_FRAME, t, depth_k)),
            (log_a, ALIGNED, msgs.image(ALIGNED, COLOR_FRAME, t, depth, "16UC1")),
            (log_a, ALIGNED_INFO, msgs.camera_info(ALIGNED_INFO, COLOR_FRAME, t, color_k)),
        ]
        if i == 0 or math.floor(i * ratio) > math.floor((i - 1) * ratio):
            pts = np.zeros(depth.shape, REALSENSE_CLOUD_DTYPE)
            xyz = np.nan_to_num(projector.to_organized(depth), nan=0.0)
            for axis, name in enumerate("xyz"):
                pts[name] = xyz[..., axis]
            c = color.astype(np.uint32)
            pts["rgb"] = (c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]
            out.append((late(t, 1.5), CLOUD, msgs.cloud(CLOUD, DEPTH_FRAME, t, pts)))
        for log, topic, data in out:
            heapq.heappush(waiting, (log, n, topic, data))
            n += 1
        next_log = start + round((i + 1) * period) + lag
        while waiting and waiting[0][0] <= next_log:
            log, _, topic, data = heapq.heappop(waiting)
            yield log, topic, data
    while waiting:
        log, _, topic, data = heapq.heappop(waiting)
        yield log, topic, data


def write_robot_bag(
    path: str | Path,
    frames: Iterable[Any],
    *,
    kind: str = "ros1",
    intrinsics: CameraIntrinsics,
    depth_scale: float,
    depth_intrinsics: CameraIntrinsics | None = None,
    fps: float = 30.0,
    seconds: float | None = None,
    cloud_hz: float = 15.0,
    extras: bool = True,
    split_bytes: int | None = None,
    compression: str | None = None,
    start_ns: int = 1_700_000_000 * _NS,
    seed: int = 0,
) -> RobotBagSummary:
    """Write a bag at ``path`` as a robot with a RealSense camera records it (see the module).

    ``frames`` yields ``(depth, color)`` pairs: H×W uint16 depth in units of ``1/depth_scale``
    metres (ROS reads 16UC1 as millimetres, so frames of another scale need the scale given
    when read) and H×W×3 uint8 RGB, of the color camera ``intrinsics``; it must start over when
    iterated again (a list, or :class:`SequenceFrames`) if ``seconds`` asks for more frames
    than it has. ``depth_intrinsics`` is the depth topic's camera (default: ``intrinsics``).
    Frame ``i`` is stamped ``start_ns + i / fps``; the bag lasts ``seconds`` (default: one pass
    over the frames). ``kind`` is one of :data:`KINDS`; ``split_bytes`` (ROS 2 only) starts a
    new storage file once that many message bytes went into one; ``compression`` (ROS 1 only)
    is ``"lz4"`` or ``"bz2"`` chunks. ``path`` must not exist. Raises
    :class:`~pcdcodec.InputError` for a bad option or frame.
    """
    from rosbags.rosbag1 import Writer as Writer1

    path = Path(path)
    if kind not in KINDS:
        raise InputError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if path.exists():
        raise InputError(f"{str(path)!r} exists already; write_robot_bag writes a new bag")
    if not (0 < cloud_hz <= fps) or not math.isfinite(fps):
        raise InputError(f"need 0 < cloud_hz <= fps, got cloud_hz {cloud_hz}, fps {fps}")
    if split_bytes is not None and (kind == "ros1" or split_bytes < 1):
        raise InputError(f"split_bytes is for ROS 2 bags, a positive size; got {split_bytes}")
    formats = {"lz4": Writer1.CompressionFormat.LZ4, "bz2": Writer1.CompressionFormat.BZ2}
    if compression is not None and (kind != "ros1" or compression not in formats):
        raise InputError(f"compression is 'lz4' or 'bz2', for ROS 1 bags; got {compression!r}")
    if seconds is None:
        count = operator.length_hint(frames)
        if count < 1:
            raise InputError("frames has no length: give seconds, or a list of frames")
    elif seconds > 0 and math.isfinite(seconds):
        count = max(1, round(seconds * fps))
    else:
        raise InputError(f"seconds must be positive and finite, got {seconds}")
    end = start_ns + round(count * _NS / fps)
    msgs = BagMessages(ros2=kind != "ros1")
    streams = [
        static_tf(msgs, start_ns),
        _camera(msgs, frames, count, start_ns, fps, cloud_hz, intrinsics,
                depth_intrinsics or intrinsics, depth_scale, seed),
    ]  # fmt: skip
    if extras:
        streams += extra_streams(msgs, start_ns, end, seed)
    chosen = {topic: v for topic, v in TOPICS.items() if extras or not v[2]}
    sink = _Sink(path, kind, msgs.builder.store, split_bytes, formats.get(compression or ""))
    counts: dict[str, int] = dict.fromkeys(chosen, 0)
    first = last = None
    try:
        for topic, (msgtype, callerid, _) in chosen.items():
            sink.add(topic, msgtype, callerid)
        for log, topic, data in heapq.merge(*streams, key=lambda m: m[0]):
            sink.write(topic, log, data)
            counts[topic] += 1
            first = log if first is None else first
            last = log
        files = sink.close()
    except BaseException:
        sink.abort()
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        raise
    size = sum(f.stat().st_size for f in files)
    if kind != "ros1":
        size += (path / "metadata.yaml").stat().st_size
    duration = 0.0 if first is None or last is None else (last - first) / _NS
    return RobotBagSummary(path, kind, counts, size, duration, tuple(files))
