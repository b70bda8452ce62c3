"""RealSense ``.bag`` files made from real RGB-D frames, for tests and benchmarks of live capture.

librealsense plays a ``.bag`` back as if it were a camera, which is how live recording is tested
without one. The one real RealSense bag at hand (``bags/realsense/`` in the shared data) holds
two depth frames; :func:`write_realsense_bag` keeps its layout (file version, device and sensor
info, options, stream info, the depth-to-color extrinsic) and writes as many depth and color
frames as it is given, each with its header stamp, frame counter and the metadata librealsense
reads back (timestamp domain, frame counter, frame timestamp). Such a bag plays through
``pyrealsense2`` and reads through :class:`pcdcodec.sources.realsense.RealSenseBagSource`, so
both can be compared frame by frame.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..geometry.camera import CameraIntrinsics
from .sequences import SHARED_DATA

__all__ = ["TEMPLATE_BAG", "write_realsense_bag"]

#: The real RealSense recording whose layout the bags made here keep.
TEMPLATE_BAG = SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag"

_NS = 1_000_000_000


def _image_msg(types: Any, seq: int, stamp: int, image: Any, encoding: str) -> Any:
    Header, Time, Image = (  # noqa: N806 - message classes
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
        types["sensor_msgs/msg/Image"],
    )
    h, w = image.shape[:2]
    data = np.ascontiguousarray(image).view(np.uint8).reshape(-1)
    return Image(
        header=Header(seq=seq, stamp=Time(sec=stamp // _NS, nanosec=stamp % _NS), frame_id="0"),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=data.size // h,
        data=data,
    )


def write_realsense_bag(
    path: str | Path,
    depths: Sequence[Any],
    colors: Sequence[Any],
    *,
    fps: float = 30.0,
    start_ns: int = 10 * _NS,
    serial: str = "000000000001",
    name: str = "Intel RealSense D435",
    intrinsics: CameraIntrinsics | None = None,
    frame_numbers: Sequence[int] | None = None,
    template: str | Path = TEMPLATE_BAG,
    color_delays_ns: Sequence[int] | None = None,
) -> Path:
    """Write a librealsense ``.bag`` at ``path`` holding ``depths`` (H×W uint16, millimetres)
    and ``colors`` (H×W×3 uint8 RGB), frame ``i`` of both stamped ``start_ns + i / fps``.

    The layout, options and depth-to-color extrinsic come from ``template`` (a real RealSense
    bag); the stream rate, serial number, device name and cameras (``intrinsics`` for both, or
    the template's when ``None``, which then must be of the frames' size) are this bag's own.
    ``frame_numbers`` gives each frame its counter (default ``0, 1, ...``): a gap is a frame
    the camera dropped. ``color_delays_ns`` stamps color frame ``i`` that many ns after depth
    frame ``i`` (default 0: the same stamp). Returns ``path``.
    """
    from rosbags.rosbag1 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if len(depths) != len(colors) or not depths:
        raise InputError(
            f"need as many depth as color frames, at least one: {len(depths)}, {len(colors)}"
        )
    numbers = list(range(len(depths))) if frame_numbers is None else list(frame_numbers)
    if len(numbers) != len(depths):
        raise InputError(f"{len(numbers)} frame numbers for {len(depths)} frames")
    delays = [0] * len(depths) if color_delays_ns is None else list(color_delays_ns)
    if len(delays) != len(depths):
        raise InputError(f"{len(delays)} color delays for {len(depths)} frames")
    ts = get_typestore(Stores.ROS1_NOETIC)
    types = ts.types
    KeyValue = types["diagnostic_msgs/msg/KeyValue"]  # noqa: N806 - message class
    period = round(_NS / fps)
    with Reader(Path(template)) as reader:
        template_msgs = [
            (c, t, bytes(raw)) for c, t, raw in reader.messages() if "/image/" not in c.topic
        ]
        conns = {c.topic: c for c in reader.connections}
    depth_prefix = next(t for t in conns if t.endswith("/Depth_0/image/data"))[: -len("/data")]
    color_prefix = next(t for t in conns if t.endswith("/Color_0/image/data"))[: -len("/data")]
    with Writer(path) as writer:
        out: dict[str, Any] = {}

        def conn(topic: str) -> Any:
            if topic not in out:
                c = conns[topic]
                out[topic] = writer.add_connection(
                    topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest
                )
            return out[topic]

        for c, t, raw in template_msgs:
            data = raw
            if c.msgtype == "realsense_msgs/msg/StreamInfo":  # uint32 fps first
                data = struct.pack("<I", round(fps)) + raw[4:]
            elif c.topic.endswith("/info") and c.msgtype == "diagnostic_msgs/msg/KeyValue":
                msg: Any = ts.deserialize_ros1(raw, c.msgtype)
                value = {"Serial Number": serial, "Name": name}.get(str(msg.key))
                if value is not None and c.topic.count("/") == 2:  # /device_0/info
                    data = bytes(ts.serialize_ros1(KeyValue(key=msg.key, value=value), c.msgtype))
            elif c.topic.endswith("/camera_info") and intrinsics is not None:
                info: Any = ts.deserialize_ros1(raw, c.msgtype)
                k = intrinsics
                info.width, info.height = k.width, k.height
                row = [k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1]
                info.K = np.array(row, dtype=np.float64)
                info.P = np.array(
                    [k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0], dtype=np.float64
                )
                data = bytes(ts.serialize_ros1(info, c.msgtype))
            writer.write(conn(c.topic), t, data)
        for i, (depth, color) in enumerate(zip(depths, colors, strict=True)):
            depth_stamp = start_ns + i * period
            log_time = 1_000 + i * period  # librealsense paces playback by the log time
            number = numbers[i]
            for prefix, image, encoding, stamp in (
                (depth_prefix, np.asarray(depth, dtype=np.uint16), "mono16", depth_stamp),
                (color_prefix, np.asarray(color, dtype=np.uint8), "rgb8", depth_stamp + delays[i]),
            ):
                msg = _image_msg(types, number, stamp, image, encoding)
                topic = f"{prefix}/data"
                writer.write(
                    conn(topic), log_time, bytes(ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
                )
                meta = conn(f"{prefix}/metadata")
                for key, value in (
                    ("system_time", f"{stamp / 1e6:.6f}"),
                    ("timestamp_domain", "Hardware Clock"),
                    ("Frame Counter", str(number)),
                    ("Frame Timestamp", str(stamp // 1000)),
                ):
                    kv = bytes(ts.serialize_ros1(KeyValue(key=key, value=value), meta.msgtype))
                    writer.write(meta, log_time, kv)
    return path
