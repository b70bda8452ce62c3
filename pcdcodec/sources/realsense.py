"""RealSense ``.bag`` recordings (RealSense Viewer, ``rs-record``) as a :class:`Source`.

A librealsense recording is a ROS 1 bag with its own topic layout, read here with ``rosbags``
(no librealsense needed)::

    /device_0/info                                   KeyValue: Name, Serial Number, ...
    /device_0/sensor_N/option/Depth Units/value      Float32: metres per depth unit
    /device_0/sensor_N/Depth_0/image/data            Image (mono16 / 16UC1)
    /device_0/sensor_N/Depth_0/info/camera_info      CameraInfo (K, D, "Brown Conrady", ...)
    /device_0/sensor_N/Depth_0/tf/0                  Transform: reference stream -> this stream
    /device_0/sensor_M/Color_0/image/data            Image (rgb8, bgr8, rgba8, bgra8)
    /device_0/sensor_M/Color_0/info/camera_info
    /device_0/sensor_M/Color_0/tf/0

Each stream's ``tf/0`` maps points of the device's reference stream into that stream's frame,
so ``depth_to_color = tf(color) · tf(depth)⁻¹`` (the depth stream is usually the reference and
its transform the identity). Depth stays the depth camera's, bit-exact; color keeps the color
camera's size. Each depth frame is paired with the color frame nearest to it in time.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..camera import CameraIntrinsics
from ..errors import DecodeError, InputError
from .base import FrameIndex, Source, read_magic, register_source

__all__ = ["RealSenseBagSource", "open_realsense"]

_ROSBAG_MAGIC = b"#ROSBAG V2.0\n"
_IMAGE = re.compile(r"^/device_(\d+)/sensor_(\d+)/(Depth|Color)_(\d+)/image/data$")
_NS = 1_000_000_000


def _is_realsense(path: Path) -> bool:
    if not path.is_file() or read_magic(path, len(_ROSBAG_MAGIC)) != _ROSBAG_MAGIC:
        return False
    try:
        from rosbags.rosbag1 import Reader

        from ._bagindex import bounded_path

        with Reader(bounded_path(path)) as reader:
            return any(_IMAGE.match(c.topic) for c in reader.connections)
    except Exception:
        return False


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * _NS + int(msg.header.stamp.nanosec)


def _image(msg: Any, what: str) -> npt.NDArray[Any]:
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    enc = str(msg.encoding).lower()
    if data.size < h * step:
        raise DecodeError(f"{what}: {data.size} bytes, expected height {h} x step {step}")
    rows = data[: h * step].reshape(h, step)
    if enc in ("mono16", "16uc1", "z16"):
        dt = np.dtype(">u2" if msg.is_bigendian else "<u2")
        depth: npt.NDArray[np.uint16] = rows[:, : 2 * w].copy().view(dt).reshape(h, w)
        return depth.astype(np.uint16)
    channels = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4}.get(enc)
    if channels is None:
        raise InputError(
            f"{what} has encoding {msg.encoding!r}; expected mono16/16UC1 depth or "
            "rgb8/bgr8/rgba8/bgra8 color"
        )
    img = rows[:, : channels * w].reshape(h, w, channels)[..., :3]
    if enc.startswith("bgr"):
        img = img[..., ::-1]
    return np.ascontiguousarray(img)


class RealSenseBagSource(Source):
    """Frames of a librealsense ``.bag``: depth with its own camera, color with its own.

    ``depth_scale`` (depth units per metre) overrides the recorded Depth Units option; without
    either, opening raises :class:`~pcdcodec.InputError`. ``max_dt`` (seconds) drops depth
    frames whose nearest color frame is farther away in time (default: keep every depth frame).
    ``max_frames`` stops early; ``intrinsics`` replaces the recorded depth camera. ``metadata``
    holds the device name, serial number and firmware, and the topics read.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        depth_scale: float | None = None,
        max_dt: float | None = None,
        max_frames: int | None = None,
        intrinsics: CameraIntrinsics | None = None,
    ) -> None:
        from rosbags.rosbag1 import Reader
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self._typestore = get_typestore(Stores.ROS1_NOETIC)
        self.max_dt = None if max_dt is None else round(max_dt * _NS)
        self.max_frames = max_frames
        self._index: FrameIndex | None = None
        name = str(self.path)
        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as exc:
            raise InputError(f"{name!r} is not a readable ROS 1 bag: {exc}") from exc
        try:
            self._read_header(reader, name, depth_scale)
        finally:
            reader.close()
        if intrinsics is not None:
            self.intrinsics = intrinsics

    # -- header ------------------------------------------------------------------------

    def _read_header(self, reader: Any, name: str, depth_scale: float | None) -> None:
        streams: dict[str, tuple[str, str]] = {}  # kind -> (prefix, sensor)
        for c in reader.connections:
            m = _IMAGE.match(c.topic)
            if m and m.group(3) not in streams:
                streams[m.group(3)] = (c.topic[: -len("/image/data")], m.group(2))
        if "Depth" not in streams:
            raise InputError(
                f"{name!r} is a ROS 1 bag without a librealsense depth stream "
                "(/device_N/sensor_N/Depth_N/image/data)"
            )
        depth_prefix, depth_sensor = streams["Depth"]
        color = streams.get("Color")
        self.depth_topic = f"{depth_prefix}/image/data"
        self.color_topic = None if color is None else f"{color[0]}/image/data"
        self.has_color = color is not None
        device = depth_prefix.split("/sensor_")[0]
        units_topic = f"{device}/sensor_{depth_sensor}/option/Depth Units/value"
        wanted = {
            f"{depth_prefix}/info/camera_info",
            f"{depth_prefix}/tf/0",
            units_topic,
            f"{device}/info",
        }
        if color is not None:
            wanted |= {f"{color[0]}/info/camera_info", f"{color[0]}/tf/0"}
        found: dict[str, Any] = {}
        info: dict[str, str] = {}
        conns = [c for c in reader.connections if c.topic in wanted]
        for conn, _, raw in reader.messages(connections=conns):
            msg: Any = self._typestore.deserialize_ros1(raw, conn.msgtype)
            if conn.topic == f"{device}/info":
                info[str(msg.key)] = str(msg.value)
            else:
                found.setdefault(conn.topic, msg)

        def camera(prefix: str) -> CameraIntrinsics:
            msg = found.get(f"{prefix}/info/camera_info")
            if msg is None:
                raise InputError(
                    f"{name!r} has no camera info for {prefix} ({prefix}/info/camera_info)"
                )
            try:
                return CameraIntrinsics.from_camera_info(
                    {
                        "width": int(msg.width),
                        "height": int(msg.height),
                        "K": [float(v) for v in msg.K],
                        "D": [float(v) for v in msg.D],
                        "distortion_model": str(msg.distortion_model),
                    }
                )
            except InputError as exc:
                raise InputError(f"{name!r}: camera info of {prefix}: {exc}") from None

        def tf(prefix: str) -> npt.NDArray[np.float64]:
            from ..transform import rigid_from_quaternion

            msg = found.get(f"{prefix}/tf/0")
            if msg is None:
                raise InputError(
                    f"{name!r} has no extrinsic for {prefix} ({prefix}/tf/0): cannot place the "
                    "color camera relative to the depth camera"
                )
            t, q = msg.translation, msg.rotation
            return rigid_from_quaternion([t.x, t.y, t.z], [q.x, q.y, q.z, q.w])

        self.intrinsics: CameraIntrinsics | None = camera(depth_prefix)
        if color is not None:
            self.color_intrinsics = camera(color[0])
            self.depth_to_color = tf(color[0]) @ np.linalg.inv(tf(depth_prefix))
        if depth_scale is None:
            units = found.get(units_topic)
            if units is None:
                raise InputError(
                    f"{name!r} has no depth units ({units_topic!r} is missing); pass "
                    "depth_scale= (depth units per metre, 1000 for millimetres)"
                )
            # The option is a float32: its shortest decimal form is the value that was set.
            metres = float(str(np.float32(units.data)))
            if not metres > 0:
                raise InputError(f"{name!r} records Depth Units {metres!r}; expected > 0 metres")
            depth_scale = 1.0 / metres
        self.depth_scale = float(depth_scale)
        self.metadata = {
            "source": "realsense",
            "depth_topic": self.depth_topic,
            **({"color_topic": self.color_topic} if self.color_topic else {}),
        }
        for key, label in (
            ("Name", "device"),
            ("Serial Number", "serial"),
            ("Firmware Version", "firmware"),
            ("Product Id", "product_id"),
        ):
            if key in info:
                self.metadata[label] = info[key]
        counts = {c.topic: c.msgcount for c in reader.connections}
        self._count = int(counts.get(self.depth_topic, 0))

    # -- frames ------------------------------------------------------------------------

    def __len__(self) -> int:
        if self.max_dt is not None:
            raise TypeError("frames farther than max_dt from any color frame are dropped")
        n = self._count
        return n if self.max_frames is None else min(n, self.max_frames)

    def __iter__(self) -> Iterator[Any]:
        from rosbags.rosbag1 import Reader

        from ..datasets import RGBDFrame

        with Reader(self.path) as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def images() -> Iterator[tuple[bool, int, Any]]:
                for conn, _, raw in reader.messages(connections=conns):
                    msg = self._typestore.deserialize_ros1(raw, conn.msgtype)
                    stamp = _stamp(msg)
                    is_depth = conn.topic == self.depth_topic
                    what = f"{'depth' if is_depth else 'color'} frame at {stamp} ns"
                    yield is_depth, stamp, _image(msg, what)

            for t, depth, rgb in self._pairs(images()):
                yield RGBDFrame(rgb, depth, t)

    def _image_topics(self) -> set[str | None]:
        return {self.depth_topic, self.color_topic}

    def _pairs(self, images: Iterator[tuple[bool, int, Any]]) -> Iterator[tuple[int, Any, Any]]:
        """``(timestamp, depth, color)`` from ``(is_depth, stamp, item)`` in bag order: each depth
        frame with the nearer of the color frames read before and after it (the items are
        images when reading, message positions when indexing)."""
        pending: deque[tuple[int, Any]] = deque()
        before: tuple[int, Any] | None = None
        emitted = 0
        has_color = self.color_topic is not None

        def pick(t: int, after: tuple[int, Any] | None) -> Any:
            options = [c for c in (before, after) if c is not None]
            if not options:
                return None
            best = min(options, key=lambda c: abs(c[0] - t))
            if self.max_dt is not None and abs(best[0] - t) > self.max_dt:
                return None
            return best[1]

        after: tuple[int, Any] | None
        for is_depth, stamp, item in images:
            if is_depth:
                pending.append((stamp, item))
                if has_color:
                    continue
                after = None
            else:
                after = (stamp, item)
            while pending and (after is None or pending[0][0] <= after[0]):
                t, depth = pending.popleft()
                rgb = pick(t, after) if has_color else None
                if rgb is None and has_color:
                    continue
                yield t, depth, rgb
                emitted += 1
                if self.max_frames is not None and emitted >= self.max_frames:
                    return
            if after is not None:
                before = after
        while pending:
            t, depth = pending.popleft()
            rgb = pick(t, None)
            if rgb is None and has_color:
                continue
            yield t, depth, rgb
            emitted += 1
            if self.max_frames is not None and emitted >= self.max_frames:
                return

    # -- segments: a frame index, and reading a stretch of frames on its own -------------

    def frame_index(self) -> FrameIndex:
        """Every frame's timestamp and the depth and color messages it is made of, from one
        pass that reads each image message's header stamp but decodes no image (see
        :meth:`pcdcodec.sources.rosbag.RosbagSource.frame_index` for the columns). Kept."""
        from rosbags.rosbag1 import Reader

        from . import _bagindex

        if self._index is not None:
            return self._index
        with Reader(self.path) as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def positions() -> Iterator[tuple[bool, int, Any]]:
                fast = _bagindex.ros1_index_stamps(reader, conns)
                if fast is not None:
                    for conn, t, ns in fast:
                        yield conn.topic == self.depth_topic, ns, (t, ns)
                    return
                for conn, t, raw in reader.messages(connections=conns):
                    stamp = _bagindex.ros1_stamp(raw)
                    if stamp is None:
                        stamp = _stamp(self._typestore.deserialize_ros1(raw, conn.msgtype))
                    yield conn.topic == self.depth_topic, stamp, (t, stamp)

            rows = [
                (t, d[0], d[1], *(c if c is not None else (-1, -1)))
                for t, d, c in self._pairs(positions())
            ]
        self._index = FrameIndex(np.array(rows, dtype=np.int64).reshape(-1, 5), 0)
        return self._index

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Any]:
        """Frames ``start`` to ``stop`` (exclusive): from a later frame than the first, through
        :meth:`frame_index` and :meth:`frames_at`, so the frames before are not read."""
        import itertools

        if start < 0 or (stop is not None and stop < 0):
            raise InputError(f"frames start and stop must be at least 0, got {start}, {stop}")
        if start == 0:
            return itertools.islice(iter(self), stop)
        return self.frames_at(self.frame_index().slice(start, stop))

    def frames_at(self, index: FrameIndex) -> Iterator[Any]:
        """The frames of a :meth:`frame_index` slice: only the messages logged between its
        first and last message are read (the bag's chunk index skips to them), and only the
        listed ones decoded. Raises :class:`~pcdcodec.DecodeError` when a listed message is
        missing (the index is another bag's)."""
        from rosbags.rosbag1 import Reader

        from ..datasets import RGBDFrame
        from . import _bagindex

        rows = _bagindex.check_rows(index.rows)
        if rows.shape[0] == 0:
            return
        color = self.color_topic is not None
        lo, hi = _bagindex.window(rows, color)
        with Reader(self.path) as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def messages() -> Iterator[tuple[bool, int, int, Any]]:
                for conn, t, raw in reader.messages(connections=conns, start=lo, stop=hi):
                    stamp = _bagindex.ros1_stamp(raw)
                    if stamp is None:
                        stamp = _stamp(self._typestore.deserialize_ros1(raw, conn.msgtype))
                    yield conn.topic == self.depth_topic, t, stamp, (conn, raw)

            def decode(is_depth: bool, item: tuple[Any, bytes]) -> Any:
                msg = self._typestore.deserialize_ros1(item[1], item[0].msgtype)
                stamp = _stamp(msg)
                return _image(msg, f"{'depth' if is_depth else 'color'} frame at {stamp} ns")

            where = repr(str(self.path))
            for t, depth, rgb in _bagindex.read_rows(
                rows, index.first, color, messages(), decode, where
            ):
                yield RGBDFrame(rgb, depth, t)


def open_realsense(path: str | Path, **options: Any) -> RealSenseBagSource:
    """Open a librealsense ``.bag`` (see :class:`RealSenseBagSource` for the options)."""
    return RealSenseBagSource(path, **options)


register_source(
    "realsense",
    _is_realsense,
    open_realsense,
    "a RealSense .bag from the RealSense Viewer or rs-record (ROS 1 bag, librealsense layout)",
    first=True,
)
