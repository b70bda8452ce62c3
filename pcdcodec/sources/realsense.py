"""RealSense ``.bag`` recordings (RealSense Viewer, ``rs-record``) as a :class:`Source`.

A librealsense recording is a ROS 1 bag with its own topic layout, read here with ``rosbags``
(no librealsense needed)::

    /device_0/info                                   KeyValue: Name, Serial Number, ...
    /device_0/sensor_N/option/Depth Units/value      Float32: metres per depth unit
    /device_0/sensor_N/Depth_0/image/data            Image (mono16 / 16UC1)
    /device_0/sensor_N/Depth_0/info/camera_info      CameraInfo (K, D, "Brown Conrady", ...)
    /device_0/sensor_N/Depth_0/tf/0                  Transform: reference stream -> this stream
    /device_0/sensor_M/Color_0/image/data            Image (rgb8, bgr8, rgba8, bgra8, mjpeg)
    /device_0/sensor_M/Color_0/info/camera_info
    /device_0/sensor_M/Color_0/tf/0

Each stream's ``tf/0`` maps points of the device's reference stream into that stream's frame,
so ``depth_to_color = tf(color) · tf(depth)⁻¹`` (the depth stream is usually the reference and
its transform the identity). Depth stays the depth camera's, bit-exact; color keeps the color
camera's size. Depth and color are paired by the rule of every reader (:mod:`pcdcodec.sync`).
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError, PcdcodecError
from ..geometry.camera import CameraIntrinsics, as_intrinsics
from ..ros.bagfile import ROS1_MAGIC
from ..ros.bagindex import PairStats, check_ros1_index, pair_in_order
from ..ros.kept import TopicFilter
from ..sync import MAX_DIFFERENCE, as_max_difference
from ._bag_kept import BagKeptTopics
from .base import FrameIndex, InputStream, Source, read_magic, register_source, streams_by_name

__all__ = ["RealSenseBagSource", "open_realsense"]

_IMAGE = re.compile(r"^/device_(\d+)/sensor_(\d+)/(Depth|Color)_(\d+)/image/data$")
_NS = 1_000_000_000


def _is_realsense(path: Path) -> bool:
    if not path.is_file() or read_magic(path, len(ROS1_MAGIC)) != ROS1_MAGIC:
        return False
    try:
        from rosbags.rosbag1 import Reader

        from ..ros.bagindex import bounded_path

        with Reader(bounded_path(path)) as reader:
            return any(_IMAGE.match(c.topic) for c in reader.connections)
    except Exception:
        return False


def _stamp(msg: Any, where: str) -> int:
    """A header stamp in ns. ROS 1 seconds are unsigned 32-bit (rosbags gives them signed), read
    here as the frame index reads them from the raw bytes, so both give one timeline."""
    sec, nsec = int(msg.header.stamp.sec) % 2**32, int(msg.header.stamp.nanosec)
    if not 0 <= nsec < _NS:
        raise DecodeError(f"{where}: header stamp nanoseconds {nsec}; expected 0 to 999999999")
    return sec * _NS + nsec


_DEPTH_ENCODINGS = ("mono16", "16uc1", "z16")
#: color encodings librealsense records that we read: bytes a pixel, or 0 for a compressed image
_COLOR_ENCODINGS = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mjpeg": 0, "jpeg": 0}


def _image(msg: Any, where: str, is_depth: bool, shape: tuple[int, int]) -> npt.NDArray[Any]:
    """The pixels of an Image message, after checking its encoding, size and layout against
    ``shape`` (the camera's ``(height, width)``) and its data length, before allocating.
    ``where`` names the file, topic and stamp in errors."""
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    enc = str(msg.encoding).lower()
    if is_depth:
        if enc not in _DEPTH_ENCODINGS:
            raise InputError(
                f"{where}: depth image has encoding {msg.encoding!r}; expected mono16 or 16UC1"
            )
        pixel = 2
    else:
        if enc not in _COLOR_ENCODINGS:
            raise InputError(
                f"{where}: color image has encoding {msg.encoding!r}; pcdcodec reads "
                "rgb8, bgr8, rgba8, bgra8 and mjpeg (record color as RGB8 or BGR8)"
            )
        pixel = _COLOR_ENCODINGS[enc]
    if (h, w) != shape:
        raise DecodeError(
            f"{where}: image is {w}x{h}, but its camera info says {shape[1]}x{shape[0]}"
        )
    data = msg.data
    if pixel == 0:
        return _jpeg(bytes(data), where, shape)
    if step < w * pixel:
        raise DecodeError(
            f"{where}: {msg.encoding} image {w} pixels wide has step {step} bytes; expected at "
            f"least {w * pixel}"
        )
    if len(data) != h * step:
        raise DecodeError(
            f"{where}: image holds {len(data)} bytes; expected height {h} x step {step} = "
            f"{h * step}"
        )
    rows = np.asarray(data, dtype=np.uint8).reshape(h, step)
    if is_depth:
        dt = np.dtype(">u2" if msg.is_bigendian else "<u2")
        depth: npt.NDArray[np.uint16] = rows[:, : 2 * w].copy().view(dt).reshape(h, w)
        return depth.astype(np.uint16)
    img = rows[:, : pixel * w].reshape(h, w, pixel)[..., :3]
    if enc.startswith("bgr"):
        img = img[..., ::-1]
    return np.ascontiguousarray(img)


def _jpeg(data: bytes, where: str, shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """An MJPEG color image, checked whole and of the camera's size before it is decoded."""
    import cv2

    from ..color.images import check_compressed

    header = check_compressed(data, where, shape)
    if header.format != "jpeg" or header.channels != 3:
        raise DecodeError(
            f"{where}: mjpeg color image is a {header.format.upper()} of {header.channels} "
            "channels; expected a 3-channel JPEG"
        )
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if img is None or img.shape != (*shape, 3):
        raise DecodeError(f"{where}: mjpeg color image does not decode")
    return np.ascontiguousarray(img[..., ::-1])


def _checked(items: Iterator[Any], where: str) -> Iterator[Any]:
    """``items`` with any error of the bag library while reading turned into a
    :class:`~pcdcodec.DecodeError` naming ``where`` (a damaged chunk: lz4 or bz2 that does not
    decompress, a record cut short)."""
    while True:
        try:
            item = next(items)
        except StopIteration:
            return
        except PcdcodecError:
            raise
        except Exception as exc:
            text = str(exc) or type(exc).__name__
            raise DecodeError(f"{where}: the bag is damaged: {text}") from exc
        yield item


def _image_topics(source: Any) -> set[str]:
    return {t for t in (source.depth_topic, source.color_topic) if t}


class RealSenseBagSource(BagKeptTopics, Source):
    """Frames of a librealsense ``.bag``: depth with its own camera, color with its own.

    ``depth_scale`` (depth units per metre) overrides the recorded Depth Units option; without
    either, opening raises :class:`~pcdcodec.InputError`. Depth and color are paired by the
    rule of every reader (:mod:`pcdcodec.sync`): each image used once, within
    ``max_difference`` ns (default :data:`~pcdcodec.sync.MAX_DIFFERENCE`, 20 ms; ``max_dt``
    in seconds is its former name). ``max_frames`` stops early; ``intrinsics`` replaces the
    recorded depth camera; ``color_topic`` picks the color stream by its image topic (default
    the first; ``''`` or ``'none'`` reads the depth alone, leaving the color topics out).
    ``metadata`` holds the device name, serial number and firmware, and the topics read.
    :attr:`dropped` counts the images left out for want of a partner. Every other topic (IMU,
    infrared, options, per-frame metadata, stream infos, ...) is kept as it came
    (:meth:`kept_topics`), as a ROS bag's are: ``keep_topics``, ``include_topics`` and
    ``exclude_topics`` choose them as they do for :class:`~pcdcodec.sources.rosbag.RosbagSource`.

    Color is read from rgb8, bgr8, rgba8, bgra8 and mjpeg Images (a JPEG is checked whole and of
    the color camera's size before it is decoded). Every Image is checked against its camera
    info (size), its step and its data length before its pixels are used. Errors are
    :class:`~pcdcodec.PcdcodecError` naming the file, and the topic and stamp where there is
    one: :class:`~pcdcodec.InputError` for what the bag declares (a missing camera info,
    extrinsic or depth units, an encoding pcdcodec does not read, a topic of another message
    type), :class:`~pcdcodec.DecodeError` for what it holds (an image of the wrong size or
    length, a chunk that does not decompress).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        depth_scale: float | None = None,
        max_difference: int = MAX_DIFFERENCE,
        max_dt: float | None = None,
        max_frames: int | None = None,
        intrinsics: CameraIntrinsics | None = None,
        color_topic: str | None = None,
        keep_topics: bool = True,
        include_topics: Sequence[str] | str | None = None,
        exclude_topics: Sequence[str] | str | None = None,
    ) -> None:
        from rosbags.rosbag1 import Reader
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self.topic_filter = TopicFilter.of(include_topics, exclude_topics, keep_topics)
        self._typestore = get_typestore(Stores.ROS1_NOETIC)
        if max_dt is not None:  # the former name, in seconds
            max_difference = round(max_dt * _NS)
        self.max_difference = as_max_difference(max_difference)
        self.max_frames = max_frames
        self._index: FrameIndex | None = None
        self._stats = PairStats()
        name = str(self.path)
        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as exc:
            raise InputError(f"{name!r} is not a readable ROS 1 bag: {exc}") from exc
        try:
            check_ros1_index(reader, repr(name))
            self._read_header(reader, name, depth_scale, color_topic)
        finally:
            reader.close()
        if intrinsics is not None:
            own = self.intrinsics  # a bare matrix takes the recorded depth camera's size
            size = (own.width, own.height) if own is not None else (None, None)
            self.intrinsics = as_intrinsics(intrinsics, "intrinsics", *size)

    def _deserialize(self, raw: bytes, conn: Any) -> Any:
        """A message of ``conn``, or a :class:`~pcdcodec.DecodeError` naming the file and topic."""
        try:
            return self._typestore.deserialize_ros1(raw, conn.msgtype)
        except Exception as exc:
            raise DecodeError(
                f"{str(self.path)!r}: a message on {conn.topic} does not read as "
                f"{conn.msgtype}: {exc or type(exc).__name__}"
            ) from None

    def _messages(self, reader: Any, conns: list[Any], **window: Any) -> Iterator[Any]:
        """``reader.messages`` of ``conns``, with the bag library's errors as ours."""
        return _checked(reader.messages(connections=conns, **window), repr(str(self.path)))

    # -- header ------------------------------------------------------------------------

    def _read_header(
        self, reader: Any, name: str, depth_scale: float | None, color_topic: str | None
    ) -> None:
        streams: dict[str, tuple[str, str]] = {}  # kind -> (prefix, sensor)
        colors: dict[str, tuple[str, str]] = {}  # every color image topic -> (prefix, sensor)
        for c in reader.connections:
            m = _IMAGE.match(c.topic)
            if m and m.group(3) == "Color":
                colors[c.topic] = (c.topic[: -len("/image/data")], m.group(2))
            if m and m.group(3) not in streams:
                streams[m.group(3)] = (c.topic[: -len("/image/data")], m.group(2))
        if color_topic is not None and color_topic.strip().lower() in ("", "none"):
            streams.pop("Color", None)  # depth only, as in a ROS bag: the color topics left out
        elif color_topic is not None:
            if color_topic not in colors:
                raise InputError(
                    f"{name!r} has no color topic {color_topic!r}; its color topics: "
                    f"{', '.join(sorted(colors)) or 'none'} ('' for depth only)"
                )
            streams["Color"] = colors[color_topic]
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
        types = {
            "image/data": "sensor_msgs/msg/Image",
            "camera_info": "sensor_msgs/msg/CameraInfo",
            "tf/0": "geometry_msgs/msg/Transform",
            "value": "std_msgs/msg/Float32",
            "info": "diagnostic_msgs/msg/KeyValue",
        }
        conns = [c for c in reader.connections if c.topic in wanted | _image_topics(self)]
        for c in conns:
            want = next(t for end, t in types.items() if c.topic.endswith("/" + end))
            if c.msgtype != want:
                raise InputError(f"{name!r}: topic {c.topic} holds {c.msgtype}; expected {want}")
        conns = [c for c in conns if c.topic in wanted]
        for conn, _, raw in self._messages(reader, conns):
            msg: Any = self._deserialize(raw, conn)
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
            from ..geometry.transform import rigid_from_quaternion

            msg = found.get(f"{prefix}/tf/0")
            if msg is None:
                raise InputError(
                    f"{name!r} has no extrinsic for {prefix} ({prefix}/tf/0): cannot place the "
                    "color camera relative to the depth camera"
                )
            t, q = msg.translation, msg.rotation
            values = [t.x, t.y, t.z, q.x, q.y, q.z, q.w]
            if not np.all(np.isfinite(values)):
                raise InputError(f"{name!r}: the extrinsic {prefix}/tf/0 holds {values}")
            try:
                return rigid_from_quaternion(values[:3], values[3:])
            except InputError as exc:
                raise InputError(f"{name!r}: the extrinsic {prefix}/tf/0: {exc}") from None

        self.intrinsics: CameraIntrinsics | None = camera(depth_prefix)
        self._shapes = {True: self.intrinsics.shape, False: (0, 0)}
        # What the recording holds of the bag: the images, the cameras, the device's info, and
        # the extrinsics and depth units where they are used.
        conns_all = self._connections = list(reader.connections)
        self._streams = streams_by_name((c.topic, c.msgtype, c.msgcount) for c in conns_all)
        self._recorded = {self.depth_topic, f"{depth_prefix}/info/camera_info", f"{device}/info"}
        if color is not None:
            self.color_intrinsics = camera(color[0])
            self._shapes[False] = self.color_intrinsics.shape
            self.depth_to_color = tf(color[0]) @ np.linalg.inv(tf(depth_prefix))
            self._recorded |= {
                f"{color[0]}/image/data",
                f"{color[0]}/info/camera_info",
                f"{color[0]}/tf/0",
                f"{depth_prefix}/tf/0",
            }
        if depth_scale is None:
            self._recorded.add(units_topic)
            units = found.get(units_topic)
            if units is None:
                raise InputError(
                    f"{name!r} has no depth units ({units_topic!r} is missing); pass "
                    "depth_scale= (depth units per metre, 1000 for millimetres)"
                )
            # The option is a float32: its shortest decimal form is the value that was set.
            metres = float(str(np.float32(units.data)))
            if not (metres > 0 and np.isfinite(1.0 / metres)) or metres == float("inf"):
                raise InputError(
                    f"{name!r} records Depth Units {metres!r} ({units_topic}); expected a "
                    "finite number of metres > 0"
                )
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
        if info:  # every key of the device's info, as the bag holds them
            self.metadata["device_info"] = json.dumps(info, sort_keys=True)
        counts = {c.topic: c.msgcount for c in reader.connections}
        self._count = int(counts.get(self.depth_topic, 0))

    # -- frames ------------------------------------------------------------------------

    def __len__(self) -> int:
        if self.color_topic is not None:
            raise TypeError("depth frames without a color frame within max_difference are dropped")
        n = self._count
        return n if self.max_frames is None else min(n, self.max_frames)

    def __iter__(self) -> Iterator[Any]:

        from ..frame import Frame as RGBDFrame

        with self._reader() as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def images() -> Iterator[tuple[bool, int, Any]]:
                for conn, _, raw in self._messages(reader, conns):
                    is_depth = conn.topic == self.depth_topic
                    yield is_depth, *self._decode(conn, raw, is_depth)

            self._stats = PairStats()
            for t, depth, rgb, color_t in self._pairs(images(), self._stats):
                yield RGBDFrame(rgb, depth, t, color_timestamp_ns=color_t)

    @property
    def dropped(self) -> dict[str, int]:
        """Images read but left out so far for want of a partner within ``max_difference``, by
        stream, as every reader counts them."""
        return {"color": self._stats.dropped_color, "depth": self._stats.dropped_depth}

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["dropped"] = self.dropped
        out["depth_topic"] = self.depth_topic
        out["color_topic"] = self.color_topic
        return out

    def _image_topics(self) -> set[str]:
        return _image_topics(self)

    def input_streams(self) -> list[InputStream]:
        """Every topic of the bag, with its type and message count from the bag's index."""
        return list(self._streams)

    def recorded_streams(self) -> set[str]:
        """The image topics, their camera infos, the device's info, and the extrinsics and the
        Depth Units option where they are used; the other topics (IMU, infrared, the other
        options, the per-frame metadata, the stream infos) are kept as they came, unless
        ``keep_topics``, ``include_topics`` or ``exclude_topics`` leave them out."""
        return set(self._recorded)

    def _bag_connections(self) -> tuple[list[Any], bool]:
        return self._connections, False

    @contextmanager
    def _reader(self) -> Iterator[Any]:
        """An open reader of the bag; a file that no longer opens raises
        :class:`~pcdcodec.DecodeError` naming it."""
        from rosbags.rosbag1 import Reader

        reader = Reader(self.path)
        try:
            reader.open()
        except Exception as exc:
            raise DecodeError(f"{str(self.path)!r} is not a readable ROS 1 bag: {exc}") from exc
        try:
            check_ros1_index(reader, repr(str(self.path)))
            yield reader
        finally:
            reader.close()

    def _decode(self, conn: Any, raw: bytes, is_depth: bool) -> tuple[int, Any]:
        """The stamp (ns) and pixels of an image message, checked against its camera."""
        msg = self._deserialize(raw, conn)
        where = f"{str(self.path)!r}: {conn.topic}"
        stamp = _stamp(msg, where)
        return stamp, _image(msg, f"{where} at {stamp} ns", is_depth, self._shapes[is_depth])

    def _pairs(
        self, images: Iterator[tuple[bool, int, Any]], stats: PairStats | None = None
    ) -> Iterator[tuple[int, Any, Any, int | None]]:
        """``(timestamp, depth, color, color stamp)`` from ``(is_depth, stamp, item)`` in bag
        order (the items are images when reading, message positions when indexing): depth and
        color paired by
        the rule of every reader (:func:`~pcdcodec.ros.bagindex.pair_in_order`: each image
        used once, within ``max_difference``), the images left without a partner counted in
        ``stats``. Without color, every depth frame."""
        if self.color_topic is None:
            pairs: Iterator[tuple[int, Any, Any, int | None]] = (
                (stamp, item, None, None) for is_depth, stamp, item in images if is_depth
            )
        else:
            pairs = pair_in_order(images, self.max_difference, stats)
        return itertools.islice(pairs, self.max_frames)

    # -- segments: a frame index, and reading a stretch of frames on its own -------------

    def frame_index(self) -> FrameIndex:
        """Every frame's timestamp and the depth and color messages it is made of, from one
        pass that reads each image message's header stamp but decodes no image (see
        :meth:`pcdcodec.sources.rosbag.RosbagSource.frame_index` for the columns). Kept."""

        from ..ros import bagindex as _bagindex

        if self._index is not None:
            return self._index
        with self._reader() as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def positions() -> Iterator[tuple[bool, int, Any]]:
                fast = _bagindex.ros1_index_stamps(reader, conns)
                if fast is not None:
                    for conn, t, ns in fast:
                        yield conn.topic == self.depth_topic, ns, (t, ns)
                    return
                for conn, t, raw in self._messages(reader, conns):
                    stamp = _bagindex.ros1_stamp(raw)
                    if stamp is None:
                        where = f"{str(self.path)!r}: {conn.topic}"
                        stamp = _stamp(self._deserialize(raw, conn), where)
                    yield conn.topic == self.depth_topic, stamp, (t, stamp)

            try:
                rows = [
                    (t, d[0], d[1], *(c if c is not None else (-1, -1)))
                    for t, d, c, _ in self._pairs(positions())
                ]
            except PcdcodecError:
                raise
            except Exception as exc:
                raise DecodeError(f"{str(self.path)!r}: the bag is damaged: {exc}") from exc
        self._index = FrameIndex(np.array(rows, dtype=np.int64).reshape(-1, 5), 0)
        return self._index

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Any]:
        """Frames ``start`` to ``stop`` (exclusive): from a later frame than the first, through
        :meth:`frame_index` and :meth:`frames_at`, so the frames before are not read."""
        import itertools

        if start < 0 or (stop is not None and stop < 0):
            raise InputError(
                f"{str(self.path)!r}: frames start and stop must be at least 0, got {start}, {stop}"
            )
        if start == 0:
            return itertools.islice(iter(self), stop)
        return self.frames_at(self.frame_index().slice(start, stop))

    def frames_at(self, index: FrameIndex) -> Iterator[Any]:
        """The frames of a :meth:`frame_index` slice: only the messages logged between its
        first and last message are read (the bag's chunk index skips to them), and only the
        listed ones decoded. Raises :class:`~pcdcodec.DecodeError` when a listed message is
        missing (the index is another bag's)."""

        from ..frame import Frame as RGBDFrame
        from ..ros import bagindex as _bagindex

        rows = _bagindex.check_rows(index.rows)
        if rows.shape[0] == 0:
            return
        color = self.color_topic is not None
        lo, hi = _bagindex.window(rows, color)
        with self._reader() as reader:
            conns = [c for c in reader.connections if c.topic in self._image_topics()]

            def messages() -> Iterator[tuple[bool, int, int, Any]]:
                for conn, t, raw in self._messages(reader, conns, start=lo, stop=hi):
                    stamp = _bagindex.ros1_stamp(raw)
                    if stamp is None:
                        where = f"{str(self.path)!r}: {conn.topic}"
                        stamp = _stamp(self._deserialize(raw, conn), where)
                    yield conn.topic == self.depth_topic, t, stamp, (conn, raw)

            def decode(is_depth: bool, item: tuple[Any, bytes]) -> Any:
                return self._decode(item[0], item[1], is_depth)[1]

            where = repr(str(self.path))
            for t, depth, rgb, color_t in _bagindex.read_rows(
                rows, index.first, color, messages(), decode, where
            ):
                yield RGBDFrame(rgb, depth, t, color_timestamp_ns=color_t)


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
