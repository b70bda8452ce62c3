"""Mutated ROS bags: what ``tests/test_fuzz_bags.py`` and ``tests/run_fuzz_bags.py`` run.

A small clean bag is built for each storage format (ROS 1, ROS 2 sqlite3, ROS 2 mcap) from the
bundled sample at 40x30: a CameraInfo, depth as a 16UC1 Image, as a compressedDepth PNG and as a
32FC1 Image, color as a JPEG, a PNG and an rgb8 Image, and an organized PointCloud2 with packed
rgb, three frames each. Four *views* read it: the three depth/color pairs and the cloud.

Each case changes the bag in one way. Most change one *message field* before the bag is
written (Image width, height, step, encoding, byte order and data; CompressedImage format and
payload: cut, bombs declaring huge sizes, another image type, flipped bytes; CameraInfo K, D,
size and distortion model; PointCloud2 fields, offsets, datatypes, counts, steps, size, byte
order and data; header stamps: nanoseconds of a second or more, negative, huge, zero, out of
order); the rest change the bytes of the written bag file. The mutant is opened through every
view that reads the changed topic; every frame is iterated, the frame index built and a stretch
read on its own, and the outcome classified:

* ``identical``: the same frames, timestamps and camera as the clean bag;
* ``detected``: a :class:`~pcdcodec.PcdcodecError` whose message names the bag file;
* ``changed-as-allowed``: data that differs where the mutation may legitimately change it (a
  flipped bit inside JPEG entropy data, an Image's byte order, a stamp), and only there;

and failures: ``FOREIGN-EXCEPTION`` (anything outside pcdcodec's tree), ``UNNAMED-ERROR`` (an
error not naming the bag), ``WRONG-DATA`` (frames, timestamps or camera differing where the
mutation could not change them, or frames of the wrong size or type), ``INDEX-MISMATCH`` (the
frame index or a stretch read alone disagreeing with iteration), ``MEMORY`` (an allocation
past :func:`memory_bound`, which follows the declared camera: the address space is capped there
while a view reads, or with ``memory="trace"`` every allocation is traced) and hangs (a
watchdog stops the process). Everything is seeded: case ``k`` of seed ``s`` is the same mutation
on every run.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import itertools
import os
import shutil
import struct
import tracemalloc
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec

from .recording_fuzz import watchdog

FORMATS = ("ros1", "sqlite3", "mcap")
W, H = 40, 30
STEP = 16  # sample frames 640x480, every 16th pixel
FRAMES = 3
NS = 1_000_000_000
T0 = 1_700_000_000 * NS

INFO = "/cam/depth/camera_info"
DEPTH = "/cam/depth/image_raw"
JPEG = "/cam/color/image_raw/compressed"
CDEPTH = "/cam/aligned/depth/compressedDepth"
PNG = "/cam/aligned/color/png"
DEPTH32 = "/cam/raw/depth32"
RGB = "/cam/raw/color"
CLOUD = "/cam/points"

#: view name -> open options; each reads a depth/color pair (or the cloud) with the camera info
VIEWS: dict[str, dict[str, Any]] = {
    "image+jpeg": {"depth_topic": DEPTH, "color_topic": JPEG, "info_topic": INFO},
    "cdepth+png": {"depth_topic": CDEPTH, "color_topic": PNG, "info_topic": INFO},
    "32fc1+rgb8": {"depth_topic": DEPTH32, "color_topic": RGB, "info_topic": INFO},
    "cloud": {"cloud_topic": CLOUD, "info_topic": INFO},
}
TOPIC_VIEWS = {
    DEPTH: ["image+jpeg"],
    JPEG: ["image+jpeg"],
    CDEPTH: ["cdepth+png"],
    PNG: ["cdepth+png"],
    DEPTH32: ["32fc1+rgb8"],
    RGB: ["32fc1+rgb8"],
    CLOUD: ["cloud"],
    INFO: list(VIEWS),
}

OK_OUTCOMES = ("identical", "detected", "changed-as-allowed")
_RANK = {"identical": 0, "changed-as-allowed": 1, "detected": 2}


# -- the clean bag ----------------------------------------------------------------------------


def _store(ros2: bool) -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)


@functools.cache
def _frames() -> list[tuple[Any, Any]]:
    seq = pcdcodec.load_sample(max_frames=FRAMES)
    return [
        (
            np.ascontiguousarray(f.color[::STEP, ::STEP]),
            np.ascontiguousarray(f.depth[::STEP, ::STEP]),
        )
        for f in seq
    ]


def build_messages(fmt: str) -> list[list[Any]]:
    """``[topic, log time, message]`` of the clean bag of ``fmt``, in log-time order (a fresh
    copy each call: mutations change it)."""
    return copy.deepcopy(_build_messages(fmt))


@functools.cache
def _build_messages(fmt: str) -> list[list[Any]]:
    import imagecodecs

    from pcdcodec.convert.rosbag import cloud_array
    from pcdcodec.ros.messages import compressed_depth_encode

    ros2 = fmt != "ros1"
    store = _store(ros2)
    t = store.types

    def header(ns: int) -> Any:
        stamp = t["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS)
        if ros2:
            return t["std_msgs/msg/Header"](stamp=stamp, frame_id="cam")
        return t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="cam")

    def image(ns: int, arr: Any, enc: str) -> Any:
        rows = np.ascontiguousarray(arr).reshape(H, -1).view(np.uint8)
        return t["sensor_msgs/msg/Image"](
            header=header(ns), height=H, width=W, encoding=enc, is_bigendian=0,
            step=rows.shape[1], data=rows.reshape(-1).copy(),
        )  # fmt: skip

    def compressed(ns: int, fmt_: str, data: bytes) -> Any:
        return t["sensor_msgs/msg/CompressedImage"](
            header=header(ns), format=fmt_, data=np.frombuffer(data, np.uint8).copy()
        )

    intr = pcdcodec.CameraIntrinsics(W, H, 32.5, 32.25, 19.75, 14.5)
    k = np.array([intr.fx, 0, intr.cx, 0, intr.fy, intr.cy, 0, 0, 1], np.float64)
    arrays = {
        "d": np.array([0.0] * 5),
        "k": k,
        "r": np.eye(3).reshape(-1),
        "p": np.array([intr.fx, 0, intr.cx, 0, 0, intr.fy, intr.cy, 0, 0, 0, 1, 0], np.float64),
    }
    if not ros2:
        arrays = {key.upper(): v for key, v in arrays.items()}
    roi = t["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    info = t["sensor_msgs/msg/CameraInfo"](
        header=header(T0), height=H, width=W, distortion_model="plumb_bob",
        binning_x=0, binning_y=0, roi=roi, **arrays,
    )  # fmt: skip
    projector = pcdcodec.Projector(intr, depth_scale=5000.0)
    field_t = t["sensor_msgs/msg/PointField"]
    msgs: list[list[Any]] = [[INFO, T0, info]]
    for i, (color, depth) in enumerate(_frames()):
        ns = T0 + i * 33_000_000
        metres = (depth.astype(np.float32) / np.float32(5000.0)).astype(np.float32)
        metres[depth == 0] = np.nan
        pts = cloud_array(projector, depth, color)
        cloud = t["sensor_msgs/msg/PointCloud2"](
            header=header(ns), height=H, width=W,
            fields=[field_t(name=n, offset=o, datatype=7, count=1)
                    for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))],
            is_bigendian=False, point_step=pts.dtype.itemsize, row_step=W * pts.dtype.itemsize,
            data=pts.reshape(-1).view(np.uint8).copy(), is_dense=False,
        )  # fmt: skip
        jpeg = bytes(imagecodecs.jpeg8_encode(color, level=90))
        png = bytes(imagecodecs.png_encode(color))
        msgs += [
            [DEPTH, ns + 1, image(ns, depth, "16UC1")],
            [JPEG, ns + 2, compressed(ns, "rgb8; jpeg compressed bgr8", jpeg)],
            [
                CDEPTH,
                ns + 3,
                compressed(ns, "16UC1; compressedDepth png", compressed_depth_encode(depth)),
            ],
            [PNG, ns + 4, compressed(ns, "bgr8; png compressed bgr8", png)],
            [DEPTH32, ns + 5, image(ns, metres, "32FC1")],
            [RGB, ns + 6, image(ns, color, "rgb8")],
            [CLOUD, ns + 7, cloud],
        ]
    return msgs


def write_bag(fmt: str, msgs: list[list[Any]], folder: Path, name: str) -> Path:
    """Write ``msgs`` as a bag of ``fmt``; returns the path to open (a ROS 1 file, a ROS 2
    sqlite3 bag folder, or a ROS 2 mcap storage file)."""
    ros2 = fmt != "ros1"
    store = _store(ros2)
    if ros2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        target = folder / name
        if target.exists():
            shutil.rmtree(target)
        plugin = StoragePlugin.SQLITE3 if fmt == "sqlite3" else StoragePlugin.MCAP
        writer: Any = Writer(target, version=9, storage_plugin=plugin)
    else:
        from rosbags.rosbag1 import Writer as Writer1

        target = folder / f"{name}.bag"
        target.unlink(missing_ok=True)
        writer = Writer1(target)
    conns: dict[str, Any] = {}
    with writer:
        for topic, ns, msg in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=store)
            ser = store.serialize_cdr if ros2 else store.serialize_ros1
            writer.write(conns[topic], ns, bytes(ser(msg, msg.__msgtype__)))
    if fmt == "mcap":
        return next(target.glob("*.mcap"))
    return target


def storage_file(fmt: str, path: Path) -> Path:
    """The file holding the messages (what byte mutations change)."""
    return next(path.glob("*.db3")) if fmt == "sqlite3" else path


# -- reading ---------------------------------------------------------------------------------


@dataclass
class Reading:
    """What a view of a bag gives: frames, their timestamps, the camera; or the error."""

    frames: list[tuple[int, Any, Any]] = field(default_factory=list)  # (ts, color, depth)
    intrinsics: Any = None
    index: list[int] | None = None
    stretch: list[tuple[int, Any, Any]] | None = None
    error: BaseException | None = None
    stage: str = ""
    peak: int = 0
    bound: int = 0


def memory_bound(shape: tuple[int, int] | None) -> int:
    """The most a view may allocate, from the camera size it declares: a fixed allowance for the
    bag reader, plus 64 frames of the declared size (8 bytes a pixel)."""
    h, w = shape if shape is not None else (H, W)
    return 256 * 2**20 + 64 * h * w * 8


def _vm_size() -> int | None:
    """This process's virtual memory size (bytes), or ``None`` where /proc does not say."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


@contextlib.contextmanager
def _address_space_limit(extra: int) -> Iterator[None]:
    """Let this process map at most ``extra`` more bytes inside the block: an allocation beyond
    it raises MemoryError (cheap, unlike tracing every allocation). No-op off Linux."""
    try:
        import resource
    except ImportError:
        yield
        return
    size = _vm_size()
    if size is None:
        yield
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = size + extra
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def read_view(path: Path, view: str, *, memory: str = "limit") -> Reading:
    """Open ``path`` with a view's options, iterate it, index it and read frames 1.. alone.

    ``memory`` is how memory is bounded: ``"limit"`` caps the address space at
    :func:`memory_bound` of the clean camera (an allocation past it is a MemoryError),
    ``"trace"`` traces every allocation and records the peak (slow), ``"none"`` neither.
    """
    out = Reading()
    out.bound = memory_bound((H, W))
    if memory == "trace":
        tracemalloc.start()
    src = None
    guard = _address_space_limit(out.bound) if memory == "limit" else contextlib.nullcontext()
    try:
        with guard:
            out.stage = "open"
            src = pcdcodec.open_source(path, **VIEWS[view])
            out.intrinsics = src.intrinsics
            out.stage = "iterate"
            for f in src:
                out.frames.append((int(f.timestamp_ns), f.color, f.depth))
            out.stage = "index"
            index = src.frame_index()
            assert index is not None
            out.index = [int(t) for t in index.timestamps]
            out.stage = "stretch"
            out.stretch = [
                (int(f.timestamp_ns), f.color, f.depth) for f in src.frames_at(index.slice(1))
            ]
            out.stage = "done"
    except BaseException as exc:
        out.error = exc
    finally:
        shape = getattr(src, "_shape", None)
        if src is not None:
            try:
                src.close()
            except BaseException as exc:
                out.error = out.error or exc
        if memory == "trace":
            out.peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            out.bound = memory_bound(shape)
    return out


# -- mutations -------------------------------------------------------------------------------


@dataclass
class Mutation:
    """One change to a bag: what it did, which views read what it changed, and what of their
    output it may legitimately change (``depth``, ``color``, ``timestamps``, ``frames``,
    ``camera``, or ``any`` for byte mutations of the file)."""

    what: str
    views: list[str]
    allowed: set[str]
    apply_bytes: Callable[[bytes], bytes] | None = None


def _pick(rng: np.random.Generator, items: Any) -> Any:
    items = list(items)
    return items[int(rng.integers(len(items)))]


def _data_of(msg: Any) -> bytes:
    return bytes(np.asarray(msg.data, np.uint8).tobytes())


def _set_data(msg: Any, data: bytes) -> None:
    msg.data = np.frombuffer(data, np.uint8).copy()


def _flip(rng: np.random.Generator, data: bytes, lo: int = 0) -> tuple[bytes, int]:
    b = bytearray(data)
    if len(b) <= lo:
        return bytes(b), -1
    pos = int(rng.integers(lo, len(b)))
    b[pos] ^= 1 << int(rng.integers(8))
    return bytes(b), pos


def _declare(data: bytes, width: int, height: int) -> bytes:
    """A JPEG or PNG (or compressedDepth PNG) whose header declares another size."""
    b = bytearray(data)
    base = b.find(b"\x89PNG")
    if base >= 0:
        struct.pack_into(">II", b, base + 16, width, height)
        struct.pack_into(">I", b, base + 29, zlib.crc32(bytes(b[base + 12 : base + 29])))
        return bytes(b)
    i = 2
    while i + 4 < len(b) and b[i + 1] not in (0xC0, 0xC1, 0xC2):
        i += 2 + struct.unpack_from(">H", b, i + 2)[0]
    struct.pack_into(">HH", b, i + 5, height, width)
    return bytes(b)


def _mutate_image(rng: np.random.Generator, msg: Any, topic: str, what: list[str]) -> set[str]:
    role = "color" if topic == RGB else "depth"
    op = _pick(rng, ["width", "height", "step", "encoding", "bigendian", "length", "data"])
    what.append(op)
    u32 = [0, 1, 2**31, 2**32 - 1]
    if op == "width":
        msg.width = _pick(rng, [W - 1, W + 1, 2 * W, H, 1 << 20, *u32])
    elif op == "height":
        msg.height = _pick(rng, [H - 1, H + 1, 2 * H, W, 1 << 20, *u32])
    elif op == "step":
        msg.step = _pick(rng, [int(msg.step) - 1, int(msg.step) + 1, 2 * int(msg.step), *u32])
    elif op == "encoding":
        encs = ["16UC1", "mono16", "32FC1", "rgb8", "bgr8", "rgba8", "bgra8", "mono8", "8UC3",
                "", "bayer_rggb8", "16UC3", "64FC1", "yuv422"]  # fmt: skip
        msg.encoding = _pick(rng, encs)
        what.append(msg.encoding)
        return {role}
    elif op == "bigendian":
        msg.is_bigendian = 1 - int(msg.is_bigendian)
        return {role}
    elif op == "length":
        data = _data_of(msg)
        n = int(rng.integers(0, len(data) + 64))
        _set_data(msg, data[:n] + bytes(max(0, n - len(data))))
        what.append(str(n))
    else:
        data, pos = _flip(rng, _data_of(msg))
        _set_data(msg, data)
        what.append(str(pos))
        return {role}
    return set()


def _mutate_compressed(
    rng: np.random.Generator, msg: Any, topic: str, what: list[str], fmt_store: Any
) -> set[str]:
    import imagecodecs

    role = "depth" if topic == CDEPTH else "color"
    op = _pick(rng, ["format", "cut", "bomb", "size", "type", "flip", "empty"])
    what.append(op)
    data = _data_of(msg)
    if op == "format":
        msg.format = _pick(
            rng,
            ["jpeg", "png", "rgb8; jpeg compressed bgr8", "bgr8; png compressed bgr8",
             "16UC1; compressedDepth", "16UC1; compressedDepth rvl", "32FC1; compressedDepth png",
             "16UC1; png compressed", "8UC3; jpeg compressed bgr8", "", "tiff",
             "mono16; compressedDepth png", "mono8; jpeg compressed mono8", "compressedDepth"],
        )  # fmt: skip
        what.append(repr(msg.format))
        # 32FC1 compressedDepth reads the same PNG as quantized inverse depth.
        return {"depth"} if role == "depth" else set()
    if op == "cut":
        n = int(rng.integers(0, len(data)))
        _set_data(msg, data[:n])
        what.append(str(n))
    elif op == "bomb":
        wh = _pick(rng, [(30000, 30000), (65535, 65535), (16384, 16384), (W * 100, H * 100)])
        with contextlib.suppress(struct.error):
            _set_data(msg, _declare(data, *wh))
        what.append(f"{wh[0]}x{wh[1]}")
    elif op == "size":
        wh = _pick(rng, [(W + 1, H), (W, H - 1), (H, W), (1, 1)])
        _set_data(msg, _declare(data, *wh))
        what.append(f"{wh[0]}x{wh[1]}")
    elif op == "type":
        color, depth = _frames()[0]
        kind = _pick(rng, ["png8", "png16", "jpeg", "garbage", "png-rgba"])
        what.append(kind)
        if kind == "png8":
            payload = bytes(imagecodecs.png_encode(color))
        elif kind == "png16":
            payload = bytes(imagecodecs.png_encode(depth))
        elif kind == "jpeg":
            payload = bytes(imagecodecs.jpeg8_encode(color, level=95))
        elif kind == "png-rgba":
            payload = bytes(imagecodecs.png_encode(np.dstack([color, color[..., :1]])))
        else:
            payload = rng.integers(0, 256, 200, dtype=np.uint8).tobytes()
        if role == "depth":
            payload = data[:12] + payload
        _set_data(msg, payload)
        return {role}  # another image of the same frame: other pixels, legitimately
    elif op == "empty":
        _set_data(msg, b"")
    else:
        lo = 12 if role == "depth" else 0
        flipped, pos = _flip(rng, data, lo)
        _set_data(msg, flipped)
        what.append(str(pos))
        # JPEG has no checksum: a flip in its entropy-coded data changes pixels undetectably.
        # PNG chunks have CRCs: a flip anywhere in a PNG must be caught.
        is_png = data[lo : lo + 4] == b"\x89PNG"
        return set() if is_png else {role}
    return set()


def _mutate_info(rng: np.random.Generator, msg: Any, what: list[str]) -> set[str]:
    op = _pick(rng, ["k", "d", "model", "width", "height"])
    what.append(op)
    kname = "k" if hasattr(msg, "k") else "K"
    dname = "d" if hasattr(msg, "d") else "D"
    if op == "k":
        k = np.array(getattr(msg, kname), np.float64)
        i = _pick(rng, [0, 2, 4, 5, 8, 1])
        k[i] = _pick(rng, [0.0, -1.0, np.nan, np.inf, 1e300, k[i] * 2, 1e-300])
        setattr(msg, kname, k)
        what.append(f"K[{i}]={k[i]}")
        return {"camera"}
    if op == "d":
        n = _pick(rng, [0, 1, 4, 5, 8, 14, 100])
        setattr(msg, dname, rng.normal(size=n))
        what.append(str(n))
    elif op == "model":
        msg.distortion_model = _pick(rng, ["", "equidistant", "rational_polynomial", "x" * 300])
    elif op == "width":
        msg.width = _pick(rng, [0, W - 1, W + 1, 2**32 - 1])
    else:
        msg.height = _pick(rng, [0, H - 1, H + 1, 2**32 - 1])
    return set()


def _mutate_cloud(rng: np.random.Generator, msg: Any, what: list[str], store: Any) -> set[str]:
    op = _pick(
        rng,
        ["name", "offset", "datatype", "count", "add-field", "drop-field", "point_step",
         "row_step", "width", "height", "bigendian", "dense", "length", "data"],
    )  # fmt: skip
    what.append(op)
    fields = list(msg.fields)
    field_t = store.types["sensor_msgs/msg/PointField"]
    i = int(rng.integers(len(fields))) if fields else 0
    if op == "name" and fields:
        fields[i].name = _pick(rng, ["x", "y", "z", "rgb", "rgba", "foo", "", "Z"])
        what.append(f"{i}={fields[i].name}")
        return {"depth", "color"}  # another field read as z or color, or color gone
    if op == "offset" and fields:
        fields[i].offset = _pick(rng, [0, 4, 8, 12, 16, 20, 28, 29, 31, 32, 2**31, 2**32 - 1])
        what.append(f"{i}={fields[i].offset}")
        return {"depth", "color"}
    if op == "datatype" and fields:
        fields[i].datatype = _pick(rng, [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 255])
        what.append(f"{i}={fields[i].datatype}")
        return set()  # only the color field may change type (5, 6, 7: the same 32 bits)
    if op == "count" and fields:
        fields[i].count = _pick(rng, [0, 2, 3, 2**32 - 1])
        what.append(f"{i}={fields[i].count}")
    elif op == "add-field":
        name = _pick(rng, ["x", "y", "z", "rgb", "rgba", "intensity"])
        fields.append(field_t(name=name, offset=_pick(rng, [0, 8, 12, 16]), datatype=7, count=1))
        what.append(name)
        msg.fields = fields
        return {"color"} if name == "rgba" else set()
    elif op == "drop-field" and fields:
        what.append(str(fields[i].name))
        del fields[i]
        msg.fields = fields
        return {"color"}  # without rgb the cloud has no color
    elif op in ("point_step", "row_step"):
        if op == "point_step":
            msg.point_step = _pick(rng, [0, 12, 16, 20, 28, 31, 33, 64, 2**32 - 1])
        else:
            msg.row_step = _pick(rng, [0, int(msg.row_step) - 4, int(msg.row_step) + 4, 2**32 - 1])
        what.append(f"{msg.point_step}/{msg.row_step}")
        # A smaller step that the data still covers is a valid, other reading of the points.
        return {"depth", "color"}
    elif op == "width":
        msg.width = _pick(rng, [0, 1, W - 1, W + 1, H, 2**31, 2**32 - 1])
    elif op == "height":
        msg.height = _pick(rng, [0, 1, H - 1, H + 1, W, 2**31, 2**32 - 1])
    elif op == "bigendian":
        msg.is_bigendian = not msg.is_bigendian
        return {"depth", "color"}
    elif op == "dense":
        msg.is_dense = not msg.is_dense
    elif op == "length":
        data = _data_of(msg)
        n = int(rng.integers(0, len(data) + 64))
        _set_data(msg, data[:n] + bytes(max(0, n - len(data))))
        what.append(str(n))
    elif op == "data":
        data, pos = _flip(rng, _data_of(msg))
        _set_data(msg, data)
        what.append(str(pos))
        return {"depth", "color"}
    return set()


def _mutate_stamp(
    rng: np.random.Generator, msg: Any, fmt: str, what: list[str], store: Any
) -> set[str]:
    op = _pick(rng, ["nanosec", "negative", "huge", "zero", "earlier", "later"])
    what.append(op)
    stamp = msg.header.stamp
    sec, nsec = int(stamp.sec), int(stamp.nanosec)
    if op == "nanosec":
        nsec = _pick(rng, [1_000_000_000, 1_500_000_000, 2**32 - 1])
    elif op == "negative":
        sec = _pick(rng, [-1, -(2**31), -5])
    elif op == "huge":
        sec = 2**31 - 1
    elif op == "zero":
        sec, nsec = 0, 0
    elif op == "earlier":
        sec -= int(rng.integers(1, 3))
    else:
        nsec = min(nsec + 20_000_000, 999_999_999)
    msg.header.stamp = store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    what.append(f"{sec} s {nsec} ns")
    if op == "nanosec":
        return set()
    # A stamp moved (for ROS 1 a negative second reads as one after 2**31 s; zero falls back to
    # the log time): frames pair, drop and time differently, but each frame keeps its pixels.
    return {"timestamps", "frames"}


def _mutate_bytes(rng: np.random.Generator, what: list[str]) -> Callable[[bytes], bytes]:
    op = _pick(rng, ["flip", "overwrite", "zero", "truncate", "delete", "duplicate", "special"])
    seed = int(rng.integers(2**31))
    what.append(op)

    def apply(data: bytes) -> bytes:
        r = np.random.default_rng(seed)
        b = bytearray(data)
        n = len(b)
        pos = int(r.integers(0, n))
        what.append(f"at {pos} of {n}")
        if op == "flip":
            for _ in range(int(r.integers(1, 4))):
                p = min(n - 1, pos + int(r.integers(0, 16)))
                b[p] ^= 1 << int(r.integers(8))
        elif op == "overwrite":
            size = int(r.integers(1, 9))
            b[pos : pos + size] = r.integers(0, 256, size, dtype=np.uint8).tobytes()
        elif op == "zero":
            end = min(n, pos + int(r.integers(1, 65)))
            b[pos:end] = bytes(end - pos)
        elif op == "truncate":
            del b[pos:]
        elif op == "delete":
            del b[pos : pos + int(r.integers(1, 65))]
        elif op == "duplicate":
            src = int(r.integers(0, n))
            b[pos:pos] = bytes(b[src : src + int(r.integers(1, 129))])
        else:
            value = _pick(r, [b"\xff" * 4, struct.pack("<I", 2**31), struct.pack("<Q", 2**63),
                              struct.pack("<I", n), b"\x00" * 4])  # fmt: skip
            b[pos : pos + len(value)] = value
            del b[n:]
        return bytes(b)

    return apply


#: kinds of mutation and how often each is drawn
KINDS = {
    "image": 0.14,
    "compressed": 0.22,
    "info": 0.08,
    "cloud": 0.2,
    "stamp": 0.14,
    "bytes": 0.22,
}


def mutate(fmt: str, msgs: list[list[Any]], seed: int, case: int) -> Mutation:
    """Case ``case`` of ``seed`` for a bag of ``fmt``: changes ``msgs`` in place (a field of one
    message) or returns a byte mutation to apply to the written file."""
    rng = np.random.default_rng([seed, case, FORMATS.index(fmt)])
    kinds = list(KINDS)
    weights = np.array(list(KINDS.values()))
    kind = kinds[int(rng.choice(len(kinds), p=weights / weights.sum()))]
    store = _store(fmt != "ros1")
    what = [f"{fmt} case {case} seed {seed}", kind]
    if kind == "bytes":
        apply = _mutate_bytes(rng, what)
        return Mutation(" ".join(what), list(VIEWS), {"any"}, apply)
    topics = {
        "image": [DEPTH, DEPTH32, RGB],
        "compressed": [JPEG, PNG, CDEPTH],
        "info": [INFO],
        "cloud": [CLOUD],
        "stamp": [DEPTH, JPEG, CDEPTH, PNG, DEPTH32, RGB, CLOUD],
    }[kind]
    topic = _pick(rng, topics)
    rows = [r for r in msgs if r[0] == topic]
    k = int(rng.integers(len(rows)))
    msg = rows[k][2]
    what += [topic, f"message {k}"]
    if kind == "image":
        allowed = _mutate_image(rng, msg, topic, what)
    elif kind == "compressed":
        allowed = _mutate_compressed(rng, msg, topic, what, store)
    elif kind == "info":
        allowed = _mutate_info(rng, msg, what)
    elif kind == "cloud":
        allowed = _mutate_cloud(rng, msg, what, store)
    else:
        allowed = _mutate_stamp(rng, msg, fmt, what, store)
    return Mutation(" ".join(what), TOPIC_VIEWS[topic], allowed)


# -- classifying -----------------------------------------------------------------------------


@dataclass
class Result:
    outcome: str
    detail: str = ""
    views: dict[str, str] = field(default_factory=dict)


def _same(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind == "f":
        return bool(np.array_equal(a.view(np.uint32), b.view(np.uint32)))
    return bool(np.array_equal(a, b))


def _named(exc: BaseException, path: Path) -> bool:
    return str(path) in str(exc)


def classify(clean: Reading, got: Reading, mutation: Mutation, path: Path) -> tuple[str, str]:
    """The outcome of one view of a mutant (see the module's docstring) and a detail."""
    allowed = mutation.allowed
    if got.peak > got.bound:
        return "MEMORY", f"traced peak {got.peak} bytes over the bound {got.bound}"
    exc = got.error
    cause: BaseException | None = exc
    while cause is not None:  # a MemoryError wrapped into a reader's error is still one
        if isinstance(cause, MemoryError):
            return "MEMORY", f"{got.stage}: an allocation past the bound of {got.bound} bytes"
        cause = cause.__cause__ or cause.__context__
    if exc is not None and not isinstance(exc, pcdcodec.PcdcodecError):
        return "FOREIGN-EXCEPTION", f"{got.stage}: {type(exc).__name__}: {exc}"
    if exc is not None and not _named(exc, path):
        return "UNNAMED-ERROR", f"{got.stage}: {type(exc).__name__}: {exc}"
    # Frames read before any error must be right frames, as must a full read.
    frames = got.frames
    for ts, color, depth in frames:
        if depth.shape != (H, W) or (color is not None and color.shape != (H, W, 3)):
            return "WRONG-DATA", f"a frame at {ts} ns has depth {depth.shape}"
        if color is not None and color.dtype != np.uint8:
            return "WRONG-DATA", f"color of {color.dtype}"
    stamps = [ts for ts, _, _ in frames]
    if any(b <= a for a, b in itertools.pairwise(stamps)):
        return "WRONG-DATA", f"timestamps do not increase: {stamps}"
    if len({str(d.dtype) for _, _, d in frames}) > 1:
        return "WRONG-DATA", "depth changes type between frames"
    if "any" not in allowed:
        if exc is None and got.intrinsics != clean.intrinsics and "camera" not in allowed:
            return "WRONG-DATA", f"camera {got.intrinsics} != {clean.intrinsics}"
        loose = bool(allowed & {"timestamps", "frames"})
        n = len(frames)
        if not loose:
            if exc is None and n != len(clean.frames):
                return "WRONG-DATA", f"{n} frames, the clean bag gives {len(clean.frames)}"
            if stamps != [ts for ts, _, _ in clean.frames][:n]:
                return "WRONG-DATA", f"timestamps {stamps} != {[t for t, _, _ in clean.frames]}"
        for i, (ts, color, depth) in enumerate(frames):
            if loose:
                ok_d = "depth" in allowed or any(_same(depth, d) for _, _, d in clean.frames)
                ok_c = "color" in allowed or any(_same(color, c) for _, c, _ in clean.frames)
            else:
                _, c0, d0 = clean.frames[i]
                ok_d = "depth" in allowed or _same(depth, d0)
                ok_c = "color" in allowed or _same(color, c0)
            if not ok_d:
                return "WRONG-DATA", f"depth of frame {i} at {ts} ns differs"
            if not ok_c:
                return "WRONG-DATA", f"color of frame {i} at {ts} ns differs"
    if got.index is not None and exc is None:
        if got.index != stamps:
            return "INDEX-MISMATCH", f"index {got.index} != iteration {stamps}"
        assert got.stretch is not None
        if len(got.stretch) != len(frames[1:]) or not all(
            a[0] == b[0] and _same(a[1], b[1]) and _same(a[2], b[2])
            for a, b in zip(got.stretch, frames[1:], strict=False)
        ):
            return "INDEX-MISMATCH", "frames read through the index differ from iteration"
    if exc is not None:
        return "detected", f"{got.stage}: {type(exc).__name__}: {exc}"
    same = (
        got.intrinsics == clean.intrinsics
        and len(frames) == len(clean.frames)
        and all(
            a[0] == b[0] and _same(a[1], b[1]) and _same(a[2], b[2])
            for a, b in zip(frames, clean.frames, strict=True)
        )
    )
    return ("identical", "") if same else ("changed-as-allowed", "")


@dataclass
class Clean:
    fmt: str
    path: Path
    readings: dict[str, Reading]


def make_clean(fmt: str, folder: Path) -> Clean:
    """Write the clean bag of ``fmt`` under ``folder`` and read it through every view."""
    path = write_bag(fmt, build_messages(fmt), folder, f"clean-{fmt}")
    readings = {view: read_view(path, view, memory="none") for view in VIEWS}
    for view, r in readings.items():
        if r.error is not None or len(r.frames) != FRAMES:
            raise RuntimeError(f"the clean {fmt} bag does not read through {view}: {r.error!r}")
    return Clean(fmt, path, readings)


def run_case(
    clean: Clean, seed: int, case: int, folder: Path, timeout: float = 60.0, memory: str = "limit"
) -> Result:
    """Build, write and read mutant ``case`` of ``seed``; the worst outcome of its views."""
    msgs = build_messages(clean.fmt)
    mutation = mutate(clean.fmt, msgs, seed, case)
    name = f"mutant-{os.getpid()}"
    try:
        path = write_bag(clean.fmt, msgs, folder, name)
    except Exception as exc:
        return Result("unwritable", f"{mutation.what}: {type(exc).__name__}: {exc}")
    if mutation.apply_bytes is not None:
        target = storage_file(clean.fmt, path)
        target.write_bytes(mutation.apply_bytes(target.read_bytes()))
    result = Result("identical")
    with watchdog(timeout, mutation.what):
        for view in mutation.views:
            got = read_view(path, view, memory=memory)
            outcome, detail = classify(clean.readings[view], got, mutation, path)
            result.views[view] = outcome
            if outcome not in OK_OUTCOMES:
                return Result(outcome, f"{mutation.what} [{view}]: {detail}", result.views)
            if _RANK[outcome] > _RANK[result.outcome]:
                result.outcome, result.detail = outcome, f"{mutation.what} [{view}]: {detail}"
    if not result.detail:
        result.detail = mutation.what
    return result
