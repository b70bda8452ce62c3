"""Structural fuzzing of camera files: RealSense ``.bag`` and Azure Kinect ``.mkv``.

Shared by ``tests/test_fuzz_camera_files.py`` (a few hundred seeded cases) and
``tests/run_fuzz_camera_files.py`` (thousands). Small clean files are built here the way the
cameras' own software writes them (librealsense's topics in a ROS 1 bag written with rosbags;
k4arecorder's tracks, tags and attachment in a Matroska file written element by element), and
the real files under ``/work/shared/data/bags`` are used too when present.

A case changes one thing: most change a field of a message or an element (an Image's width,
step or encoding, a CameraInfo, the depth units, a stamp, the calibration JSON, a tag, a
CodecPrivate, an EBML element's size or ID, a block's payload), the rest change bytes (inside
lz4 chunks, anywhere). The mutant is opened and every frame read, and the outcome classified:

* ``identical``: the same frames as the clean file;
* ``detected``: a :class:`~pcdcodec.PcdcodecError` whose message names the file;
* ``changed-as-declared``: frames differ only in what the mutation may legitimately change
  (the file now declares big-endian depth, other stamps, another camera...);
* ``reported-drops``: frames are missing, and the reader reports as many dropped;

and failures: ``FOREIGN-EXCEPTION``, ``ERROR-WITHOUT-FILE``, ``WRONG-DATA``, ``SILENT-LOSS``,
``MEMORY`` (tracemalloc peak over a bound set by the clean file's cameras), and a hang (the
watchdog prints every thread's stack and ends the process).
"""

from __future__ import annotations

import copy
import json
import os
import resource
import struct
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec

from .recording_fuzz import watchdog

SHARED = Path(os.environ.get("PCDCODEC_SHARED_DATA", "/work/shared/data"))
REAL_BAG = SHARED / "bags" / "realsense" / "single_depth_color_640x480.bag"
REAL_MKV = SHARED / "bags" / "pyk4a_recording.mkv"

OK_OUTCOMES = ("identical", "detected", "changed-as-declared", "reported-drops")
#: what a mutation may legitimately change without an error: bytes changed in a format without
#: checksums may read as other pixels, stamps or cameras; frames lost must still be reported
ANY = frozenset({"depth", "color", "timestamps", "camera"})


@dataclass
class Result:
    outcome: str
    detail: str = ""


@dataclass
class Clean:
    """A clean camera file: how to rebuild it, its bytes and what reading it gives."""

    name: str
    kind: str  # "realsense" or "mkv"
    spec: Any
    data: bytes
    frames: list[tuple[int, Any, Any]]
    camera: tuple[Any, Any, float]
    bound: int  # bytes of memory a read may take
    regions: list[tuple[int, int, str]] = field(default_factory=list)


# -- reading and classifying --------------------------------------------------------------


def read_all(path: Path) -> tuple[list[tuple[int, Any, Any]], tuple[Any, Any, float], Any]:
    """Open ``path`` with :func:`pcdcodec.open_source` and read every frame; also what the
    source reports: ``{"dropped": {...}, "damage": str | None}``. RealSense bags pair within
    300 ms: the real bag's one color frame is 101 ms from its nearer depth frame."""
    options = {"max_difference": 300_000_000} if path.suffix == ".bag" else {}
    with pcdcodec.open_source(path, **options) as src:
        frames = [(f.timestamp_ns, f.depth, f.color) for f in src]
        camera = (src.intrinsics, src.color_intrinsics, src.depth_scale)
        report = {
            "dropped": getattr(src, "dropped", {}) or {},
            "damage": getattr(src, "damage", None),
        }
    return frames, camera, report


def _same(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b))


def classify(clean: Clean, path: Path, allow: frozenset[str]) -> Result:
    """Read the mutant at ``path`` and say what happened (see the module docstring).

    Memory is watched twice: tracemalloc sees Python's and numpy's allocations, the process's
    peak resident size also those of the libraries in C (FFmpeg, lz4)."""
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    tracemalloc.start()
    try:
        try:
            frames, camera, report = read_all(path)
        except pcdcodec.PcdcodecError as exc:
            if str(path) not in str(exc):
                return Result("ERROR-WITHOUT-FILE", f"{type(exc).__name__}: {exc}")
            return Result("detected", f"{type(exc).__name__}: {str(exc)[:200]}")
        except Exception as exc:
            return Result("FOREIGN-EXCEPTION", f"{type(exc).__name__}: {str(exc)[:300]}")
        finally:
            peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    dropped, damage = report["dropped"], report["damage"]
    if peak > clean.bound:
        return Result("MEMORY", f"peak {peak / 2**20:.1f} MiB > {clean.bound / 2**20:.1f} MiB")
    grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss_before
    if grown > clean.bound:
        return Result("MEMORY", f"peak RSS grew {grown / 2**20:.1f} MiB")
    notes = []
    if camera != clean.camera:
        if "camera" not in allow:
            return Result("WRONG-DATA", f"camera {camera} != {clean.camera}")
        notes.append("camera")
    drops = sum(dropped.values()) if isinstance(dropped, dict) else 0
    lost = len(clean.frames) - len(frames)
    if lost > 0 and "frames" not in allow and drops < lost and not damage:
        return Result("SILENT-LOSS", f"{len(frames)} of {len(clean.frames)} frames, {dropped}")
    want = {t: (d, c) for t, d, c in clean.frames}
    got_ts = [t for t, _, _ in frames]
    if got_ts != [t for t, _, _ in clean.frames] and "timestamps" not in allow:
        missing = [t for t in want if t not in got_ts]
        extra = [t for t in got_ts if t not in want]
        if extra or (missing and "frames" not in allow and drops < len(missing) and not damage):
            return Result(
                "SILENT-LOSS" if not extra else "WRONG-DATA",
                f"timestamps {got_ts} != {list(want)}, dropped {dropped}",
            )
        if missing:
            notes.append("frames")
    for t, d, c in frames:
        if t in want and "timestamps" not in allow:
            wd, wc = want[t]
            if not _same(d, wd) and "depth" not in allow:
                return Result("WRONG-DATA", f"depth at {t} differs")
            if not _same(c, wc) and "color" not in allow:
                return Result("WRONG-DATA", f"color at {t} differs")
            if not (_same(d, wd) and _same(c, wc)):
                notes.append("pixels")
        else:
            # other stamps: the images must still be images of the clean file
            if not any(_same(d, wd) for _, wd, _ in clean.frames) and "depth" not in allow:
                return Result("WRONG-DATA", f"depth at {t} is none of the clean file's")
            if not any(_same(c, wc) for _, _, wc in clean.frames) and "color" not in allow:
                return Result("WRONG-DATA", f"color at {t} is none of the clean file's")
            notes.append("stamps")
    if len(frames) < len(clean.frames) and (damage or any(dropped.values())):
        return Result("reported-drops", f"{len(frames)} frames, dropped {dropped}, {damage}")
    if not notes:
        return Result("identical")
    return Result("changed-as-declared", ", ".join(sorted(set(notes))))


def run_case(clean: Clean, seed: int, case: int, folder: Path, timeout: float = 60.0) -> Result:
    """Build case ``case`` of ``seed`` of ``clean``, read it, and classify the outcome."""
    data, what, allow = mutate(clean, seed, case)
    suffix = ".bag" if clean.kind == "realsense" else ".mkv"
    path = folder / f"mutant-{os.getpid()}{suffix}"
    path.write_bytes(data)
    with watchdog(timeout, what):
        result = classify(clean, path, allow)
    result.detail = f"{what}: {result.detail}"
    return result


def mutate(clean: Clean, seed: int, case: int) -> tuple[bytes, str, frozenset[str]]:
    """The mutant's bytes, a description to reproduce it by, and what it may change."""
    rng = np.random.default_rng([seed, case])
    if clean.kind == "realsense":
        mutators = RS_MUTATORS
    else:
        mutators = MKV_MUTATORS if clean.spec is not None else REAL_MKV_MUTATORS
    names = list(mutators)
    weights = np.array([mutators[n][0] for n in names], dtype=float)
    name = names[int(rng.choice(len(names), p=weights / weights.sum()))]
    data, what, allow = mutators[name][1](clean, rng)
    return data, f"{clean.name} case {case} seed {seed} ({name}): {what}", allow


def _bound(cameras: list[tuple[int, int, int]], file_size: int) -> int:
    """Memory a read may take: a few frames of each declared camera, the file, and a margin."""
    frames = sum(w * h * c for w, h, c in cameras)
    return 24 * frames + 4 * file_size + 48 * 2**20


def _pick(rng: np.random.Generator, items: list[Any]) -> Any:
    return items[int(rng.integers(len(items)))]


def _bytes_op(data: bytes, rng: np.random.Generator, lo: int, hi: int) -> tuple[bytes, str]:
    """Flip, overwrite, zero, truncate, delete or duplicate bytes of ``data[lo:hi]``."""
    out = bytearray(data)
    pos = int(rng.integers(lo, max(lo + 1, hi)))
    op = _pick(rng, ["flip", "overwrite", "zero", "truncate", "delete", "insert"])
    if op == "flip":
        for _ in range(int(rng.integers(1, 4))):
            p = min(len(out) - 1, pos + int(rng.integers(0, 8)))
            out[p] ^= 1 << int(rng.integers(8))
    elif op == "overwrite":
        size = int(rng.integers(1, 9))
        out[pos : pos + size] = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        del out[len(data) :]
    elif op == "zero":
        size = int(rng.integers(1, 33))
        out[pos : pos + size] = bytes(len(out[pos : pos + size]))
    elif op == "truncate":
        del out[pos:]
    elif op == "delete":
        del out[pos : pos + int(rng.integers(1, 65))]
    else:
        src = int(rng.integers(0, len(data)))
        out[pos:pos] = data[src : src + int(rng.integers(1, 129))]
    return bytes(out), f"{op} at {pos}"


# == RealSense .bag ========================================================================

_RS_DEPTH = "/device_0/sensor_0/Depth_0"
_RS_COLOR = "/device_0/sensor_1/Color_0"
_RS_UNITS = "/device_0/sensor_0/option/Depth Units/value"


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC)


@dataclass
class BagRecord:
    topic: str
    msgtype: str
    time: int
    msg: Any


@dataclass
class BagSpec:
    records: list[BagRecord]
    compression: str  # "", "lz4" or "bz2"


def _header(ts: Any, stamp_ns: int) -> Any:
    t = ts.types
    stamp = t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="0")


def rs_image(ts: Any, stamp_ns: int, pixels: np.ndarray, encoding: str) -> Any:
    """An Image message as librealsense writes it (rows packed, little-endian)."""
    h, w = pixels.shape[:2]
    data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
    return ts.types["sensor_msgs/msg/Image"](
        header=_header(ts, stamp_ns),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=data.size // h,
        data=data.copy(),
    )


def rs_camera_info(ts: Any, w: int, h: int, f: float) -> Any:
    t = ts.types
    return t["sensor_msgs/msg/CameraInfo"](
        header=_header(ts, 0),
        height=h,
        width=w,
        distortion_model="Brown Conrady",
        D=np.zeros(5),
        K=np.array([f, 0, w / 2, 0, f, h / 2, 0, 0, 1], dtype=np.float64),
        R=np.eye(3).ravel(),
        P=np.zeros(12),
        binning_x=0,
        binning_y=0,
        roi=t["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        ),
    )


def rs_transform(ts: Any, x: float) -> Any:
    t = ts.types
    return t["geometry_msgs/msg/Transform"](
        translation=t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
        rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )


def rs_spec(
    depth_size: tuple[int, int] = (8, 6),
    color_size: tuple[int, int] = (10, 8),
    frames: int = 3,
    compression: str = "lz4",
    color_encoding: str = "rgb8",
) -> BagSpec:
    """A small RealSense-style bag: librealsense's topics, ``frames`` depth and color images."""
    ts = _typestore()
    t = ts.types
    rng = np.random.default_rng(7)
    (dw, dh), (cw, ch) = depth_size, color_size
    recs = [
        BagRecord("/file_version", "std_msgs/msg/UInt32", 1, t["std_msgs/msg/UInt32"](data=3)),
        BagRecord(
            "/device_0/info",
            "diagnostic_msgs/msg/KeyValue",
            1,
            t["diagnostic_msgs/msg/KeyValue"](key="Name", value="Intel RealSense D435"),
        ),
        BagRecord(_RS_UNITS, "std_msgs/msg/Float32", 1, t["std_msgs/msg/Float32"](data=0.001)),
        BagRecord(
            f"{_RS_DEPTH}/info/camera_info",
            "sensor_msgs/msg/CameraInfo",
            1,
            rs_camera_info(ts, dw, dh, 5.0),
        ),
        BagRecord(
            f"{_RS_COLOR}/info/camera_info",
            "sensor_msgs/msg/CameraInfo",
            1,
            rs_camera_info(ts, cw, ch, 6.0),
        ),
    ]
    for k in range(frames):
        stamp = 1_000_000_000 + k * 33_000_000
        depth = rng.integers(0, 4000, (dh, dw)).astype("<u2")
        color = rng.integers(0, 256, (ch, cw, 3)).astype(np.uint8)
        if color_encoding == "mjpeg":
            import cv2

            ok, jpeg = cv2.imencode(".jpg", color[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 90])
            assert ok
            img = rs_image(ts, stamp + 1_000_000, color, "rgb8")
            img.encoding, img.step, img.data = "mjpeg", 0, jpeg.reshape(-1).copy()
        else:
            img = rs_image(ts, stamp + 1_000_000, color, color_encoding)
        recs.append(
            BagRecord(
                f"{_RS_DEPTH}/image/data",
                "sensor_msgs/msg/Image",
                stamp,
                rs_image(ts, stamp, depth, "mono16"),
            )
        )
        recs.append(
            BagRecord(f"{_RS_COLOR}/image/data", "sensor_msgs/msg/Image", stamp + 1_000_000, img)
        )
        if k == 0:
            recs += [
                BagRecord(
                    f"{_RS_DEPTH}/tf/0", "geometry_msgs/msg/Transform", stamp, rs_transform(ts, 0)
                ),
                BagRecord(
                    f"{_RS_COLOR}/tf/0",
                    "geometry_msgs/msg/Transform",
                    stamp,
                    rs_transform(ts, 0.015),
                ),
            ]
    return BagSpec(recs, compression)


def write_bag(spec: BagSpec, path: Path, raw_types: dict[str, str] | None = None) -> None:
    """Write ``spec`` as a ROS 1 bag; ``raw_types`` gives a topic's connection another type
    (its messages are still written as their own type)."""
    from rosbags.rosbag1 import Writer

    ts = _typestore()
    path.unlink(missing_ok=True)
    writer = Writer(path)
    if spec.compression:
        writer.set_compression(Writer.CompressionFormat[spec.compression.upper()])
    writer.chunk_threshold = 4096
    with writer:
        conns: dict[str, Any] = {}
        for rec in spec.records:
            if rec.topic not in conns:
                msgtype = (raw_types or {}).get(rec.topic, rec.msgtype)
                conns[rec.topic] = writer.add_connection(rec.topic, msgtype, typestore=ts)
            writer.write(conns[rec.topic], rec.time, ts.serialize_ros1(rec.msg, rec.msgtype))


def rs_spec_from(path: Path) -> BagSpec:
    """The records of a real RealSense bag, deserialized (compression lz4 as librealsense's)."""
    from rosbags.rosbag1 import Reader

    ts = _typestore()
    recs = []
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            if conn.msgtype not in ts.types:  # realsense_msgs: not read by the reader
                continue
            msg = ts.deserialize_ros1(raw, conn.msgtype)
            recs.append(BagRecord(conn.topic, conn.msgtype, t, msg))
    return BagSpec(recs, "lz4")


def make_clean_realsense(name: str, folder: Path) -> Clean:
    """Build (or, for ``"real"``, rebuild from the real file) and read one clean bag."""
    if name == "real":
        spec = rs_spec_from(REAL_BAG)
        # Its one color frame pairs with one of its two depth frames; a copy beside the other
        # makes every image of the clean file part of a frame, so a mutant's frames are too.
        images = _images(spec)
        color = next(r for r in images if "Color" in r.topic)
        depth = [r for r in images if "Depth" in r.topic][-1]
        copy_ = copy.deepcopy(color)
        copy_.time = depth.time + 1
        stamp = depth.msg.header.stamp
        copy_.msg.header.stamp.sec, copy_.msg.header.stamp.nanosec = stamp.sec, stamp.nanosec
        spec.records.insert(spec.records.index(depth) + 1, copy_)
    elif name == "uncompressed":
        spec = rs_spec(compression="")
    elif name == "mjpeg":
        spec = rs_spec(color_encoding="mjpeg", compression="")
    else:
        spec = rs_spec()
    path = folder / f"clean-rs-{name}.bag"
    write_bag(spec, path)
    frames, camera, _ = read_all(path)
    if not frames:
        raise RuntimeError(f"{path} gives no frames")
    cams = [(c.width, c.height, 3) for c in camera[:2] if c is not None]
    data = path.read_bytes()
    return Clean(
        name, "realsense", spec, data, frames, camera, _bound(cams, len(data)), _bag_regions(data)
    )


def _bag_regions(data: bytes) -> list[tuple[int, int, str]]:
    """(start, end, kind) of a ROS 1 bag's records: record headers and chunk data."""
    out = []
    pos = len(b"#ROSBAG V2.0\n")
    while pos + 4 <= len(data):
        (hlen,) = struct.unpack_from("<I", data, pos)
        if pos + 8 + hlen > len(data):
            break
        (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
        out.append((pos, pos + 4 + hlen, "record-header"))
        out.append((pos + 8 + hlen, min(len(data), pos + 8 + hlen + dlen), "record-data"))
        pos += 8 + hlen + dlen
    return out


def _images(spec: BagSpec, kind: str | None = None) -> list[BagRecord]:
    return [
        r
        for r in spec.records
        if r.topic.endswith("/image/data") and (kind is None or f"/{kind}_" in r.topic)
    ]


_INTS = [0, 1, 2, 3, 7, 9, 11, 12, 16, 20, 24, 31, 640, 2**16, 2**31 - 1, 2**32 - 1]


def _rs_image_field(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    kind = _pick(rng, ["Depth", "Color"])
    rec = _pick(rng, _images(spec, kind))
    msg = rec.msg
    fld = _pick(rng, ["width", "height", "step", "encoding", "is_bigendian", "data", "padded"])
    allow: frozenset[str] = frozenset()
    if fld in ("width", "height", "step"):
        old = getattr(msg, fld)
        value = _pick(rng, [*_INTS, old + 1, old - 1, old * 2, old // 2])
        value = max(0, min(value, 2**32 - 1))
        setattr(msg, fld, value)
        what = f"{rec.topic} at {rec.time}: {fld} {old} -> {value}"
    elif fld == "encoding":
        value = _pick(
            rng,
            [
                "mono16",
                "16UC1",
                "MONO16",
                "z16",
                "rgb8",
                "bgr8",
                "rgba8",
                "bgra8",
                "mono8",
                "yuv422",
                "32FC1",
                "mjpeg",
                "",
                "rgb8\x00",
            ],
        )
        what = f"{rec.topic} at {rec.time}: encoding {msg.encoding!r} -> {value!r}"
        msg.encoding = value
        if kind == "Color" and value.lower() in ("bgr8", "bgra8", "rgba8"):
            allow = frozenset({"color"})  # the file now declares other channels
    elif fld == "is_bigendian":
        value = int(_pick(rng, [0, 1, 2, 255]))
        what = f"{rec.topic} at {rec.time}: is_bigendian {msg.is_bigendian} -> {value}"
        if kind == "Depth" and bool(value) != bool(msg.is_bigendian):
            allow = frozenset({"depth"})
        msg.is_bigendian = value
    elif fld == "data":
        n = len(msg.data)
        value = _pick(rng, [0, 1, n - 1, n + 1, n // 2, n * 2])
        msg.data = np.resize(msg.data, max(0, value)).astype(np.uint8)
        what = f"{rec.topic} at {rec.time}: data {n} -> {value} bytes"
    else:  # each row padded, step to match: the same pixels
        h, step = int(msg.height), int(msg.step)
        if step == 0 or str(msg.encoding) == "mjpeg":
            return _rs_image_field(clean, rng)
        pad = int(rng.integers(1, 9))
        rows = np.asarray(msg.data).reshape(h, step)
        extra = rng.integers(0, 256, (h, pad)).astype(np.uint8)
        msg.data = np.concatenate([rows, extra], axis=1).reshape(-1)
        msg.step = step + pad
        what = f"{rec.topic} at {rec.time}: rows padded by {pad} bytes"
    return _rs_bytes(spec, clean), what, allow


def _rs_bytes(spec: BagSpec, clean: Clean, raw_types: dict[str, str] | None = None) -> bytes:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.bag"
        write_bag(spec, path, raw_types)
        return path.read_bytes()


def _by_topic(spec: BagSpec, end: str) -> list[BagRecord]:
    return [r for r in spec.records if r.topic.endswith(end)]


_FLOATS = [0.0, -1.0, 1e-45, 1e38, float("nan"), float("inf"), -float("inf"), 1e-3, 0.0001, 5e3]


def _rs_camera_info(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    rec = _pick(rng, _by_topic(spec, "/info/camera_info"))
    msg = rec.msg
    fld = _pick(rng, ["width", "height", "K", "D", "D-length", "distortion_model"])
    allow = frozenset({"camera"})
    if fld in ("width", "height"):
        old = getattr(msg, fld)
        value = _pick(rng, [*_INTS, old + 1, old - 1])
        setattr(msg, fld, value)
        what = f"{rec.topic}: {fld} {old} -> {value}"
    elif fld in ("K", "D"):
        arr = np.array(getattr(msg, fld), dtype=np.float64)
        if arr.size == 0:
            arr = np.zeros(5)
        i = int(rng.integers(arr.size))
        arr[i] = _pick(rng, _FLOATS)
        setattr(msg, fld, arr)
        what = f"{rec.topic}: {fld}[{i}] -> {arr[i]}"
    elif fld == "D-length":
        n = int(_pick(rng, [0, 1, 4, 6, 8, 12, 14, 100]))
        msg.D = rng.normal(0, 0.1, n)
        what = f"{rec.topic}: D of {n} values"
    else:
        value = _pick(
            rng,
            [
                "plumb_bob",
                "Brown Conrady",
                "Inverse Brown Conrady",
                "equidistant",
                "Kannala Brandt4",
                "rational_polynomial",
                "",
                "unknown",
            ],
        )
        msg.distortion_model = value
        what = f"{rec.topic}: distortion_model -> {value!r}"
    return _rs_bytes(spec, clean), what, allow


def _rs_units(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    rec = _by_topic(spec, "Depth Units/value")[0]
    value = _pick(rng, _FLOATS)
    rec.msg.data = value
    return _rs_bytes(spec, clean), f"depth units -> {value}", frozenset({"camera"})


def _rs_stamp(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    rec = _pick(rng, _images(spec))
    stamp = rec.msg.header.stamp
    if rng.random() < 0.5:
        stamp.nanosec = int(_pick(rng, [0, 1, 999_999_999, 10**9, 2**31 - 1]))
        what = f"{rec.topic} at {rec.time}: nanosec -> {stamp.nanosec}"
    else:
        stamp.sec = int(_pick(rng, [0, 1, 2, 2**31 - 1]))
        what = f"{rec.topic} at {rec.time}: sec -> {stamp.sec}"
    return _rs_bytes(spec, clean), what, frozenset({"timestamps"})


def _rs_tf(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    rec = _pick(rng, _by_topic(spec, "/tf/0"))
    part, axis = _pick(rng, [("translation", "x"), ("rotation", "x"), ("rotation", "w")])
    value = _pick(rng, _FLOATS)
    setattr(getattr(rec.msg, part), axis, value)
    if part == "rotation" and rng.random() < 0.5:
        for a in "xyzw":
            setattr(rec.msg.rotation, a, 0.0)
        what = f"{rec.topic}: zero quaternion"
    else:
        what = f"{rec.topic}: {part}.{axis} -> {value}"
    return _rs_bytes(spec, clean), what, frozenset({"camera"})


def _rs_topics(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    """Leave a topic out, or give its connection another message type."""
    spec = copy.deepcopy(clean.spec)
    topics = sorted(
        {r.topic for r in spec.records if "/option/" not in r.topic or "Units" in r.topic}
    )
    topic = _pick(rng, topics)
    if rng.random() < 0.5:
        spec.records = [r for r in spec.records if r.topic != topic]
        # without color the frames lose their color: the file now declares no color stream
        return _rs_bytes(spec, clean), f"without {topic}", frozenset({"color", "camera"})
    other = _pick(
        rng,
        [
            "sensor_msgs/msg/CompressedImage",
            "std_msgs/msg/Float32",
            "sensor_msgs/msg/CameraInfo",
            "std_msgs/msg/String",
        ],
    )
    return _rs_bytes(spec, clean, {topic: other}), f"{topic} typed {other}", frozenset()


def _rs_raw(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    """Bytes changed: in a record's data (chunks: lz4 or plain messages), its header, anywhere."""
    kind = _pick(rng, ["record-data", "record-header", "anywhere"])
    spans = [(a, b) for a, b, k in clean.regions if k == kind and b > a]
    a, b = _pick(rng, spans) if spans and kind != "anywhere" else (0, len(clean.data))
    data, what = _bytes_op(clean.data, rng, a, b)
    # A bag has no checksums: changed message bytes may read as other pixels or stamps.
    return data, f"{kind}: {what}", ANY


RS_MUTATORS: dict[str, tuple[float, Callable[[Clean, np.random.Generator], Any]]] = {
    "image-field": (0.3, _rs_image_field),
    "camera-info": (0.12, _rs_camera_info),
    "depth-units": (0.05, _rs_units),
    "stamp": (0.1, _rs_stamp),
    "tf": (0.06, _rs_tf),
    "topics": (0.07, _rs_topics),
    "bytes": (0.3, _rs_raw),
}
RS_CLEANS = ("lz4", "uncompressed", "mjpeg", "real")


# == Azure Kinect .mkv =====================================================================

#: a Matroska element: (ID with its marker bits, payload bytes or child elements, size override)
El = list  # [id, bytes | list[El]] or [id, value, size_override]

_MASTERS = {
    0x1A45DFA3,
    0x18538067,
    0x1549A966,
    0x1654AE6B,
    0xAE,
    0xE0,
    0x1941A469,
    0x61A7,
    0x1254C367,
    0x7373,
    0x63C0,
    0x67C8,
    0x1F43B675,
}


def _uint(v: int) -> bytes:
    return v.to_bytes(max(1, (v.bit_length() + 7) // 8), "big")


def _id_bytes(eid: int) -> bytes:
    return eid.to_bytes(max(1, (eid.bit_length() + 7) // 8), "big")


def serialize(el: list[Any]) -> bytes:
    eid, value = el[0], el[1]
    body = b"".join(serialize(c) for c in value) if isinstance(value, list) else bytes(value)
    size = len(body) if len(el) < 3 or el[2] is None else el[2]
    if size == -1:  # unknown size
        head = b"\x01\xff\xff\xff\xff\xff\xff\xff"
    else:
        head = b"\x01" + (size & (2**56 - 1)).to_bytes(7, "big")
    return _id_bytes(eid) + head + body


def _bih(w: int, h: int, bits: int, fourcc: bytes, image: int) -> bytes:
    return struct.pack("<IiiHH4sIiiII", 40, w, h, 1, bits, fourcc, image, 0, 0, 0, 0)


def _track(num: int, uid: int, name: str, private: bytes, w: int, h: int) -> list[Any]:
    return [
        0xAE,
        [
            [0xD7, _uint(num)],
            [0x73C5, _uint(uid)],
            [0x83, b"\x01"],
            [0x86, b"V_MS/VFW/FOURCC"],
            [0x536E, name.encode()],
            [0x63A2, private],
            [0x23E383, _uint(33_333_333)],
            [0xE0, [[0xB0, _uint(w)], [0xBA, _uint(h)]]],
        ],
    ]


def _tag(name: str, value: str, track_uid: int | None = None) -> list[Any]:
    targets: list[Any] = []
    if track_uid is not None:
        targets = [[0x63CA, b"TRACK"], [0x63C5, _uint(track_uid)]]
    return [
        0x7373,
        [[0x63C0, targets], [0x67C8, [[0x45A3, name.encode()], [0x4487, value.encode()]]]],
    ]


def k4a_calibration() -> dict[str, Any]:
    """A calibration.json like a device's: a depth camera and a color camera."""

    def cam(purpose: str, w: int, h: int, params: list[float], t: list[float]) -> dict[str, Any]:
        return {
            "Intrinsics": {
                "ModelParameterCount": 14,
                "ModelParameters": params,
                "ModelType": "CALIBRATION_LensDistortionModelBrownConrady",
            },
            "Location": purpose.split("Purpose")[1],
            "Purpose": purpose,
            "MetricRadius": 1.7,
            "Rt": {
                "Rotation": [1.0, 0.0, 0.0, 0.0, 0.9999, -0.0141, 0.0, 0.0141, 0.9999],
                "Translation": t,
            }
            if t[0]
            else {"Rotation": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], "Translation": t},
            "SensorHeight": h,
            "SensorWidth": w,
            "Shutter": "CALIBRATION_ShutterTypeUndefined",
            "ThermalAdjustmentParams": {"Params": [0.0] * 12},
        }

    return {
        "CalibrationInformation": {
            "Cameras": [
                cam(
                    "CALIBRATION_CameraPurposeDepth",
                    1024,
                    1024,
                    [
                        0.513,
                        0.517,
                        0.4928,
                        0.4929,
                        4.1,
                        2.6,
                        0.13,
                        4.4,
                        3.8,
                        0.69,
                        0.0,
                        0.0,
                        -3e-5,
                        2e-5,
                    ],
                    [0.0, 0.0, 0.0],
                ),
                cam(
                    "CALIBRATION_CameraPurposePhotoVideo",
                    4096,
                    3072,
                    [
                        0.4998,
                        0.5066,
                        0.478,
                        0.6374,
                        0.5,
                        -2.7,
                        1.6,
                        0.4,
                        -2.5,
                        1.5,
                        0.0,
                        0.0,
                        7e-4,
                        -3e-4,
                    ],
                    [-0.032, -0.002, 0.004],
                ),
            ],
            "Metadata": {"SerialId": "000000000000", "Version": {"Major": 1, "Minor": 2}},
        }
    }


@dataclass
class MkvSpec:
    """The elements of a k4arecorder-like file, before they are written."""

    calibration: Any
    tags: dict[str, str]
    tracks: list[list[Any]]
    clusters: list[list[Any]]
    calibration_text: str | None = None  # written as is instead of ``calibration``

    def elements(self) -> list[list[Any]]:
        text = self.calibration_text
        if text is None:
            text = json.dumps(self.calibration)
        ebml = [
            0x1A45DFA3,
            [
                [0x4286, b"\x01"],
                [0x42F7, b"\x01"],
                [0x42F2, b"\x04"],
                [0x42F3, b"\x08"],
                [0x4282, b"matroska"],
                [0x4287, b"\x04"],
                [0x4285, b"\x02"],
            ],
        ]
        info = [
            0x1549A966,
            [
                [0x2AD7B1, _uint(1000)],
                [0x4D80, b"pcdcodec-tests"],
                [0x5741, b"k4arecord-1.4.1"],
                [0x7BA9, b"Azure Kinect"],
            ],
        ]
        attach = [
            0x1941A469,
            [
                [
                    0x61A7,
                    [
                        [0x466E, b"calibration.json"],
                        [0x4660, b"application/octet-stream"],
                        [0x465C, text.encode()],
                        [0x46AE, _uint(0x1234567)],
                    ],
                ]
            ],
        ]
        uids = {el[1][1][1]: el for el in self.tracks}
        color_uid, depth_uid = list(uids)[:2]
        tags = []
        for k, v in self.tags.items():
            uid = (
                color_uid
                if k.startswith("K4A_COLOR_")
                else depth_uid
                if k.startswith("K4A_DEPTH_MODE")
                else None
            )
            tags.append(_tag(k, v, None if uid is None else int.from_bytes(uid, "big")))
        segment = [
            0x18538067,
            [info, [0x1654AE6B, self.tracks], attach, [0x1254C367, tags], *self.clusters],
        ]
        return [ebml, segment]

    def to_bytes(self) -> bytes:
        return b"".join(serialize(e) for e in self.elements())


def _block(track: int, rel: int, payload: bytes) -> list[Any]:
    return [0xA3, bytes([0x80 | track]) + struct.pack(">hB", rel, 0x80) + payload]


def mkv_spec(captures: int = 3) -> MkvSpec:
    """A small Azure Kinect recording: MJPEG 1280x720 color, NFOV 2x2 binned depth (320x288)."""
    import cv2

    rng = np.random.default_rng(11)
    yy, xx = np.mgrid[0:720, 0:1280]
    clusters = []
    for k in range(captures):
        img = np.stack([(xx // 5 + 40 * k) % 256, (yy // 3) % 256, (xx + yy) // 8 % 256], -1)
        ok, jpeg = cv2.imencode(".jpg", img.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 70])
        assert ok
        depth = rng.integers(0, 5000, (288, 320)).astype(">u2").tobytes()
        clusters.append(
            [
                0x1F43B675,
                [[0xE7, _uint(k * 33_333)], _block(1, 0, jpeg.tobytes()), _block(2, 0, depth)],
            ]
        )
    tracks = [
        _track(
            1,
            0x0324_4080_9F71_DFD2,
            "COLOR",
            _bih(1280, 720, 24, b"MJPG", 1280 * 720 * 3),
            1280,
            720,
        ),
        _track(
            2, 0x0651_47E6_D36F_4632, "DEPTH", _bih(320, 288, 16, b"b16g", 320 * 288 * 2), 320, 288
        ),
    ]
    tags = {
        "K4A_COLOR_MODE": "MJPG_720P",
        "K4A_DEPTH_MODE": "NFOV_2X2BINNED",
        "K4A_DEVICE_SERIAL_NUMBER": "000000000000",
        "K4A_START_OFFSET_NS": "336277000",
    }
    return MkvSpec(k4a_calibration(), tags, tracks, clusters)


def make_clean_mkv(name: str, folder: Path) -> Clean:
    """Build (or take the real file) and read one clean ``.mkv``."""
    path = folder / f"clean-{name}.mkv"
    if name == "real":
        data = REAL_MKV.read_bytes()
        spec = None
    else:
        spec = mkv_spec()
        data = spec.to_bytes()
    path.write_bytes(data)
    frames, camera, _ = read_all(path)
    if not frames:
        raise RuntimeError(f"{path} gives no frames")
    cams = [(c.width, c.height, 3) for c in camera[:2] if c is not None]
    return Clean(name, "mkv", spec, data, frames, camera, _bound(cams, len(data)))


_JSON_VALUES = [
    None,
    "x",
    "",
    0,
    -1,
    1e308,
    float("nan"),
    float("inf"),
    [],
    {},
    [1.0],
    True,
    [0.5] * 20,
    "0.5",
]


def _json_paths(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [path]
    if isinstance(value, dict):
        for k, v in value.items():
            out += _json_paths(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += _json_paths(v, (*path, i))
    return out


def _mkv_calibration(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    cal = spec.calibration
    op = _pick(rng, ["set", "set", "drop", "resize", "text"])
    if op == "text":
        text = json.dumps(cal)
        cut = int(rng.integers(0, len(text)))
        spec.calibration_text = _pick(
            rng,
            [
                text[:cut],
                text[:cut] + "}" + text[cut:],
                "",
                "null",
                "[]",
                '{"CalibrationInformation": null}',
            ],
        )
        return spec.to_bytes(), "calibration text changed", frozenset({"camera"})
    paths = [p for p in _json_paths(cal) if p]
    # Aim at the fields the reader reads most of the time.
    wanted = [
        p
        for p in paths
        if any(k in p for k in ("ModelParameters", "Rt", "Purpose", "SensorWidth", "SensorHeight"))
    ]
    path = _pick(rng, wanted if wanted and rng.random() < 0.8 else paths)
    parent = cal
    for k in path[:-1]:
        parent = parent[k]
    last = path[-1]
    if op == "set":
        value = _pick(rng, _JSON_VALUES)
        parent[last] = value
        what = f"{list(path)} -> {value!r}"
    elif op == "drop":
        del parent[last]
        what = f"{list(path)} removed"
    else:
        target = parent[last]
        if not isinstance(target, list):
            parent[last] = [target]
            what = f"{list(path)} -> a list"
        else:
            n = int(_pick(rng, [0, 1, 3, 8, 13, 15, 20]))
            parent[last] = (target * 20)[:n] if target else [0.5] * n
            what = f"{list(path)} of {n} values"
    # Another calibration is another camera; frames stay the same.
    return spec.to_bytes(), f"calibration {op}: {what}", frozenset({"camera"})


def _mkv_tags(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    key = _pick(
        rng, ["K4A_START_OFFSET_NS", "K4A_DEPTH_MODE", "K4A_COLOR_MODE", "K4A_DEVICE_SERIAL_NUMBER"]
    )
    values = {
        "K4A_START_OFFSET_NS": [
            "",
            "-5",
            "abc",
            "1e9",
            "99999999999999999999",
            " 12",
            "0",
            "١٢",
            "12.5",
            "0x10",
        ],
        "K4A_DEPTH_MODE": [
            "NFOV_UNBINNED",
            "WFOV_2X2BINNED",
            "PASSIVE_IR",
            "",
            "nfov_2x2binned",
            "NFOV_2X2BINNED\x00",
        ],
        "K4A_COLOR_MODE": ["", "NV12_720P", "garbage"],
        "K4A_DEVICE_SERIAL_NUMBER": ["", "\x00" * 3, "x" * 300],
    }[key]
    if rng.random() < 0.2:
        spec.tags.pop(key)
        what = f"tag {key} removed"
    else:
        value = _pick(rng, values)
        spec.tags[key] = value
        what = f"tag {key} -> {value!r}"
    # another start offset moves every frame; the serial is metadata only
    return spec.to_bytes(), what, frozenset({"timestamps"})


def _mkv_track(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    t = int(rng.integers(len(spec.tracks)))
    fields = spec.tracks[t][1]
    byid = {el[0]: el for el in fields}
    what_field = _pick(
        rng,
        [
            "CodecPrivate",
            "CodecPrivate",
            "fourcc",
            "bih-size",
            "CodecID",
            "Name",
            "PixelWidth",
            "TrackNumber",
        ],
    )
    if what_field == "CodecPrivate":
        old = byid[0x63A2][1]
        value = _pick(
            rng,
            [
                b"",
                old[:16],
                old[:39],
                old + b"\x00" * 8,
                rng.integers(0, 256, 40, dtype=np.uint8).tobytes(),
            ],
        )
        byid[0x63A2][1] = value
        what = f"track {t} CodecPrivate of {len(value)} bytes"
    elif what_field == "fourcc":
        fourcc = _pick(rng, [b"MJPG", b"b16g", b"NV12", b"YUY2", b"H264", b"\x00" * 4, b"BGRA"])
        old = bytearray(byid[0x63A2][1])
        old[16:20] = fourcc
        byid[0x63A2][1] = bytes(old)
        what = f"track {t} FOURCC -> {fourcc!r}"
    elif what_field == "bih-size":
        old = bytearray(byid[0x63A2][1])
        w, h = (int(_pick(rng, [0, 1, 320, 1280, 4096, 65535, -1])) for _ in range(2))
        struct.pack_into("<ii", old, 4, w, h)
        byid[0x63A2][1] = bytes(old)
        what = f"track {t} BITMAPINFOHEADER {w}x{h}"
    elif what_field == "CodecID":
        value = _pick(rng, [b"V_MJPEG", b"V_UNCOMPRESSED", b"", b"V_MS/VFW/FOURC"])
        byid[0x86][1] = value
        what = f"track {t} CodecID -> {value!r}"
    elif what_field == "Name":
        value = _pick(rng, [b"DEPTH", b"COLOR", b"IR", b""])
        byid[0x536E][1] = value
        what = f"track {t} Name -> {value!r}"
    elif what_field == "PixelWidth":
        value = int(_pick(rng, [0, 1, 320, 1280, 65535, 2**31]))
        byid[0xE0][1][0][1] = _uint(value)
        what = f"track {t} PixelWidth -> {value}"
    else:
        value = int(_pick(rng, [0, 1, 2, 3, 127]))
        byid[0xD7][1] = _uint(value)
        what = f"track {t} TrackNumber -> {value}"
    return spec.to_bytes(), what, frozenset()


def _all_elements(els: list[Any]) -> list[list[Any]]:
    out = []
    for el in els:
        out.append(el)
        if isinstance(el[1], list):
            out += _all_elements(el[1])
    return out


def _mkv_ebml(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    """An element's size or ID changed."""
    spec = copy.deepcopy(clean.spec)
    elements = spec.elements()
    flat = _all_elements(elements)
    i = int(rng.integers(len(flat)))
    el = flat[i]
    length = len(serialize(el)) - len(_id_bytes(el[0])) - 8
    if rng.random() < 0.6:
        size = int(
            _pick(
                rng, [0, 1, length - 1, length + 1, length // 2, length * 2, 2**31, 2**56 - 2, -1]
            )
        )
        el[2:] = [size]
        what = f"element {i} (0x{el[0]:X}) size {length} -> {size}"
    else:
        other = int(
            _pick(
                rng,
                [
                    0xEC,
                    0xBF,
                    0x1F43B675,
                    0x1A45DFA3,
                    0xA3,
                    0x4286,
                    0x80,
                    0xFF,
                    0x18538067,
                    0x1654AE6B,
                ],
            )
        )
        what = f"element {i} (0x{el[0]:X}) ID -> 0x{other:X}"
        el[0] = other
    # A damaged block structure may leave a capture with other pixels (JPEG has no checksum).
    return b"".join(serialize(e) for e in elements), what, ANY


def _blocks(spec: MkvSpec) -> list[tuple[int, int, list[Any]]]:
    """(cluster, index in the cluster, SimpleBlock element) of every block."""
    out = []
    for c, cl in enumerate(spec.clusters):
        for j, el in enumerate(cl[1]):
            if el[0] == 0xA3:
                out.append((c, j, el))
    return out


def _mkv_block(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    spec = copy.deepcopy(clean.spec)
    c, j, el = _pick(rng, _blocks(spec))
    head, payload = el[1][:4], el[1][4:]
    track = head[0] & 0x7F
    op = _pick(
        rng,
        [
            "cut",
            "cut",
            "extend",
            "drop",
            "duplicate",
            "timecode",
            "flip-entropy",
            "flip-header",
            "zero-tail",
        ],
    )
    allow: frozenset[str] = frozenset()
    if op == "cut":
        n = int(rng.integers(0, len(payload)))
        el[1] = head + payload[:n]
        what = f"block {c}/{j} (track {track}) cut to {n} of {len(payload)} bytes"
    elif op == "extend":
        el[1] = head + payload + bytes(int(rng.integers(1, 64)))
        what = f"block {c}/{j} (track {track}) extended"
    elif op == "drop":
        del spec.clusters[c][1][j]
        what = f"block {c}/{j} (track {track}) removed"
    elif op == "duplicate":
        spec.clusters[c][1].insert(j, list(el))
        what = f"block {c}/{j} (track {track}) twice"
    elif op == "timecode":
        rel = int(_pick(rng, [1, -1, 100, 32767, -32768]))
        el[1] = head[:1] + struct.pack(">h", rel) + head[3:] + payload
        what = f"block {c}/{j} (track {track}) timecode +{rel}"
        allow = frozenset({"timestamps", "frames"})
    elif op == "flip-entropy":
        # inside the data: a JPEG cannot tell (no checksum), depth is raw
        p = int(rng.integers(len(payload) // 2, len(payload) - 2))
        b = bytearray(payload)
        b[p] ^= 1 << int(rng.integers(8))
        el[1] = head + bytes(b)
        what = f"block {c}/{j} (track {track}) bit flipped at {p}"
        allow = frozenset({"color", "depth"})
    elif op == "flip-header":
        p = int(rng.integers(0, min(len(payload), 700)))
        b = bytearray(payload)
        b[p] ^= 1 << int(rng.integers(8))
        el[1] = head + bytes(b)
        what = f"block {c}/{j} (track {track}) bit flipped at {p} (JPEG headers)"
        allow = frozenset({"color", "depth"})
    else:
        n = int(rng.integers(1, 200))
        el[1] = head + payload[:-n] + bytes(n)
        what = f"block {c}/{j} (track {track}) last {n} bytes zeroed"
        allow = frozenset({"depth"}) if track == 2 else frozenset()
    return spec.to_bytes(), what, allow


def _mkv_raw(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str, frozenset[str]]:
    lo = 0 if rng.random() < 0.5 else min(len(clean.data) - 1, 8000)
    hi = 8000 if lo == 0 else len(clean.data)
    data, what = _bytes_op(clean.data, rng, lo, min(hi, len(clean.data)))
    return data, f"bytes: {what}", ANY


MKV_MUTATORS: dict[str, tuple[float, Callable[[Clean, np.random.Generator], Any]]] = {
    "calibration": (0.25, _mkv_calibration),
    "tags": (0.1, _mkv_tags),
    "track": (0.15, _mkv_track),
    "ebml": (0.15, _mkv_ebml),
    "block": (0.25, _mkv_block),
    "bytes": (0.1, _mkv_raw),
}
#: the real file is only mutated byte-wise (it is not rebuilt from elements)
REAL_MKV_MUTATORS = {"bytes": MKV_MUTATORS["bytes"]}
MKV_CLEANS = ("k4a", "real")


def make_clean(name: str, folder: Path) -> Clean:
    """``rs-<variant>`` or ``mkv-<variant>``."""
    kind, variant = name.split("-", 1)
    clean = (
        make_clean_realsense(variant, folder) if kind == "rs" else make_clean_mkv(variant, folder)
    )
    clean.name = name
    return clean


def available_cleans() -> list[str]:
    names = [f"rs-{v}" for v in RS_CLEANS if v != "real" or REAL_BAG.exists()]
    return names + [f"mkv-{v}" for v in MKV_CLEANS if v != "real" or REAL_MKV.exists()]
