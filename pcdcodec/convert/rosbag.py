"""Recordings (or any source) back into ROS 1 and ROS 2 bags that ``rosbag play`` and
``ros2 bag play`` accept.

:func:`export_bag` writes, per frame and at the frame's recorded stamp (as both the header stamp
and the bag time):

* ``<ns>/depth/image_raw``: ``sensor_msgs/Image``, 16UC1 millimetres when the depth scale is 1000
  per metre, else 32FC1 metres; or, with ``compressed_depth``, image_transport's
  ``<ns>/depth/image_raw/compressedDepth`` (``"16UC1; compressedDepth png"``);
* ``<ns>/color/image_raw``: ``sensor_msgs/Image`` rgb8 (registered to the depth);
* ``<ns>/depth/camera_info`` and ``<ns>/color/camera_info``: ``sensor_msgs/CameraInfo`` with the
  recording's camera (and the distortion its source had, when it was kept);
* with ``cloud``, ``<ns>/depth_registered/points``: the organized ``sensor_msgs/PointCloud2``
  XYZRGB (x, y, z float32 at bytes 0, 4, 8, packed rgb at 16, 32 bytes per point, NaN for
  pixels without depth), as the paper's broadcast node published it;
* for frames with a pose, ``/tf``: ``tf2_msgs/TFMessage`` with one ``TransformStamped`` from
  ``world`` to the camera frame (the camera-to-world pose), so the trajectory plays in RViz.

Connection headers, message definitions and MD5 sums (ROS 1) or type hashes (ROS 2) come from
the rosbags typestores of ROS 1 Noetic and ROS 2 Humble. The bag is written beside its final
name and moved into place when complete.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..ros.clouds import CLOUD_DTYPE, cloud_array

__all__ = ["CLOUD_DTYPE", "cloud_array", "export_bag"]

_NS = 1_000_000_000
FORMATS = ("rosbag1", "rosbag2")
STORAGES = ("mcap", "sqlite3")


@dataclass
class _Input:
    frames: Iterator[tuple[Any, Any, int, Any]]
    intrinsics: Any
    depth_scale: float
    metadata: dict[str, str]
    total: int | None
    close: Callable[[], None]
    #: The color camera and the depth-to-color transform, where color is not registered.
    color_intrinsics: Any = None
    depth_to_color: Any = None


def _input(src: Any, intrinsics: Any, depth_scale: float | None) -> _Input:
    from ..recording.reader import Recording
    from ..sources.base import Source, open_source

    if isinstance(src, (str, os.PathLike)):
        p = Path(src)
        head = b""
        if p.is_file():
            with p.open("rb") as f:
                head = f.read(8)
        from ..recording import _index as fmt

        if head == fmt.MAGIC:
            try:
                rec = Recording(p)
            except Exception:
                rec = None
            if rec is not None:
                return _from_recording(rec, close=rec.close)
        src = open_source(p)
        owned = True
    else:
        owned = False
    if isinstance(src, Recording):
        return _from_recording(src, close=lambda: None)
    if isinstance(src, Source):
        intr = intrinsics if intrinsics is not None else src.intrinsics
        if intr is None:
            raise InputError(
                f"source {str(src.path)!r} has no camera: pass intrinsics to write camera info "
                "and clouds"
            )
        frames = ((f.color, f.depth, int(f.timestamp_ns), f.pose) for f in src)
        return _Input(
            frames,
            intr,
            float(depth_scale if depth_scale is not None else src.depth_scale),
            dict(src.metadata),
            src.frame_count,
            src.close if owned else (lambda: None),
            src.color_intrinsics,
            src.depth_to_color,
        )
    raise InputError(
        f"export_bag takes a .pcdc path, a Recording, a Source or a path open_source reads, "
        f"got {type(src).__name__}"
    )


def _from_recording(rec: Any, close: Callable[[], None]) -> _Input:
    frames = ((f.color, f.depth, int(f.timestamp_ns), f.pose) for f in rec)
    return _Input(
        frames,
        rec.intrinsics,
        rec.depth_scale,
        dict(rec.metadata),
        len(rec),
        close,
        rec.color_intrinsics,
        rec.depth_to_color,
    )


class _Messages:
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
        from ..geometry.transform import matrix_to_quaternion

        t = self.types
        q = matrix_to_quaternion(pose[:3, :3])
        header = self.header(ns)
        header.frame_id = parent
        stamped = t["geometry_msgs/msg/TransformStamped"](
            header=header,
            child_frame_id=self.frame_id,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](
                    x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3])
                ),
                rotation=t["geometry_msgs/msg/Quaternion"](
                    x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
                ),
            ),
        )
        return self.serialize(t["tf2_msgs/msg/TFMessage"](transforms=[stamped]))

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


class _BagWriter:
    """One flavour of bag writer behind a common add/write/close."""

    def __init__(self, path: Path, fmt: str, storage: str, messages: _Messages) -> None:
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

    def add(self, topic: str, msgtype: str) -> None:
        self.conns[topic] = self.writer.add_connection(
            topic, msgtype, typestore=self.messages.store
        )

    def write(self, topic: str, ns: int, data: bytes) -> None:
        self.writer.write(self.conns[topic], ns, data)

    def close(self) -> None:
        self.writer.close()


def export_bag(
    src: Any,
    out: str | os.PathLike[str],
    *,
    to: str = "rosbag1",
    storage: str = "mcap",
    images: bool = True,
    camera_info: bool = True,
    cloud: bool = False,
    compressed_depth: bool = False,
    namespace: str = "/camera",
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
    ``to`` is ``"rosbag1"`` or ``"rosbag2"``; ``storage`` (ROS 2) ``"mcap"`` or ``"sqlite3"``.
    ``images``, ``camera_info`` and ``cloud`` pick the topics (see the module docstring);
    ``compressed_depth`` writes depth as image_transport compressedDepth (16UC1 depth, depth
    scale 1000, only). ``intrinsics``/``depth_scale`` override a source's.

    Returns a summary: ``frames``, ``path``, ``topics`` and ``bytes`` (size on disk). Raises
    :class:`~pcdcodec.InputError` for an unknown format or storage, an existing output without
    ``overwrite``, or compressedDepth of depth that is not millimetres; nothing is left under
    ``out`` when writing fails.
    """
    if to not in FORMATS:
        raise InputError(f"bag format must be one of {', '.join(FORMATS)}, got {to!r}")
    if storage not in STORAGES:
        raise InputError(f"ROS 2 storage must be one of {', '.join(STORAGES)}, got {storage!r}")
    if not (images or cloud or camera_info):
        raise InputError("nothing to write: enable images, camera_info or cloud")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    target = Path(out)
    if target.exists() and not overwrite:
        raise InputError(f"{str(target)!r} already exists; pass overwrite=True to replace it")
    namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
    inp = _input(src, intrinsics, depth_scale)
    try:
        return _write(
            inp, target, to, storage, images, camera_info, cloud, compressed_depth,
            namespace, frame_id, max_frames, progress,
        )  # fmt: skip
    finally:
        inp.close()


def _write(
    inp: _Input,
    target: Path,
    to: str,
    storage: str,
    images: bool,
    camera_info: bool,
    cloud: bool,
    compressed_depth: bool,
    namespace: str,
    frame_id: str | None,
    max_frames: int | None,
    progress: Callable[[int], None] | None,
) -> dict[str, Any]:
    from .._atomic import atomic_output  # not loaded by `import pcdcodec`
    from ..geometry.projector import Projector

    intr = inp.intrinsics
    scale = inp.depth_scale
    if compressed_depth and images and scale != 1000.0:
        raise InputError(
            f"compressedDepth holds 16UC1 millimetres; this depth has scale {scale} per metre "
            "(export without compressed_depth to get 32FC1 metres)"
        )
    model = inp.metadata.get("distortion_model", "plumb_bob")
    try:
        dist = [float(v) for v in json.loads(inp.metadata.get("distortion", "[]"))]
    except (ValueError, TypeError):
        dist = []
    if not dist and model == "plumb_bob":
        dist = [0.0] * 5
    fid = frame_id or inp.metadata.get("frame_id") or "camera_color_optical_frame"
    msgs = _Messages(to == "rosbag2", fid)
    color_cam = inp.color_intrinsics
    projector = (
        Projector(
            intr,
            depth_scale=scale,
            color_intrinsics=color_cam,
            depth_to_color=inp.depth_to_color if color_cam is not None else None,
        )
        if cloud
        else None
    )
    if color_cam is not None:
        # The color image comes from its own camera: its CameraInfo says so.
        color_info = color_cam.to_camera_info()
        color_model, color_dist = color_info["distortion_model"], list(color_info["D"])
    else:
        color_cam, color_model, color_dist = intr, model, dist

    t_depth = f"{namespace}/depth/image_raw"
    t_cdepth = f"{t_depth}/compressedDepth"
    t_color = f"{namespace}/color/image_raw"
    t_dinfo = f"{namespace}/depth/camera_info"
    t_cinfo = f"{namespace}/color/camera_info"
    t_cloud = f"{namespace}/depth_registered/points"

    count = 0
    topics: list[str] = []
    with atomic_output(target, place=_swap_in) as staging:
        staging.mkdir(parents=True)
        tmp_out = staging / target.name
        bag = _BagWriter(tmp_out, to, storage, msgs)
        try:
            for color, depth, ts, pose in inp.frames:
                if count == 0:
                    has_color = color is not None
                    if images:
                        if compressed_depth:
                            topics.append(t_cdepth)
                            bag.add(t_cdepth, "sensor_msgs/msg/CompressedImage")
                        else:
                            topics.append(t_depth)
                            bag.add(t_depth, "sensor_msgs/msg/Image")
                        if has_color:
                            topics.append(t_color)
                            bag.add(t_color, "sensor_msgs/msg/Image")
                    if camera_info:
                        for t in (t_dinfo, t_cinfo) if has_color else (t_dinfo,):
                            topics.append(t)
                            bag.add(t, "sensor_msgs/msg/CameraInfo")
                    if cloud:
                        topics.append(t_cloud)
                        bag.add(t_cloud, "sensor_msgs/msg/PointCloud2")
                if depth.shape != intr.shape:
                    raise InputError(
                        f"frame at {ts} ns is {depth.shape[1]}x{depth.shape[0]}, the camera "
                        f"{intr.width}x{intr.height}"
                    )
                if images:
                    if compressed_depth:
                        from ..ros.messages import compressed_depth_encode

                        payload = compressed_depth_encode(np.asarray(depth, np.uint16))
                        fmt = "16UC1; compressedDepth png"
                        bag.write(t_cdepth, ts, msgs.compressed(ts, payload, fmt))
                    elif depth.dtype == np.uint16 and scale == 1000.0:
                        bag.write(t_depth, ts, msgs.image(ts, depth, "16UC1"))
                    else:
                        if depth.dtype == np.float32 and scale == 1.0:
                            metres = depth
                        else:
                            metres = (depth / np.float32(scale)).astype(np.float32)
                            metres[depth == 0] = np.nan  # ROS 32FC1: NaN is no measurement
                        bag.write(t_depth, ts, msgs.image(ts, metres, "32FC1"))
                    if color is not None:
                        bag.write(t_color, ts, msgs.image(ts, color, "rgb8"))
                if camera_info:
                    info = msgs.camera_info(ts, intr, model, dist)
                    bag.write(t_dinfo, ts, info)
                    if color is not None:
                        bag.write(
                            t_cinfo, ts, msgs.camera_info(ts, color_cam, color_model, color_dist)
                        )
                if projector is not None:
                    bag.write(t_cloud, ts, msgs.cloud(ts, cloud_array(projector, depth, color)))
                if pose is not None:
                    if "/tf" not in bag.conns:
                        topics.append("/tf")
                        bag.add("/tf", "tf2_msgs/msg/TFMessage")
                    bag.write("/tf", ts, msgs.tf(ts, pose, "world"))
                count += 1
                if progress is not None:
                    progress(count)
                if max_frames is not None and count >= max_frames:
                    break
            if count == 0:
                raise InputError("the input has no frames to write")
        except BaseException:
            with contextlib.suppress(Exception):
                bag.writer.abort()
            raise
        bag.close()
    size = (
        sum(f.stat().st_size for f in target.rglob("*") if f.is_file())
        if target.is_dir()
        else target.stat().st_size
    )
    return {"frames": count, "path": str(target), "topics": topics, "bytes": size, "format": to}


def _swap_in(staging: Path, target: Path) -> None:
    """Move the bag written as ``staging/NAME`` onto ``target``, replacing a bag there (a file
    or a folder)."""
    tmp_out = staging / target.name
    if target.exists():
        trash = target.parent / f".{target.name}.old-{os.getpid()}"
        os.replace(target, trash)
        os.replace(tmp_out, target)
        if trash.is_dir():
            shutil.rmtree(trash)
        else:
            trash.unlink()
    else:
        os.replace(tmp_out, target)
