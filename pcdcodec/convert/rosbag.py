"""Recordings (or any source) back into ROS 1 and ROS 2 bags that ``rosbag play`` and
``ros2 bag play`` accept.

:func:`export_bag` writes, per frame, each message at its own recorded stamp (as both the header
stamp and the bag time): the depth image and its camera info at the depth image's own time, the
color image and its camera info at the color image's (``Frame.depth_timestamp_ns``,
``Frame.color_timestamp_ns``: they differ where the input stamped them apart, as TUM's lists
do). The cloud, in the depth camera's pixels, and ``/tf`` are at the depth's time too: a
frame's pose is the camera's at its depth image (TUM's trajectory is sampled there, and a bag
read back looks its poses up there). Messages go into the bag in time order (a
message stamped before one already written, which only inputs whose stamps go back in time
give, keeps its header stamp and is logged at the time of the one before):

* ``<ns>/depth/image_raw``: ``sensor_msgs/Image``, 16UC1 millimetres when the depth scale is 1000
  per metre, else 32FC1 metres; or, with ``compressed_depth``, image_transport's
  ``<ns>/depth/image_raw/compressedDepth`` (``"16UC1; compressedDepth png"``);
* ``<ns>/color/image_raw``: ``sensor_msgs/Image`` rgb8;
* ``<ns>/depth/camera_info`` and ``<ns>/color/camera_info``: ``sensor_msgs/CameraInfo`` with the
  recording's camera (and the distortion its source had, when it was kept);
* where the color camera is apart from the depth camera (the recording has
  ``color_intrinsics`` and ``depth_to_color``), the color images and their CameraInfo (the
  color camera's own, with its distortion) are in the color camera's frame, and one latched
  ``/tf_static`` message at the first frame's stamp places that frame in the depth camera's
  frame (the inverse of ``depth_to_color``); the frames are ``<frame_id>_color`` in
  ``<frame_id>``, or realsense-ros's ``camera_color_optical_frame`` in
  ``camera_depth_optical_frame`` without a ``frame_id``. Otherwise color is registered to the
  depth and every message is in the one frame (``camera_color_optical_frame`` unless given);
* with ``cloud``, ``<ns>/depth_registered/points``: the organized ``sensor_msgs/PointCloud2``
  XYZRGB (x, y, z float32 at bytes 0, 4, 8, packed rgb at 16, 32 bytes per point, NaN for
  pixels without depth), as the paper's broadcast node published it;
* for frames with a pose, ``/tf``: ``tf2_msgs/TFMessage`` with one ``TransformStamped`` from
  ``world`` to the camera frame (the camera-to-world pose), so the trajectory plays in RViz.

A recording of several cameras (:class:`~pcdcodec.RigRecording`) is written with each camera's
topics under its own namespace (``/<name>/depth/image_raw``, ...; each message in the camera's
``frame_id``), every camera's frames in time order, and one latched ``/tf_static`` message at
the first frame's stamp placing each camera frame in the rig frame (its rig pose), and, for a
camera whose color camera is apart from its depth camera, the color frame ``<frame_id>_color``
in the camera frame (the color images and their camera info are in that frame). Frames with a
pose place the rig in ``world`` on ``/tf``.

The messages are built and the bag written by :mod:`pcdcodec.ros.bagwriter`. The bag is written
beside its final name and moved into place when complete. A recording of a ROS bag also gives
back the topics it kept, as they came, and its camera topics under the names the bag had them
(:mod:`pcdcodec.convert.bag_back`, ``docs/bags.md``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_output
from ..errors import InputError
from ..frame import Frame
from ..geometry.projector import Projector
from ..recording.reader import Recording
from ..recording.rig_reader import RigRecording
from ..ros.bagfile import MCAP_MAGIC
from ..ros.bagwriter import BagWriter, InTimeOrder, MessageBuilder
from ..ros.clouds import CLOUD_DTYPE, cloud_array
from ..ros.kept import KeptMessage
from ..ros.messages import compressed_depth_encode
from ..sources.base import Source, open_source
from .bag_back import AS_IT_CAME, FORMATS, STORAGES, BagBack, bag_kind, merge_by_time
from .bag_layout import color_transform, frame_ids, in_time_order, rig_transforms, swap_in

__all__ = ["CLOUD_DTYPE", "cloud_array", "export_bag"]


@dataclass
class _Input:
    frames: Iterator[Frame]
    intrinsics: Any
    depth_scale: float
    metadata: dict[str, str]
    total: int | None
    close: Callable[[], None]
    #: The color camera and the depth-to-color transform, where color is not registered.
    color_intrinsics: Any = None
    depth_to_color: Any = None


def _open(src: Any) -> tuple[Any, Callable[[], None]]:
    """``src`` opened (a recording of one or several cameras, or a source), and how to close
    what was opened here."""
    if not isinstance(src, (str, os.PathLike)):
        return src, lambda: None
    p = Path(src)
    head = b""
    if p.is_file():
        with p.open("rb") as f:
            head = f.read(8)
    if head == MCAP_MAGIC:  # a recording, or a ROS 2 bag (which the reader refuses)
        from ..recording import open as open_recording

        try:
            rec = open_recording(p)
        except Exception:
            rec = None
        if rec is not None:
            return rec, rec.close
    source = open_source(p)
    return source, source.close


def _input(src: Any, intrinsics: Any, depth_scale: float | None) -> _Input:
    if isinstance(src, Recording):
        return _from_recording(src, close=lambda: None)
    if isinstance(src, Source):
        intr = intrinsics if intrinsics is not None else src.intrinsics
        if intr is None:
            raise InputError(
                f"source {str(src.path)!r} has no camera: pass intrinsics to write camera info "
                "and clouds"
            )
        return _Input(
            iter(src),
            intr,
            float(depth_scale if depth_scale is not None else src.depth_scale),
            dict(src.metadata),
            src.frame_count,
            lambda: None,
            src.color_intrinsics,
            src.depth_to_color,
        )
    raise InputError(
        f"export_bag takes a .pcdc path, a Recording, a RigRecording, a Source or a path "
        f"open_source reads, got {type(src).__name__}"
    )


def _from_recording(rec: Any, close: Callable[[], None]) -> _Input:
    return _Input(
        iter(rec),
        rec.intrinsics,
        rec.depth_scale,
        dict(rec.metadata),
        len(rec),
        close,
        rec.color_intrinsics,
        rec.depth_to_color,
    )


def export_bag(
    src: Any,
    out: str | os.PathLike[str],
    *,
    to: str = AS_IT_CAME,
    storage: str | None = None,
    images: bool | None = None,
    camera_info: bool | None = None,
    cloud: bool | None = None,
    compressed_depth: bool | None = None,
    kept: bool = True,
    namespace: str | None = None,
    frame_id: str | None = None,
    intrinsics: Any = None,
    depth_scale: float | None = None,
    max_frames: int | None = None,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Write a recording, or any source, as a ROS 1 bag (a file) or a ROS 2 bag (a folder).

    ``src`` is a ``.pcdc`` path, a :class:`~pcdcodec.Recording`, a :class:`~pcdcodec.Source`, or
    a path :func:`pcdcodec.open_source` reads (so an RGB-D folder can be written straight to a
    PointCloud2 bag: ``export_bag("tum_folder", "cloud.bag", images=False, cloud=True)``).
    ``to`` is ``"rosbag1"``, ``"rosbag2"`` or ``"rosbag"``: the kind the recording's input was
    (ROS 1 for an input that was no bag); ``storage`` (ROS 2) ``"mcap"``, ``"sqlite3"`` or
    ``None``: the input's (else mcap). ``images``, ``camera_info`` (default on) and ``cloud``
    (default off) pick the topics (see the module docstring); ``compressed_depth`` writes depth
    as image_transport compressedDepth (16UC1 depth, depth scale 1000, only). With ``kept``, a
    recording's kept topics are written too, as they came, and the camera topics as the input
    had them (:mod:`pcdcodec.convert.bag_back`; the defaults of ``images``, ``camera_info``,
    ``cloud`` and ``compressed_depth`` follow the input). ``intrinsics``/``depth_scale`` override a
    source's. ``namespace`` is where the topics go (default ``/camera``); of a recording of
    several cameras, each camera goes under ``<namespace>/<name>`` (default: ``/<name>``)
    with ``/tf_static`` placing the cameras in the rig (see the module docstring), and
    ``frame_id``, ``intrinsics`` and ``depth_scale`` cannot be given (each camera has its own).

    Returns a summary: ``frames``, ``path``, ``topics``, ``bytes`` (size on disk) and ``format``,
    of a recording with kept topics ``kept`` (messages per topic), ``camera`` and ``notes``,
    and of a recording of several cameras ``cameras`` (frames written per camera). Raises
    :class:`~pcdcodec.InputError` for an unknown format or storage, an existing output without
    ``overwrite``, or compressedDepth of depth that is not millimetres; nothing is left under
    ``out`` when writing fails.
    """
    if to not in (*FORMATS, AS_IT_CAME):
        raise InputError(
            f"bag format must be one of {', '.join((*FORMATS, AS_IT_CAME))}, got {to!r}"
        )
    if storage not in (*STORAGES, None):
        raise InputError(f"ROS 2 storage must be one of {', '.join(STORAGES)}, got {storage!r}")
    if images is False and not (cloud or camera_info):
        raise InputError("nothing to write: enable images, camera_info or cloud")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    target = Path(out)
    if target.exists() and not overwrite:
        raise InputError(f"{str(target)!r} already exists; pass overwrite=True to replace it")
    opened, close = _open(src)
    try:
        rig = isinstance(opened, RigRecording)
        if namespace is None:
            namespace = "" if rig else "/camera"
        namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
        to, storage = bag_kind(to, storage, dict(getattr(opened, "metadata", {})))
        back = None
        if kept and isinstance(opened, Recording):
            back = BagBack.of(opened, repr(str(opened.path)))
        if back is not None:
            images, camera_info, cloud, compressed_depth = back.defaults(
                images, camera_info, cloud, compressed_depth
            )
        opts = _Options(
            to,
            storage,
            images is not False,
            camera_info is not False,
            bool(cloud),
            bool(compressed_depth),
            namespace,
            frame_id,
        )
        if rig:
            given = [
                k
                for k, v in (
                    ("frame_id", frame_id),
                    ("intrinsics", intrinsics),
                    ("depth_scale", depth_scale),
                )
                if v is not None
            ]
            if given:
                raise InputError(
                    f"{', '.join(given)} cannot be given for a recording of several cameras: "
                    "each camera keeps its own"
                )
            return _write_rig(opened, target, opts, max_frames, progress)
        inp = _input(opened, intrinsics, depth_scale)
        try:
            return _write(inp, target, opts, max_frames, progress, back)
        finally:
            inp.close()
    finally:
        close()


@dataclass(frozen=True)
class _Options:
    """What :func:`export_bag` writes, checked."""

    to: str
    storage: str
    images: bool
    camera_info: bool
    cloud: bool
    compressed_depth: bool
    namespace: str
    frame_id: str | None


class _Export:
    """One bag being written: its topics, its cameras, and the messages of each frame."""

    def __init__(self, inp: _Input, opts: _Options) -> None:
        self.opts = opts
        self.intr = intr = inp.intrinsics
        self.scale = scale = inp.depth_scale
        if opts.compressed_depth and opts.images and scale != 1000.0:
            raise InputError(
                f"compressedDepth holds 16UC1 millimetres; this depth has scale {scale} per "
                "metre (export without compressed_depth to get 32FC1 metres)"
            )
        self.model = inp.metadata.get("distortion_model", "plumb_bob")
        try:
            self.dist = [float(v) for v in json.loads(inp.metadata.get("distortion", "[]"))]
        except (ValueError, TypeError):
            self.dist = []
        if not self.dist and self.model == "plumb_bob":
            self.dist = [0.0] * 5
        color_cam = inp.color_intrinsics
        apart = color_cam is not None and inp.depth_to_color is not None
        fid, color_fid = frame_ids(opts.frame_id or inp.metadata.get("frame_id"), apart=apart)
        self.msgs = MessageBuilder(opts.to == "rosbag2", fid)
        self.projector = (
            Projector(
                intr,
                depth_scale=scale,
                color_intrinsics=color_cam,
                depth_to_color=inp.depth_to_color if color_cam is not None else None,
            )
            if opts.cloud
            else None
        )
        if color_cam is not None:
            # The color image comes from its own camera: its CameraInfo says so.
            color_info = color_cam.to_camera_info()
            self.color_cam = color_cam
            self.color_model = color_info["distortion_model"]
            self.color_dist = list(color_info["D"])
        else:
            self.color_cam, self.color_model, self.color_dist = intr, self.model, self.dist
        #: The frame of the color images and their camera info, and of a color camera apart,
        #: its place in the depth camera's frame (an edge of ``/tf_static``).
        self.color_frame = color_fid
        self.color_msgs = (
            MessageBuilder(opts.to == "rosbag2", color_fid) if color_fid != fid else self.msgs
        )
        self.color_edge = (
            color_transform(fid, color_fid, inp.depth_to_color) if color_fid != fid else None
        )
        ns = opts.namespace
        self.t_depth = f"{ns}/depth/image_raw"
        self.t_cdepth = f"{self.t_depth}/compressedDepth"
        self.t_color = f"{ns}/color/image_raw"
        self.t_dinfo = f"{ns}/depth/camera_info"
        self.t_cinfo = f"{ns}/color/camera_info"
        self.t_cloud = f"{ns}/depth_registered/points"
        self.topics: list[str] = []
        #: Of a camera of a rig: the rig's frame and the camera's rig pose.
        self.rig_pose: tuple[str, Any] | None = None
        #: Topics not written (those a recording kept, written as they came).
        self.skip: set[str] = set()

    def _add(self, bag: BagWriter, topic: str, msgtype: str) -> None:
        if topic in self.skip:
            return
        self.topics.append(topic)
        bag.add(topic, msgtype)

    def add_topics(self, bag: BagWriter, has_color: bool) -> None:
        """The topics the first frame says the bag has (``/tf`` waits for a pose)."""
        opts = self.opts
        if opts.images:
            if opts.compressed_depth:
                self._add(bag, self.t_cdepth, "sensor_msgs/msg/CompressedImage")
            else:
                self._add(bag, self.t_depth, "sensor_msgs/msg/Image")
            if has_color:
                self._add(bag, self.t_color, "sensor_msgs/msg/Image")
        if opts.camera_info:
            for t in (self.t_dinfo, self.t_cinfo) if has_color else (self.t_dinfo,):
                self._add(bag, t, "sensor_msgs/msg/CameraInfo")
        if opts.cloud:
            self._add(bag, self.t_cloud, "sensor_msgs/msg/PointCloud2")

    def write_frame(self, bag: BagWriter, emit: _Emit, frame: Frame) -> None:
        """Every message of one frame, each at its own stamp, handed to ``emit``."""
        opts, msgs, intr, scale = self.opts, self.msgs, self.intr, self.scale
        color, depth, pose = frame.color, frame.depth, frame.pose
        ts = int(frame.timestamp_ns)
        d_ts = int(frame.depth_timestamp_ns if frame.depth_timestamp_ns is not None else ts)
        c_ts = int(frame.color_timestamp_ns if frame.color_timestamp_ns is not None else ts)
        if depth.shape != intr.shape:
            raise InputError(
                f"frame at {ts} ns is {depth.shape[1]}x{depth.shape[0]}, the camera "
                f"{intr.width}x{intr.height}"
            )
        if opts.images:
            if opts.compressed_depth:
                payload = compressed_depth_encode(np.asarray(depth, np.uint16))
                fmt = "16UC1; compressedDepth png"
                emit(self.t_cdepth, d_ts, msgs.compressed(d_ts, payload, fmt))
            elif depth.dtype == np.uint16 and scale == 1000.0:
                emit(self.t_depth, d_ts, msgs.image(d_ts, depth, "16UC1"))
            else:
                if depth.dtype == np.float32 and scale == 1.0:
                    metres = depth
                else:
                    metres = (depth / np.float32(scale)).astype(np.float32)
                    metres[depth == 0] = np.nan  # ROS 32FC1: NaN is no measurement
                emit(self.t_depth, d_ts, msgs.image(d_ts, metres, "32FC1"))
            if color is not None:
                emit(self.t_color, c_ts, self.color_msgs.image(c_ts, color, "rgb8"))
        if opts.camera_info:
            emit(self.t_dinfo, d_ts, msgs.camera_info(d_ts, intr, self.model, self.dist))
            if color is not None:
                info = self.color_msgs.camera_info(
                    c_ts, self.color_cam, self.color_model, self.color_dist
                )
                emit(self.t_cinfo, c_ts, info)
        if self.projector is not None:
            cloud = cloud_array(self.projector, depth, color)
            emit(self.t_cloud, d_ts, msgs.cloud(d_ts, cloud))
        if pose is not None:
            if "/tf" not in bag.conns:
                self._add(bag, "/tf", "tf2_msgs/msg/TFMessage")
            if self.rig_pose is None:
                emit("/tf", d_ts, msgs.tf(d_ts, pose, "world"))
            else:
                # One tree, world -> rig -> camera: the rig's pose through the camera's.
                rig_frame, rig_pose = self.rig_pose
                rig_in_world = np.asarray(pose, np.float64) @ np.linalg.inv(rig_pose)
                edge = ("world", rig_frame, rig_in_world)
                emit("/tf", d_ts, msgs.transforms(d_ts, [edge]))


#: Hands one message (topic, log time in ns, serialized data) to the bag being written.
_Emit = Callable[[str, int, bytes], None]


def _earliest(frame: Frame) -> int:
    """The earliest of a frame's stamps: no message of it is stamped before."""
    stamps = (frame.timestamp_ns, frame.depth_timestamp_ns, frame.color_timestamp_ns)
    return min(int(t) for t in stamps if t is not None)


def _write(
    inp: _Input,
    target: Path,
    opts: _Options,
    max_frames: int | None,
    progress: Callable[[int], None] | None,
    back: BagBack | None = None,
) -> dict[str, Any]:
    export = _Export(inp, opts)
    frames: Iterator[Any] = (("", frame) for frame in inp.frames)
    edges = [] if export.color_edge is None else [export.color_edge]
    if back is not None and back.as_recorded:  # the frames' own messages, as they came
        frames, edges = back.messages(), []
    elif back is not None:  # the frames' messages built anew, named as the input's were
        for key, name in back.names(vars(export), opts.compressed_depth, opts.cloud).items():
            setattr(export, key, name)
        export.skip = back.kept_names
        edges = [] if "/tf_static" in back.kept_names else edges
        frames = merge_by_time(frames, back.messages(), key=_item_time)
    start = _tf_static(opts, edges) if edges else None
    summary, _ = _to_bag(frames, {"": export}, target, opts, max_frames, progress, start, back)
    return summary


def _item_time(item: Any) -> int:
    return item.log_time if isinstance(item, KeptMessage) else _earliest(item[1])


#: What :func:`_to_bag` starts a bag with, at the first frame's earliest stamp (``/tf_static``).
_Start = Callable[[BagWriter, _Emit, int], None]


def _tf_static(opts: _Options, edges: list[tuple[str, str, Any]]) -> _Start:
    """Starting a bag with one latched ``/tf_static`` message of ``edges``."""
    msgs = MessageBuilder(opts.to == "rosbag2", edges[0][0])

    def start(bag: BagWriter, emit: _Emit, ts: int) -> None:
        bag.add("/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
        emit("/tf_static", ts, msgs.transforms(ts, edges))

    return start


def _to_bag(
    frames: Iterator[Any],
    exports: dict[str, _Export],
    target: Path,
    opts: _Options,
    max_frames: int | None,
    progress: Callable[[int], None] | None,
    start: _Start | None = None,
    back: BagBack | None = None,
) -> tuple[dict[str, Any], dict[str, int]]:
    """Write ``frames`` (``(camera, frame)``, each camera's through its export, and the kept
    messages of ``back``) into a bag at ``target``, the messages in time order; the summary,
    and the frames written per camera."""
    counts = dict.fromkeys(exports, 0)
    count = 0
    with atomic_output(target, place=swap_in) as staging:
        staging.mkdir(parents=True)
        first = next(iter(exports.values()))
        bag = BagWriter(staging / target.name, opts.to, opts.storage, first.msgs)
        order = InTimeOrder(bag)
        skip = first.skip

        def emit(topic: str, ns: int, data: bytes) -> None:
            if topic not in skip:  # a topic the recording kept is written as it came
                order.emit(topic, ns, data)

        try:
            if back is not None:
                back.open(bag)
            for item in frames:
                if isinstance(item, KeptMessage):
                    order.flush(item.log_time)
                    assert back is not None
                    if not back.write(item):  # not a frame
                        continue
                else:
                    camera, frame = item
                    earliest = _earliest(frame)
                    order.flush(earliest)
                    if count == 0 and start is not None:
                        start(bag, emit, earliest)
                    export = exports[camera]
                    if counts[camera] == 0:
                        export.add_topics(bag, frame.color is not None)
                    export.write_frame(bag, emit, frame)
                    counts[camera] += 1
                count += 1
                if progress is not None:
                    progress(count)
                if max_frames is not None and count >= max_frames:
                    break
            if count == 0:
                raise InputError("the input has no frames to write")
            order.flush()
        except BaseException:
            with contextlib.suppress(Exception):
                bag.abort()
            raise
        bag.close()
    size = (
        sum(f.stat().st_size for f in target.rglob("*") if f.is_file())
        if target.is_dir()
        else target.stat().st_size
    )
    summary = {
        "frames": count,
        "path": str(target),
        "topics": list(bag.conns) + ([] if back is None else back.written_topics()),
        "bytes": size,
        "format": opts.to,
        "storage": opts.storage,
        **({} if back is None else back.summary()),
    }
    return summary, counts


def _camera_export(rig: RigRecording, name: str, opts: _Options) -> _Export:
    """The export of camera ``name`` of ``rig``: its namespace, its frame, its camera."""
    cam = rig.cameras[name]
    rec = rig.frames(name)
    inp = _Input(
        iter(()),
        cam.intrinsics,
        cam.depth_scale,
        dict(rec.metadata),
        len(rec),
        lambda: None,
        cam.color_intrinsics,
        cam.depth_to_color,
    )
    own = dataclasses.replace(opts, namespace=f"{opts.namespace}/{name}", frame_id=cam.frame_id)
    try:
        export = _Export(inp, own)
    except InputError as exc:
        raise InputError(f"camera {name!r}: {exc}") from None
    export.rig_pose = (rig.rig_frame_id, cam.rig_pose)
    return export


def _write_rig(
    rig: RigRecording,
    target: Path,
    opts: _Options,
    max_frames: int | None,
    progress: Callable[[int], None] | None,
) -> dict[str, Any]:
    exports = {name: _camera_export(rig, name, opts) for name in rig.camera_names}
    start = _tf_static(opts, rig_transforms(rig))
    frames = ((name, frame) for _, name, frame in in_time_order(rig))
    summary, counts = _to_bag(frames, exports, target, opts, max_frames, progress, start)
    return {**summary, "cameras": counts}
