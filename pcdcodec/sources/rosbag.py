"""ROS 1 bags and ROS 2 bags (sqlite3 or mcap storage) as a :class:`Source`, read with rosbags.

No ROS installation is needed. The bag is streamed: messages are read one at a time in bag
order, color and depth are paired by header stamp with :class:`pcdcodec.sync.Synchronizer`, so
memory stays bounded however large the bag.

Two kinds of camera data are read:

* **images**: a depth topic (``sensor_msgs/Image`` in 16UC1, mono16 or 32FC1, or a
  ``CompressedImage`` holding a 16-bit PNG or image_transport's compressedDepth) and optionally a
  color topic (``Image`` in rgb8, bgr8, rgba8, bgra8 or mono8, or a JPEG/PNG ``CompressedImage``),
  with the camera from a ``sensor_msgs/CameraInfo`` topic;
* **organized point clouds** (``sensor_msgs/PointCloud2``, one point per pixel): depth is each
  point's z as float32 metres, bit for bit, color the packed ``rgb``/``rgba`` field; the camera
  comes from a CameraInfo topic when the bag has one, else it is fitted to the cloud.

Topics are chosen automatically by the rules of :mod:`pcdcodec.ros.topics` (see
:meth:`RosbagSource.candidates` and ``docs/ingest.md``); ``depth_topic``, ``color_topic``,
``info_topic`` and ``cloud_topic`` override the choice. The source reads the frames (one pass,
or a stretch of them through :meth:`~RosbagSource.frame_index`) and passes encoded video
through (:meth:`~RosbagSource.encoded_frames`); message payloads are read by
:mod:`pcdcodec.ros.messages`.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, PcdcodecError
from ..frame import Frame
from ..geometry.camera import as_intrinsics
from ..ros import bagfile, bagindex, clouds, tf, topics
from ..ros import messages as rm
from ..ros.bagfile import MCAP_MAGIC as MCAP_MAGIC
from ..ros.bagfile import ROS1_MAGIC as ROS1_MAGIC
from ..ros.bagfile import SQLITE_MAGIC as SQLITE_MAGIC
from ..ros.kept import TopicFilter
from ..ros.topics import (
    CAMERA_INFO,
    COMPRESSED,
    IMAGE,
    POINT_CLOUD,
    TopicCandidate,
)
from ..sync import MAX_DIFFERENCE, as_max_difference
from ._bag_color import color_camera
from ._bag_envelope import BagEnvelopes
from ._bag_video import BagVideo
from .base import FrameIndex, InputStream, Source, read_magic, register_source, streams_by_name

__all__ = ["RosbagSource", "TopicCandidate", "open_bag"]


def _is_bag(path: Path) -> bool:
    if path.is_dir():
        return bagfile.is_bag_folder(path)
    return bagfile.is_bag_head(read_magic(path, 64))


def _open(path: Path, **options: Any) -> Source:
    return RosbagSource(path, **options)


register_source(
    "rosbag",
    _is_bag,
    _open,
    "a ROS 1 bag, or a ROS 2 bag folder or .db3/.mcap file (images, or an organized PointCloud2)",
)


def open_bag(path: str | os.PathLike[str], **options: Any) -> RosbagSource:
    """Open a ROS 1 or ROS 2 bag as a source (the options of :class:`RosbagSource`)."""
    return RosbagSource(path, **options)


def _encoding(msg: Any) -> str:
    return str(getattr(msg, "encoding", getattr(msg, "format", "")))


def _add_time(exc: PcdcodecError, what: str) -> None:
    """Say which message an error is about, keeping its class."""
    if exc.args and isinstance(exc.args[0], str) and what not in exc.args[0]:
        exc.args = (f"{exc.args[0]} ({what})", *exc.args[1:])


#: A frame's images as a reader's passes give them: color (or None), depth, the frame's time
#: (the depth's), and the color image's own time where it has one apart (else None).
_Images = tuple[Any, Any, int, int | None]


@dataclass
class _Stats(bagindex.PairStats):
    frames: int = 0


class RosbagSource(BagVideo, BagEnvelopes, Source):
    """A ROS 1 or ROS 2 bag read as RGB-D frames.

    Options (all keyword-only):

    * ``depth_topic``, ``color_topic``, ``info_topic``, ``cloud_topic``: override the automatic
      topic choice (``color_topic=""`` records depth only);
    * ``intrinsics``, ``depth_scale``: override what the bag says (depth scale defaults to
      1000 per metre for 16UC1/mono16 and 1 for 32FC1 and clouds, whose depth is metres);
    * ``max_difference``: the largest color/depth stamp difference paired, ns (20 ms,
      :data:`pcdcodec.sync.MAX_DIFFERENCE`, the default of every reader);
    * ``max_frames``: stop after this many frames;
    * ``depth_to_color``: the 4 × 4 depth-to-color transform (metres, or a text file of its 16
      numbers) where the color topic's own CameraInfo shows a camera apart from the depth and
      the bag's tf does not place one in the other (see :meth:`_setup_color_camera`);
    * ``keep_topics`` (default true), ``include_topics``, ``exclude_topics``: which of the other
      topics a recording keeps as they came (:meth:`kept_topics`; shell-style patterns), and
      the depth and color topics' own messages, kept exactly (``docs/format.md``).

    After iterating, :attr:`dropped` counts the images that found no partner and
    :attr:`out_of_order` those whose stamp did not increase. Raises
    :class:`~pcdcodec.InputError` for a bag without a depth topic, an unsupported encoding, an
    unorganized cloud, a CameraInfo whose size disagrees with the images, or depth and color of
    different sizes; :class:`~pcdcodec.DecodeError` for a damaged or truncated bag.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        depth_topic: str | None = None,
        color_topic: str | None = None,
        info_topic: str | None = None,
        cloud_topic: str | None = None,
        intrinsics: Any = None,
        depth_scale: float | None = None,
        max_difference: int = MAX_DIFFERENCE,
        max_frames: int | None = None,
        cloud_depth: str = "auto",
        depth_to_color: Any = None,
        keep_topics: bool = True,
        include_topics: Sequence[str] | str | None = None,
        exclude_topics: Sequence[str] | str | None = None,
    ) -> None:
        self.path = Path(path)
        self.topic_filter = TopicFilter.of(include_topics, exclude_topics, keep_topics)
        if cloud_depth not in ("auto", "float32"):
            raise InputError(f"cloud_depth must be 'auto' or 'float32', got {cloud_depth!r}")
        self.cloud_depth = cloud_depth
        self._cloud_units: clouds.DepthUnits | None = None  # the cloud's z as uint16 units
        if max_frames is not None and max_frames < 1:
            raise InputError(f"max_frames must be at least 1, got {max_frames}")
        self.max_frames = max_frames
        self.max_difference = as_max_difference(max_difference)
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self._layouts = clouds.LayoutCache()
        self._shape: tuple[int, int] | None = None
        self._depth_dtype: np.dtype[Any] = np.dtype(np.uint16)
        self._index: FrameIndex | None = None
        self._tf: Any = None  # the camera's poses from /tf (False: none); read on first use
        self._tf_extrinsics = False  # whether tf gave the color camera's extrinsics
        self._reader, self._tmp = bagfile.open_reader(self.path)
        try:
            self._setup(depth_topic, color_topic, info_topic, cloud_topic, intrinsics, depth_scale)
            if self.mode == "images":
                self._setup_color_camera(depth_topic is not None, depth_to_color)
        except BaseException:
            self.close()
            raise

    # -- opening: the topics and the camera --------------------------------------------------

    def _new_stats(self) -> _Stats:
        return _Stats()

    def _first(self, conn: Any) -> Any:
        try:
            for c, _, raw in self._reader.messages(connections=[conn]):
                return self._reader.deserialize(raw, c.msgtype)
        except PcdcodecError:
            raise
        except Exception as exc:
            raise bagfile.bag_error(exc, self.path) from exc
        return None

    def candidates(self) -> list[TopicCandidate]:
        """Every topic with its role (depth, color, info, cloud, video) from its first message
        (:func:`pcdcodec.ros.topics.classify`)."""
        return [
            topics.classify(c.topic, c.msgtype, c.msgcount, partial(self._first, c))
            for c in self._reader.connections
        ]

    def _conn(self, topic: str, what: str) -> Any:
        conns = [c for c in self._reader.connections if c.topic == topic]
        if not conns:
            names = sorted({c.topic for c in self._reader.connections})
            raise InputError(
                f"bag {str(self.path)!r} has no {what} topic {topic!r}; it has {names}"
            )
        return conns[0]

    def _setup(
        self,
        depth_topic: str | None,
        color_topic: str | None,
        info_topic: str | None,
        cloud_topic: str | None,
        intrinsics: Any,
        depth_scale: float | None,
    ) -> None:
        """Choose the topics (each given one checked), then the camera, then the metadata."""
        self.stats = _Stats()
        self.notes: list[str] = []
        self.distortion_model = ""
        self.distortion: list[float] = []
        self.fit_residual: float | None = None
        self.info_topic: str | None = None
        self.color_topic: str | None = None
        self.depth_topic: str | None = None
        self.cloud_topic: str | None = None
        self._info_camera: Any = None  # the depth camera the bag's CameraInfo gives

        conns = self._reader.connections
        self._streams = streams_by_name((c.topic, c.msgtype, c.msgcount) for c in conns)
        cands = self.candidates()
        self.mode = topics.choose_mode(cands, depth_topic, cloud_topic, str(self.path))
        first_pts = None
        if self.mode == "cloud":
            if cloud_topic is None:
                cloud_topic = topics.choose_cloud(cands)
            first_pts = self._setup_cloud(cloud_topic, depth_scale)
            anchor, size = cloud_topic, (self._layout.width, self._layout.height)
        else:
            if depth_topic is None:
                depth_topic = topics.choose_depth(cands)
            size = self._setup_depth(cands, depth_topic, depth_scale)
            self._setup_color(cands, color_topic, size)
            anchor = depth_topic
        if info_topic is None:
            info_topic = topics.choose_info(cands, anchor)
        self._setup_camera(info_topic, intrinsics, anchor, size, first_pts)
        self.metadata = self._metadata()

    def _setup_cloud(self, cloud_topic: str, depth_scale: float | None) -> Any:
        """Read the cloud topic's first cloud: its layout, whether its z values are whole
        depth units (:func:`~pcdcodec.ros.clouds.find_units`); returns its points."""
        conn = self._conn(cloud_topic, "cloud")
        if conn.msgtype != POINT_CLOUD:
            raise InputError(f"cloud topic {cloud_topic!r} is a {conn.msgtype}, not PointCloud2")
        first = self._first(conn)
        if first is None:
            raise InputError(f"cloud topic {cloud_topic!r} has no messages")
        self._layout = self._layouts.get(first, cloud_topic)
        self.cloud_topic = cloud_topic
        self._depth_conn = conn
        self._color_conn = None
        self.has_color = self._layout.color is not None
        self.depth_scale = 1.0 if depth_scale is None else float(depth_scale)
        first_pts = clouds.cloud_points(first, self._layout, cloud_topic)
        if self.cloud_depth == "auto" and depth_scale is None:
            self._cloud_units = clouds.find_units(first_pts["z"].astype(np.float32))
            if self._cloud_units is not None:
                self.depth_scale = scale = self._cloud_units.scale
                self.notes.append(
                    f"cloud z values are whole 1/{scale:g} m steps: stored as uint16 units at "
                    f"depth scale {scale:g} (every z rebuilds bit for bit)"
                )
        self._depth_dtype = np.dtype(np.uint16 if self._cloud_units is not None else np.float32)
        return first_pts

    def _setup_depth(
        self, cands: Sequence[TopicCandidate], depth_topic: str, depth_scale: float | None
    ) -> tuple[int, int]:
        """Check the depth topic; its depth type and scale. Returns its images' size."""
        conn = self._conn(depth_topic, "depth")
        cand = {c.topic: c for c in cands}[depth_topic]
        if conn.msgtype not in (IMAGE, COMPRESSED):
            raise InputError(
                f"depth topic {depth_topic!r} is a {conn.msgtype}, expected Image or "
                "CompressedImage"
            )
        topics.check_depth(cand)
        self.depth_topic = depth_topic
        self._depth_conn = conn
        float_depth = cand.encoding.startswith("32FC1")
        self._depth_dtype = np.dtype(np.float32 if float_depth else np.uint16)
        self.depth_scale = (
            float(depth_scale) if depth_scale is not None else (1.0 if float_depth else 1000.0)
        )
        return cand.width, cand.height

    def _setup_color(
        self, cands: Sequence[TopicCandidate], color_topic: str | None, size: tuple[int, int]
    ) -> None:
        """The color topic: none when ``color_topic`` is ``""`` or ``"none"``, else the given
        one, checked, or the one :func:`~pcdcodec.ros.topics.choose_color` picks."""
        assert self.depth_topic is not None
        width, height = size
        if color_topic is not None and color_topic.strip().lower() in ("", "none"):
            color_topic = ""
        elif color_topic is None:
            color_topic = topics.choose_color(cands, self.depth_topic, width, height)
            if color_topic is None:
                self.notes.append(
                    f"no color topic of the depth's size {width}x{height}, nor one with a "
                    "CameraInfo of its own: depth only"
                )
        self._color_conn = None
        if color_topic:
            cconn = self._conn(color_topic, "color")
            cand = {c.topic: c for c in cands}[color_topic]
            apart = topics.choose_color_info(cands, color_topic, self.depth_topic, None)
            topics.check_color(cand, self.depth_topic, width, height, apart is not None)
            self._color_conn = cconn
            self.color_topic = color_topic
        self.has_color = self._color_conn is not None

    def _setup_camera(
        self,
        info_topic: str | None,
        intrinsics: Any,
        anchor: str,
        size: tuple[int, int],
        first_pts: Any,
    ) -> None:
        """The camera: given, or from the CameraInfo topic, or fitted to the first cloud."""
        width, height = size
        if intrinsics is not None:
            self.intrinsics = as_intrinsics(intrinsics, "intrinsics", width, height)
        elif info_topic:
            self._read_camera_info(info_topic, anchor, size)
        elif self.mode == "cloud":
            self.intrinsics, self.fit_residual = clouds.fit_intrinsics(first_pts, anchor)
            self.notes.append(
                f"no camera info: intrinsics fitted to the cloud, residual "
                f"{self.fit_residual:.3g} px"
            )
        else:
            self.intrinsics = None  # describe() asks for intrinsics while none are set
        self._shape = (height, width)
        if self.intrinsics is not None and self.intrinsics.shape != (height, width):
            raise InputError(
                f"intrinsics are for {self.intrinsics.width}x{self.intrinsics.height} but "
                f"{anchor!r} is {width}x{height}"
            )

    def _read_camera_info(self, info_topic: str, anchor: str, size: tuple[int, int]) -> None:
        """The camera and its distortion from the first message of ``info_topic``, which must
        be for images of ``size`` (those of ``anchor``)."""
        width, height = size
        iconn = self._conn(info_topic, "camera info")
        if iconn.msgtype != CAMERA_INFO:
            raise InputError(f"info topic {info_topic!r} is a {iconn.msgtype}, not CameraInfo")
        msg = self._first(iconn)
        if msg is None:
            raise InputError(f"camera info topic {info_topic!r} has no messages")
        if (int(msg.width), int(msg.height)) != (width, height):
            raise InputError(
                f"camera info topic {info_topic!r} is for {msg.width}x{msg.height} images, "
                f"but {anchor!r} is {width}x{height}"
            )
        self.intrinsics, self.distortion_model, self.distortion = rm.camera_info(msg, info_topic)
        self._info_camera = self.intrinsics
        self.info_topic = info_topic
        if any(self.distortion):
            self.notes.append(
                f"camera info has {self.distortion_model} distortion {self.distortion}: kept "
                "in the recording's metadata, not applied to the points"
            )

    def _setup_color_camera(self, depth_given: bool, given: Any) -> None:
        """The color camera: registered to depth, or apart with its ``depth_to_color``
        (:func:`~pcdcodec.sources._bag_color.color_camera`); a camera apart whose transform is
        unknown leaves a problem that reading the frames raises (``info`` still describes
        the bag)."""
        cands = self.candidates()
        assert self.depth_topic is not None
        note = topics.depth_choice_note(cands, self.depth_topic, given=depth_given)
        if note:
            self.notes.append(note)
        self._color_problem: str | None = None
        if self._color_conn is None:
            return
        found = color_camera(
            cands, (self._depth_conn, self._color_conn), self.info_topic,
            self._info_camera or self.intrinsics, given,
            lambda topic: self._first(self._conn(topic, "camera info")),
            self._extrinsics,
        )  # fmt: skip
        if found is not None:
            self.color_intrinsics, self.depth_to_color, note, self._color_problem = found
            self.notes.append(note)
            # The color camera's own CameraInfo is read, and so recorded, not left out.
            info = topics.choose_color_info(
                cands, self._color_conn.topic, self._depth_conn.topic, self.info_topic
            )
            if info:
                self.metadata["ros_color_info_topic"] = info

    def _extrinsics(self, source: str, target: str) -> tuple[Any, str]:
        """:func:`pcdcodec.ros.tf.frame_to_frame` over this bag; ``/tf`` and ``/tf_static``
        count as recorded once they gave the color camera's extrinsics."""
        found = tf.frame_to_frame(self._messages, self._reader.connections, source, target)
        self._tf_extrinsics = found[0] is not None
        return found

    def _check_color_camera(self) -> None:
        if getattr(self, "_color_problem", None):
            raise InputError(f"bag {str(self.path)!r}: {self._color_problem}")

    def _metadata(self) -> dict[str, str]:
        """The recording metadata: the bag, the topics read, and how the camera was found."""
        metadata = {
            "source": "rosbag",
            "bag": self.path.name,
            **bagfile.bag_kind(self.path, bool(self._reader.is2)),  # given back as it came
            **{
                f"ros_{k}": v
                for k, v in (
                    ("depth_topic", self.depth_topic),
                    ("color_topic", self.color_topic),
                    ("info_topic", self.info_topic),
                    ("cloud_topic", self.cloud_topic),
                )
                if v
            },
        }
        if self.distortion_model:
            metadata["distortion_model"] = self.distortion_model
            metadata["distortion"] = json.dumps(self.distortion)
        if self.fit_residual is not None:
            metadata["intrinsics_fit_residual_px"] = repr(self.fit_residual)
        return metadata

    # -- the Source protocol ------------------------------------------------------------------

    def input_streams(self) -> list[InputStream]:
        """Every topic of the bag, with its type and message count from the bag's index."""
        return list(self._streams)

    def recorded_streams(self) -> set[str]:
        """The topics read (depth or cloud, color or video, camera info, and any other topic
        the recording's metadata names as read), and ``/tf`` and ``/tf_static``, read for the
        camera's poses and a color camera's extrinsics: once read, they count as left out when
        they gave neither."""
        topics = {self.depth_topic, self.color_topic, self.info_topic, self.cloud_topic}
        topics |= {
            v for k, v in self.metadata.items() if k.startswith("ros_") and k.endswith("_topic")
        }
        if self._tf is not False or self._tf_extrinsics:
            topics |= {s.name for s in self._streams if "/" + s.name.lstrip("/") in tf.TF_TOPICS}
        return {t for t in topics if t}

    @property
    def dropped(self) -> dict[str, int]:
        """Images dropped for lack of a partner so far, by stream."""
        return {"color": self.stats.dropped_color, "depth": self.stats.dropped_depth}

    @property
    def out_of_order(self) -> int:
        """Messages skipped because their stamp did not increase."""
        return int(self.stats.out_of_order)

    def __length_hint__(self) -> int:
        n = int(self._depth_conn.msgcount)
        return min(n, self.max_frames) if self.max_frames else n

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out.update(
            {
                "mode": self.mode,
                "depth_topic": self.depth_topic,
                "color_topic": self.color_topic,
                "info_topic": self.info_topic,
                "cloud_topic": self.cloud_topic,
                "dropped": self.dropped,
                "out_of_order": self.out_of_order,
                "notes": list(self.notes)
                + (["no camera info topic: pass intrinsics"] if self.intrinsics is None else []),
            }
        )
        if self.fit_residual is not None:
            out["intrinsics_fit_residual_px"] = self.fit_residual
        return out

    def _stamp(self, msg: Any, log_time: int, topic: str) -> int:
        """A message's time: its header stamp, or its log time where the stamp is 0 (unset).
        Every path (iteration, :meth:`frame_index`, :meth:`frames_at`) reads stamps through
        :func:`~pcdcodec.ros.bagindex.stamp_value`, so they agree."""
        ns = rm.stamp_ns(msg, topic, ros1=not self._reader.is2)
        return ns if ns > 0 else int(log_time)

    def _decode(self, msg: Any, conn: Any, role: str, ts: int) -> Any:
        """An image message as depth or color, checked against the camera's size before it is
        decoded; errors name the topic and the message's time."""
        shape = self._shape
        if role == "color" and self.color_intrinsics is not None:
            shape = self.color_intrinsics.shape  # a color camera apart: its own size
        try:
            if conn.msgtype == IMAGE:
                out = rm.decode_image(msg, role, conn.topic, shape)
            else:
                out = rm.decode_compressed(msg, role, conn.topic, shape)
        except PcdcodecError as exc:
            _add_time(exc, f"message at {ts} ns")
            raise
        if role == "depth" and out.dtype != self._depth_dtype:
            raise InputError(
                f"depth topic {conn.topic!r}: the message at {ts} ns holds {out.dtype} depth "
                f"({_encoding(msg)!r}), the first message {self._depth_dtype}; expected one "
                "depth type in a topic"
            )
        return out

    def __iter__(self) -> Iterator[Any]:
        self._check_color_camera()
        self.stats = _Stats()
        if self.mode == "cloud":
            frames: Iterator[Any] = self._cloud_frames()
        elif self._color_conn is None:
            frames = self._depth_frames()
        else:
            frames = self._paired_frames()
        return self._emit(frames, self.max_frames)

    def _emit(self, frames: Iterator[_Images], limit: int | None) -> Iterator[Any]:
        """Frames from ``(color, depth, depth stamp, color stamp)``: the frame at the depth's
        stamp, each image keeping its own."""
        shape = self._shape
        assert shape is not None  # set when the source opens
        for color, depth, ts, color_ts in frames:
            if depth.shape != shape:
                topic = self.depth_topic or self.cloud_topic
                raise InputError(
                    f"topic {topic!r}: the frame at {ts} ns is {depth.shape[1]}x{depth.shape[0]}, "
                    f"the first frame {shape[1]}x{shape[0]}"
                )
            self.stats.frames += 1
            yield Frame(color, depth, ts, pose=self._pose(ts), color_timestamp_ns=color_ts)
            if limit is not None and self.stats.frames >= limit:
                return

    def _pose(self, ts: int) -> Any:
        """The camera-to-world pose at stamp ``ts`` from the bag's /tf and /tf_static (see
        ``_tf``), or ``None``."""
        if self._tf is None:
            frame = ""
            if any(tf.is_tf(c) for c in self._reader.connections):
                first = self._first(self._depth_conn)
                frame = str(first.header.frame_id) if first is not None else ""
            found = tf.read_tf_poses(self._messages, self._reader.connections, frame, self.notes)
            self._tf = found if found is not None else False
        return self._tf.at(ts) if self._tf else None

    def _messages(self, conns: list[Any]) -> Iterator[tuple[Any, int, Any]]:
        try:
            for c, t, raw in self._reader.messages(connections=conns):
                msg = self._reader.deserialize(raw, c.msgtype)
                self._env_read(c, t, raw, msg)
                yield c, t, msg
        except PcdcodecError:
            raise
        except Exception as exc:
            raise bagfile.bag_error(exc, self.path) from exc

    def _in_order(self, conn: Any) -> Iterator[tuple[Any, int]]:
        """The messages of ``conn`` with their stamps, skipping (and counting) those whose
        stamp does not increase."""
        last = -1
        for c, t, msg in self._messages([conn]):
            ts = self._stamp(msg, t, c.topic)
            if ts <= last:
                self.stats.out_of_order += 1
                self._env_left(True, ts, msg)
                continue
            last = ts
            yield msg, ts

    def _depth_frames(self) -> Iterator[_Images]:
        for msg, ts in self._in_order(self._depth_conn):
            depth = self._decode(msg, self._depth_conn, "depth", ts)
            self._env_frame(ts, (msg, depth, "depth"))
            yield None, depth, ts, None

    def _paired_frames(self) -> Iterator[_Images]:
        dtopic = self._depth_conn.topic
        messages = (
            (conn.topic == dtopic, self._stamp(msg, t, conn.topic), msg)
            for conn, t, msg in self._messages([self._depth_conn, self._color_conn])
        )
        pairs = bagindex.pair_in_order(messages, self.max_difference, self.stats, self._env_left)
        for dts, dmsg, cmsg, cts in pairs:
            yield self._pair(cmsg, dmsg, dts, cts)

    def _pair(self, cmsg: Any, dmsg: Any, dts: int, cts: int | None) -> _Images:
        cconn, dconn = self._color_conn, self._depth_conn
        assert cconn is not None
        color = self._decode(cmsg, cconn, "color", dts)
        depth = self._decode(dmsg, dconn, "depth", dts)
        if self.color_intrinsics is None and color.shape[:2] != depth.shape:
            raise InputError(
                f"color topic {cconn.topic!r} is {color.shape[1]}x{color.shape[0]} but "
                f"depth topic {dconn.topic!r} is {depth.shape[1]}x{depth.shape[0]} "
                f"at {dts} ns"
            )
        self._env_frame(dts, (dmsg, depth, "depth"), (cmsg, color, "color"))
        return color, depth, dts, cts

    def _cloud_frames(self) -> Iterator[_Images]:
        for msg, ts in self._in_order(self._depth_conn):
            yield self._cloud_frame(msg, ts)

    def _cloud_frame(self, msg: Any, ts: int) -> _Images:
        topic = self._depth_conn.topic
        first = self._layout
        if (int(msg.width), int(msg.height)) != (first.width, first.height):
            raise InputError(
                f"cloud topic {topic!r}: cloud at {ts} ns is {msg.width}x{msg.height}, earlier "
                f"clouds {first.width}x{first.height}"
            )
        try:
            layout = self._layouts.get(msg, topic)
            if (layout.color is None) != (first.color is None):
                raise InputError(
                    f"cloud topic {topic!r}: the cloud {'has' if layout.color else 'lacks'} a "
                    f"color field, the first cloud {'has' if first.color else 'lacks'} one"
                )
            z, rgb, _ = clouds.cloud_to_rgbd(msg, layout, topic)
        except PcdcodecError as exc:
            _add_time(exc, f"cloud at {ts} ns")
            raise
        if self._cloud_units is not None:
            units = self._cloud_units.of(z)
            if units is None:
                raise InputError(
                    f"cloud topic {topic!r}: the cloud at {ts} ns has z values that are not "
                    f"whole 1/{self.depth_scale:g} m steps, unlike the first cloud; open the "
                    "bag with cloud_depth='float32' to keep z as float32 metres"
                )
            return rgb, units, ts, None
        with np.errstate(invalid="ignore"):
            z[~np.isfinite(z)] = np.nan
        return rgb, z, ts, None

    # -- reading a stretch of frames without reading the bag from the top --------------------

    def _raw(
        self, conns: list[Any], start: int | None = None, stop: int | None = None
    ) -> Iterator[tuple[Any, int, bytes]]:
        """Serialised messages of ``conns`` with log times in ``[start, stop)``, not decoded."""
        try:
            yield from self._reader.messages(connections=conns, start=start, stop=stop)
        except PcdcodecError:
            raise
        except Exception as exc:
            raise bagfile.bag_error(exc, self.path) from exc

    def _raw_stamp(self, raw: bytes, conn: Any, log_time: int) -> int:
        """The header stamp of a serialised message, read from its first bytes (every message
        read here starts with a std_msgs/Header), or the log time where the stamp is 0."""
        where = f"topic {conn.topic!r}"
        ns = bagindex.cdr_stamp(raw, where) if self._reader.is2 else bagindex.ros1_stamp(raw, where)
        if ns is None:
            try:
                msg = self._reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                raise bagfile.bag_error(exc, self.path) from exc
            return self._stamp(msg, log_time, conn.topic)
        return ns if ns > 0 else int(log_time)

    def frame_index(self) -> FrameIndex:
        """Every frame's timestamp and the messages it is made of, from one pass over the bag
        that reads each depth and color message's header stamp but decodes no image (in an
        uncompressed ROS 1 bag, only the first bytes of each message are read, through the
        bag's index).

        Rows are ``(timestamp, depth log time, depth stamp, color log time, color stamp)`` (the
        color columns -1 without color), in the order iteration yields the frames: color and
        depth are paired here by the same rule and state as when iterating, so the index lists
        exactly the frames :meth:`__iter__` gives. Built once and kept.
        """
        self._check_color_camera()
        if self._index is None:
            self._index = self._build_index()
        return self._index

    def _stamps(self, conns: list[Any]) -> Iterator[tuple[Any, int, int]]:
        """``(connection, log time, stamp)`` of each message of ``conns``, in bag order: from
        the first bytes of each message (uncompressed ROS 1 bags: read through the bag's index,
        a few kilobytes per message), else from the messages read whole."""
        readers = getattr(self._reader, "readers", [])
        if not self._reader.is2 and len(readers) == 1:
            fast = bagindex.ros1_index_stamps(readers[0], conns)
            if fast is not None:
                for conn, t, ns in fast:
                    yield conn, t, ns if ns > 0 else t
                return
        for conn, t, raw in self._raw(conns):
            yield conn, t, self._raw_stamp(raw, conn, t)

    def _build_index(self) -> FrameIndex:
        dconn, cconn = self._depth_conn, self._color_conn
        conns = [dconn] if cconn is None else [dconn, cconn]
        stamps = ((c.topic == dconn.topic, t, ts) for c, t, ts in self._stamps(conns))
        rows = bagindex.index_rows(stamps, cconn is not None, self.max_difference, self.max_frames)
        return FrameIndex(rows, 0)

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Any]:
        """Frames ``start`` to ``stop`` (exclusive). From the top this is plain iteration;
        from a later frame the bag is indexed first (:meth:`frame_index`) and only the
        messages of those frames are read (:meth:`frames_at`)."""
        if start < 0 or (stop is not None and stop < 0):
            raise InputError(f"frames start and stop must be at least 0, got {start}, {stop}")
        if start == 0:
            return itertools.islice(iter(self), stop)
        return self.frames_at(self.frame_index().slice(start, stop))

    def frames_at(self, index: FrameIndex) -> Iterator[Any]:
        """The frames of a :meth:`frame_index` slice, found by their messages' log times.

        Only messages logged between the slice's first and last message are read (ROS 1 and
        MCAP bags skip to them through their chunk index, sqlite3 through its time index), and
        only the listed ones are decoded, so reading segment k of a bag costs the same
        whatever k is. Raises :class:`~pcdcodec.DecodeError` when a listed message is not in
        the bag (the index was made from another bag, or the bag changed).
        """
        self._check_color_camera()
        rows = bagindex.check_rows(index.rows)
        self.stats = _Stats()
        return self._emit(self._indexed(rows, index.first), None)

    def _indexed(self, rows: Any, first: int) -> Iterator[_Images]:
        if rows.shape[0] == 0:
            return
        dconn, cconn = self._depth_conn, self._color_conn
        paired = cconn is not None
        lo, hi = bagindex.window(rows, paired)
        conns = [dconn, cconn] if paired else [dconn]
        messages = (
            (conn.topic == dconn.topic, t, self._raw_stamp(raw, conn, t), (raw, conn))
            for conn, t, raw in self._raw(conns, lo, hi)
        )

        def decode(_: bool, item: tuple[bytes, Any]) -> Any:
            try:
                return self._reader.deserialize(item[0], item[1].msgtype)
            except Exception as exc:
                raise bagfile.bag_error(exc, self.path) from exc

        where = f"bag {str(self.path)!r}"
        for ts, dmsg, cmsg, cts in bagindex.read_rows(rows, first, paired, messages, decode, where):
            if paired:
                yield self._pair(cmsg, dmsg, ts, cts)
            elif self.mode == "cloud":
                yield self._cloud_frame(dmsg, ts)
            else:
                yield None, self._decode(dmsg, dconn, "depth", ts), ts, None

    def close(self) -> None:
        reader = getattr(self, "_reader", None)
        if reader is not None:
            with contextlib.suppress(Exception):
                reader.close()
            self._reader = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
