"""Kept images and organized clouds stored compressed (``docs/format.md``, "kept images and
clouds"): a kept ``sensor_msgs/Image`` has its pixels coded losslessly (16-bit through a
lossless depth codec, 8-bit RGB through :mod:`pcdcodec.color.rgb_lossless`, other 8-bit
through lossless JPEG XL), or, when they equal a depth frame of
the recording, a reference to that frame; a kept organized ``sensor_msgs/PointCloud2`` made
from a recorded depth frame keeps its envelope, a reference to the frame, the corrections of
its x, y and z to the one ulp, its packed colours losslessly (``rgb_lossless``) and its
other bytes (an empty section where they are all zero). The rest of each message (header,
encoding, step, fields, ...) is kept byte for byte.

Every packed image is rebuilt when written and compared with the original, and every cloud
checked as it is split (:meth:`Packer.pack`); one that would not come back byte-identical is
kept as it came, on the topic's plain channel. Reading gives back the original bytes, checked
against the CRC-32 of the original each packed message holds.
"""

from __future__ import annotations

import itertools
import json
import struct
import threading
import zlib
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError, PcdcodecError
from ..ros import bagindex
from ..ros.kept import KeptMessage, KeptTopic
from ..ros.message_split import Envelope, split_cloud, split_image

__all__ = [
    "CLOUD_ENCODING",
    "IMAGE_ENCODING",
    "KEPT_IMAGES",
    "Packer",
    "kept_packer",
    "kept_topic_of_channel",
    "packed_frames",
    "unpack",
]

#: The message encodings of packed channels: no tool but pcdcodec decodes them.
IMAGE_ENCODING = "pcdcodec.image"
CLOUD_ENCODING = "pcdcodec.cloud"
PACKED_ENCODINGS = (IMAGE_ENCODING, CLOUD_ENCODING)
#: A packed channel's metadata key holding the topic's own message encoding (ros1, cdr).
ORIGINAL_KEY = "pcdcodec.message_encoding"
#: ``kept_images`` choices: packed where exact, or every kept message as it came.
KEPT_IMAGES = ("lossless", "raw")

IMAGE = "sensor_msgs/msg/Image"
CLOUD = "sensor_msgs/msg/PointCloud2"
_MAGIC = b"PCDK"
_HEAD = struct.Struct("<4sBBII")  # magic, version, kind, CRC-32 and length of the original
#: 2: three-channel colours (kept rgb8/bgr8 images, clouds' packed colours) coded by
#: :mod:`pcdcodec.color.rgb_lossless`; 1: by lossless JPEG XL (still read).
_VERSION = 2
_VERSIONS = (1, 2)
_IMAGE16, _IMAGE8, _DEPTH_REF, _CLOUD = 1, 2, 3, 4
_SHAPE = struct.Struct("<IIB")  # height, width, channels (8-bit) or big-endian (16-bit)
# frame, h, w, point_step, x, y, z and rgb offsets, rule of the rebuild
_CLOUD_HEAD = struct.Struct("<qIIIiiiiB")
#: The rebuilds of x, y and z a cloud may be compared with (:func:`_predict_xyz`).
RULES = (0, 1)
_U32 = struct.Struct("<I")
_16BIT = frozenset(("16UC1", "mono16", "Y16"))
_8BIT = {"mono8": 1, "8UC1": 1, "rgb8": 3, "bgr8": 3, "8UC3": 3, "rgba8": 4, "bgra8": 4}
#: Frames of the recording held back to compare kept messages with, and how far from a
#: frame's stamp a cloud's stamp may be.
WINDOW = 16
CLOUD_TOLERANCE_NS = 20_000_000
#: Recorded frames a message may refer to: (timestamp, depth) pairs.
Frames = tuple[tuple[int, "npt.NDArray[np.uint16]"], ...]
#: A cloud's x, y and z may differ from the rebuild by this many float32 ulps at most (the
#: difference is stored, so they come back bit-exact).
MAX_ULPS = 1
_JXL_EFFORT = 1  # measured: a quarter of the bytes at 11 ms a 640x480 RGB frame


def _jxl_encode(pixels: npt.NDArray[np.uint8]) -> bytes:
    import imagecodecs

    return bytes(imagecodecs.jpegxl_encode(pixels, lossless=True, effort=_JXL_EFFORT))


def _jxl_decode(data: bytes, shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """The pixels of a JPEG XL image of ``shape`` (height, width), checked before decoding."""
    import imagecodecs

    from ..depth.jpegxl import jpegxl_size

    try:
        found = jpegxl_size(data)
    except DecodeError as exc:
        raise ValueError(str(exc)) from None
    if found != shape:
        raise ValueError(f"its JPEG XL image is {found}, expected {shape}")
    try:
        return np.asarray(imagecodecs.jpegxl_decode(data))
    except Exception as exc:  # the library's own errors: damaged data
        raise ValueError(f"its JPEG XL image does not decode: {exc}") from None


def _colour_encode(pixels: npt.NDArray[np.uint8], check: bool = False) -> bytes:
    """8-bit pixels coded losslessly: three channels by :mod:`pcdcodec.color.rgb_lossless`
    (the way the camera made them found and used), others by JPEG XL. ``check``: the coded
    planes decoded and compared (``ValueError`` if they differ)."""
    if pixels.ndim == 3 and pixels.shape[2] == 3:
        from ..color import rgb_lossless

        return rgb_lossless.encode(pixels, check=check)
    return _jxl_encode(pixels)


def _colour_decode(
    data: bytes, shape: tuple[int, int], channels: int, version: int
) -> npt.NDArray[np.uint8]:
    if version >= 2 and channels == 3:
        from ..color import rgb_lossless

        return rgb_lossless.decode(data, shape)
    return _jxl_decode(data, shape)


def _zstd(data: bytes) -> bytes:
    import zstandard

    return bytes(zstandard.ZstdCompressor(level=3).compress(data))


def _unzstd(data: bytes, size: int) -> bytes:
    import zstandard

    try:
        out = bytes(zstandard.ZstdDecompressor().decompress(data, max_output_size=size))
    except zstandard.ZstdError as exc:
        raise ValueError(f"a zstd section does not decompress: {exc}") from None
    if len(out) != size:
        raise ValueError(f"a zstd section holds {len(out)} bytes, expected {size}")
    return out


def _sections(*parts: bytes) -> bytes:
    return b"".join(_U32.pack(len(p)) + p for p in parts)


class _Cursor:
    """Reads a packed message's length-prefixed sections; :class:`ValueError` past the end."""

    def __init__(self, data: bytes, pos: int) -> None:
        self.data, self.pos = data, pos

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.data):
            raise ValueError("short")
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def section(self) -> bytes:
        (n,) = _U32.unpack(self.take(4))
        return self.take(n)


def _predict_xyz(
    depth: npt.NDArray[np.uint16],
    camera: tuple[float, float, float, float],
    scale: float,
    rule: int,
) -> tuple[npt.NDArray[np.uint32], ...]:
    """The float32 bits of x, y and z a pinhole camera gives each pixel of ``depth``. Rule 0
    (pcdcodec's projector): z = float32(d / scale), x = float32((u - cx) / fx) * z, y
    likewise, the divisions in float64, and x = y = 0 where d is 0. Rule 1 (librealsense's
    deprojection, so realsense-ros's clouds): all in float32, z = d * float32(1 / scale),
    x = ((u - cx) / fx) * z, y likewise."""
    fx, fy, cx, cy = camera
    h, w = depth.shape
    if rule == 0:
        z = (depth.astype(np.float64) / scale).astype(np.float32)
        rx = ((np.arange(w, dtype=np.float64) - cx) / fx).astype(np.float32)
        ry = ((np.arange(h, dtype=np.float64) - cy) / fy).astype(np.float32)
    else:
        f32 = np.float32
        z = depth.astype(np.float32) * f32(1.0 / scale)
        rx = (np.arange(w, dtype=np.float32) - f32(cx)) / f32(fx)
        ry = (np.arange(h, dtype=np.float32) - f32(cy)) / f32(fy)
    x = rx[None, :] * z
    y = ry[:, None] * z
    if rule == 0:  # holes are 0 (rule 1 keeps the products: -0.0 left of cx)
        hole = depth == 0
        np.copyto(x, 0, where=hole)
        np.copyto(y, 0, where=hole)
    return x.view(np.uint32), y.view(np.uint32), z.view(np.uint32)


class _CloudShape:
    """Where a cloud's x, y, z and packed colour sit in a point, and its other bytes."""

    def __init__(self, point_step: int, offsets: tuple[int, int, int, int]) -> None:
        self.point_step = point_step
        self.offsets = offsets
        used: set[int] = set()
        for off in offsets[:3]:
            used.update(range(off, off + 4))
        if offsets[3] >= 0:
            used.update(range(offsets[3], offsets[3] + 3))  # b, g, r; the fourth byte is rest
        self.rest = [i for i in range(point_step) if i not in used]

    @classmethod
    def of(cls, env: Envelope) -> _CloudShape | None:
        """The shape of an organized little-endian cloud with float32 x, y and z (and a 4-byte
        rgb or rgba), or ``None``."""
        if env.height <= 1 or env.is_bigendian or env.row_step != env.width * env.point_step:
            return None
        if env.data_end - env.data_start != env.height * env.row_step:
            return None
        found: dict[str, int] = {}
        for f in env.fields:
            if f.name in found or f.count != 1 or f.offset + 4 > env.point_step:
                return None
            if f.name in ("x", "y", "z") and f.datatype == 7:
                found[f.name] = f.offset
            elif f.name in ("rgb", "rgba") and f.datatype in (6, 7) and "rgb" not in found:
                found["rgb"] = f.offset
        if not all(k in found for k in "xyz"):
            return None
        offsets = (found["x"], found["y"], found["z"], found.get("rgb", -1))
        spans = sorted(o for o in offsets if o >= 0)
        if any(b - a < 4 for a, b in itertools.pairwise(spans)):
            return None
        return cls(env.point_step, offsets)


class Packer:
    """The writer's side: which kept topics are packed, the recording's recent depth frames,
    and each message packed (and rebuilt, to check it) or left as it came."""

    def __init__(
        self,
        depth_codec: Any,
        camera: Any,
        depth_scale: float,
    ) -> None:
        usable = depth_codec.lossless and "uint16" in depth_codec.dtypes
        #: The coder of 16-bit images: the recording's depth codec when lossless, else depthac
        #: (made on first use).
        self.depth_codec: Any = depth_codec if usable else None
        self.reference = bool(depth_codec.lossless)  # frames come back exactly: refer to them
        self.camera = (camera.fx, camera.fy, camera.cx, camera.cy)
        self.pinhole = not getattr(camera, "has_distortion", False)
        self.depth_scale = float(depth_scale)
        self.frames: deque[tuple[int, npt.NDArray[np.uint16]]] = deque(maxlen=WINDOW)
        self._lock = threading.Lock()

    @staticmethod
    def packs(topic: KeptTopic) -> str | None:
        """The packed encoding of ``topic``'s channel, or ``None`` when it is kept as is."""
        if topic.message_encoding not in ("ros1", "cdr"):
            return None
        return {IMAGE: IMAGE_ENCODING, CLOUD: CLOUD_ENCODING}.get(topic.msgtype)

    @staticmethod
    def channel_metadata(topic: KeptTopic) -> dict[str, str]:
        return {**topic.channel_metadata(), ORIGINAL_KEY: topic.message_encoding}

    def saw_frame(self, timestamp: int, depth: npt.NDArray[Any]) -> None:
        """Hold a recorded frame's depth for a while (its depth codec lossless, uint16)."""
        if self.reference and depth.dtype == np.uint16:
            self.frames.append((int(timestamp), np.array(depth, copy=True)))

    def recent(self) -> Frames:
        """The frames held now (what a message taken now may refer to), for :meth:`pack` on
        another thread while more frames arrive."""
        return tuple(self.frames)

    @staticmethod
    def _frame(
        frames: Frames, stamp: int, tolerance: int
    ) -> tuple[int, npt.NDArray[np.uint16]] | None:
        best = min(frames, key=lambda f: abs(f[0] - stamp), default=None)
        return best if best is not None and abs(best[0] - stamp) <= tolerance else None

    def pack(self, message: KeptMessage, frames: Frames | None = None) -> bytes | None:
        """``message``'s packed bytes, checked to rebuild it exactly, or ``None`` (keep it
        as it came). ``frames``: the frames it may refer to (:meth:`recent`; by default those
        held now). An image is rebuilt whole and compared. A cloud is checked as it is split,
        in one pass over its points: x, y and z within one ulp of the rebuild from the frame
        (the differences stored), the colours coded losslessly, the rest kept; it is not
        decoded again, which would cost as much as packing it. Reading checks every rebuilt
        message against the original's CRC-32, as it checks every frame."""
        frames = self.recent() if frames is None else frames
        raw = bytes(message.data)
        enc = message.topic.message_encoding
        try:
            if message.topic.msgtype == IMAGE:
                body = self._image(raw, enc, frames)
            else:
                body = self._cloud(raw, enc, frames)
        except Exception:  # a coder refusing these pixels: the message is kept as it came
            body = None
        packed = None if body is None else self._whole(raw, *body)
        if packed is not None and message.topic.msgtype == IMAGE:
            by_time = dict(frames)
            try:
                camera = (*self.camera, self.depth_scale)
                if unpack(packed, by_time.get, "a kept message", camera) != raw:
                    packed = None
            except DecodeError:
                packed = None
        return packed

    @staticmethod
    def _whole(raw: bytes, env: Envelope, kind: int, body: bytes) -> bytes:
        head = _HEAD.pack(_MAGIC, _VERSION, kind, zlib.crc32(raw), len(raw))
        return head + _sections(raw[: env.data_start], raw[env.data_end :]) + body

    def _image(self, raw: bytes, enc: str, frames: Frames) -> tuple[Envelope, int, bytes] | None:
        env = split_image(raw, enc)
        if env is None:
            return None
        h, w = env.height, env.width
        data = raw[env.data_start : env.data_end]
        if env.encoding in _16BIT:
            if env.step != 2 * w or len(data) != 2 * h * w or h * w == 0:
                return None
            depth = np.frombuffer(data, ">u2" if env.is_bigendian else "<u2").reshape(h, w)
            depth = depth.astype(np.uint16)
            stamp = _stamp(raw, enc)
            found = None if stamp is None else self._frame(frames, stamp, 0)
            if found is not None and np.array_equal(found[1], depth):
                return (
                    env,
                    _DEPTH_REF,
                    _SHAPE.pack(h, w, env.is_bigendian) + struct.pack("<q", found[0]),
                )
            with self._lock:  # packed on more than one thread
                if self.depth_codec is None:
                    from ..registry import get_codec

                    self.depth_codec = get_codec("depthac", kind="depth")
            config = json.dumps(self.depth_codec.stored_config(), separators=(",", ":"))
            coded = self.depth_codec.encode(depth)
            return (
                env,
                _IMAGE16,
                _SHAPE.pack(h, w, env.is_bigendian) + _sections(config.encode(), coded),
            )
        channels = _8BIT.get(env.encoding)
        if channels is None or env.step != channels * w or len(data) != env.step * h or h * w == 0:
            return None
        shape = (h, w) if channels == 1 else (h, w, channels)
        pixels = np.frombuffer(data, np.uint8).reshape(shape)
        return env, _IMAGE8, _SHAPE.pack(h, w, channels) + _colour_encode(pixels)

    def _cloud(self, raw: bytes, enc: str, frames: Frames) -> tuple[Envelope, int, bytes] | None:
        env = split_cloud(raw, enc)
        if env is None or not self.pinhole:
            return None
        shape = _CloudShape.of(env)
        stamp = _stamp(raw, enc)
        if shape is None or stamp is None:
            return None
        found = self._frame(frames, stamp, CLOUD_TOLERANCE_NS)
        if found is None or found[1].shape != (env.height, env.width):
            return None
        ts, depth = found
        data = np.frombuffer(raw, np.uint8, env.data_end - env.data_start, env.data_start)
        points = data.reshape(env.height, env.width, env.point_step)
        from ._cloud_kernels import split_points

        h, w = depth.shape
        offsets = np.array(shape.offsets, np.int64)
        # the other bytes: whole aligned words read at once where the points allow it
        groups = set(shape.rest) if env.point_step % 4 == 0 and data.size % 4 == 0 else set()
        full = [g for g in range(0, env.point_step, 4) if groups.issuperset(range(g, g + 4))]
        rest = np.array([i for i in shape.rest if i - i % 4 not in full], np.int64)
        rest_words = np.array(full, np.int64)
        colours = np.empty((h, w, 3), np.uint8)
        # the points as uint32 words too (x, y and z read at once where 4-byte aligned)
        words = data.view("<u4") if data.size % 4 == 0 else np.zeros(1, "<u4")
        best: tuple[int, tuple[int, int, int], Any, bool] | None = None
        for rule in RULES:
            predicted = np.stack(_predict_xyz(depth, self.camera, self.depth_scale, rule))
            diffs = np.empty((3, h, w), np.uint32)
            fits, nx, ny, nz, rest_set = split_points(
                data, words, env.point_step, offsets, rest, rest_words, predicted, depth,
                MAX_ULPS, diffs, colours,
            )  # fmt: skip
            if not fits:
                continue  # not this rule's rebuild of this frame's depth
            changed = (nx, ny, nz)
            if best is None or sum(changed) < sum(best[1]):
                best = (rule, changed, diffs, rest_set)
            if not any(changed):
                break
        if best is None:
            return None  # not made from this frame's depth
        rule, changed, diffs, rest_set = best
        # an empty section: all zero (as every correction is, for a cloud made by the rule)
        parts = [_zstd(d.tobytes()) if n else b"" for d, n in zip(diffs, changed, strict=True)]
        rgb = _colour_encode(colours) if shape.offsets[3] >= 0 else b""
        parts.append(rgb)
        parts.append(_zstd(points[..., shape.rest].tobytes()) if rest_set else b"")
        head = _CLOUD_HEAD.pack(ts, env.height, env.width, env.point_step, *shape.offsets, rule)
        return env, _CLOUD, head + _sections(*parts)


def _column(data: npt.NDArray[np.uint8], offset: int, shape: tuple[int, ...]) -> Any:
    """The uint32 at byte ``offset`` of every point of ``data`` (``shape``: height, width,
    point_step), as a strided view (writable where ``data`` is)."""
    h, w, step = shape
    return np.ndarray((h, w), "<u4", data, offset, (w * step, step))


def _rgb(data: npt.NDArray[np.uint8], shape: _CloudShape, dims: tuple[int, ...]) -> Any:
    """The r, g, b bytes of every point (stored b, g, r from the colour field's offset), as an
    H x W x 3 strided view (writable where ``data`` is)."""
    h, w, step = dims
    return np.ndarray((h, w, 3), np.uint8, data, shape.offsets[3] + 2, (w * step, step, -1))


def _stamp(raw: bytes, enc: str) -> int | None:
    try:
        return bagindex.ros1_stamp(raw) if enc == "ros1" else bagindex.cdr_stamp(raw)
    except DecodeError:
        return None


# -- reading ------------------------------------------------------------------------------------

DepthAt = Callable[[int], "npt.NDArray[Any] | None"]


def kept_topic_of_channel(
    topic: str, encoding: str, metadata: Mapping[str, str], schema: tuple[str, str, bytes] | None
) -> KeptTopic:
    """The kept topic an MCAP channel stores; a packed channel's own message encoding and
    metadata restored."""
    if encoding in PACKED_ENCODINGS:
        meta = dict(metadata)
        encoding = meta.pop(ORIGINAL_KEY, "")
        metadata = meta
    return KeptTopic.from_channel(topic, encoding, metadata, schema)


def unpack(
    data: bytes,
    depth_at: DepthAt | None,
    what: str,
    camera: tuple[float, float, float, float, float] | None = None,
) -> bytes:
    """The original bytes of a packed message. ``depth_at(timestamp)`` gives a recorded
    frame's depth (a cloud's or a referring image's); ``camera`` is ``(fx, fy, cx, cy,
    depth_scale)`` of the recording (for clouds). Raises :class:`~pcdcodec.DecodeError`
    naming ``what`` for damaged data, a frame the file lacks, or bytes that do not match the
    original's CRC-32."""
    try:
        magic, version, kind, crc, size = _HEAD.unpack_from(data, 0)
        if magic != _MAGIC or version not in _VERSIONS:
            raise ValueError("not a packed kept message")
        cur = _Cursor(data, _HEAD.size)
        prefix, suffix = cur.section(), cur.section()
        if kind == _CLOUD:
            body = _unpack_cloud(cur, depth_at, camera, size, version)
        else:
            body = _unpack_image(kind, cur, depth_at, size, version)
    except (ValueError, struct.error, TypeError) as exc:
        raise DecodeError(f"{what}: a packed kept message is damaged ({exc})") from None
    except PcdcodecError as exc:  # its depth codec's, or a frame the file lacks
        raise DecodeError(f"{what}: a packed kept message: {exc}") from None
    out = prefix + body + suffix
    if len(out) != size or zlib.crc32(out) != crc:
        raise DecodeError(f"{what}: a packed kept message does not rebuild its original bytes")
    return out


def _frame_depth(depth_at: DepthAt | None, ts: int, shape: tuple[int, int]) -> Any:
    depth = None if depth_at is None else depth_at(ts)
    if depth is None:
        raise DecodeError(f"it refers to the depth frame at {ts} ns, which is not in the file")
    if depth.shape != shape or depth.dtype != np.uint16:
        raise DecodeError(f"the depth frame at {ts} ns is not a {shape} uint16 image")
    return depth


def _unpack_image(
    kind: int, cur: _Cursor, depth_at: DepthAt | None, size: int, version: int
) -> bytes:
    h, w, extra = _SHAPE.unpack(cur.take(_SHAPE.size))
    if kind == _IMAGE8:
        if h * w * max(extra, 1) > size:
            raise ValueError(f"a {h}x{w} image does not fit the message's {size} bytes")
        pixels = _colour_decode(cur.take(len(cur.data) - cur.pos), (h, w), extra, version)
        if pixels.dtype != np.uint8 or pixels.size != h * w * max(extra, 1):
            raise ValueError(f"the image is {pixels.shape}, expected {h}x{w}x{extra}")
        return pixels.tobytes()
    if kind == _DEPTH_REF:
        (ts,) = struct.unpack("<q", cur.take(8))
        depth = _frame_depth(depth_at, ts, (h, w))
    elif kind == _IMAGE16:
        from ..depth.base import read_header
        from ..registry import codec_for_reading

        config = json.loads(cur.section())
        codec: Any = codec_for_reading(config, kind="depth")
        coded = cur.section()
        header = read_header(coded)  # checked before decoding: no huge image is made
        if header.shape != (h, w) or header.dtype != np.uint16 or 2 * h * w > size:
            raise ValueError(f"its coded image is {header.dtype} {header.shape}, expected {h}x{w}")
        depth = codec.decode(coded, max_pixels=None)
        if depth.shape != (h, w) or depth.dtype != np.uint16:
            raise ValueError(f"the image is {depth.shape} {depth.dtype}, expected {h}x{w}")
    else:
        raise ValueError(f"unknown kind {kind}")
    return bytes(depth.astype(">u2" if extra else "<u2").tobytes())


def _unpack_cloud(
    cur: _Cursor, depth_at: DepthAt | None, camera: Any, size: int, version: int
) -> bytes:
    ts, h, w, step, *offsets, rule = _CLOUD_HEAD.unpack(cur.take(_CLOUD_HEAD.size))
    if camera is None:
        raise DecodeError("a kept cloud needs the recording's camera to be rebuilt")
    if h * w * step > size:
        raise ValueError(f"{h}x{w} points of {step} bytes exceed the message's {size}")
    depth = _frame_depth(depth_at, ts, (h, w))
    shape = _CloudShape(step, (offsets[0], offsets[1], offsets[2], offsets[3]))
    if max(offsets) + 4 > step or min(offsets[:3]) < 0:
        raise ValueError(f"field offsets {offsets} do not fit points of {step} bytes")
    data = np.zeros(h * w * step, np.uint8)
    dims = (h, w, step)
    n = h * w * 4
    if rule not in RULES:
        raise ValueError(f"unknown rebuild rule {rule}")
    xyz = _predict_xyz(depth, camera[:4], camera[4], rule)
    for bits, off in zip(xyz, offsets[:3], strict=True):
        coded = cur.section()
        if not coded:  # no corrections
            _column(data, off, dims)[...] = bits
            continue
        diff = np.frombuffer(_unzstd(coded, n), "<u4").reshape(h, w)
        np.add(bits, diff, out=_column(data, off, dims))
    rgb = cur.section()
    if offsets[3] >= 0:
        pixels = _colour_decode(rgb, (h, w), 3, version)
        if pixels.shape != (h, w, 3):
            raise ValueError(f"the colours are {pixels.shape}, expected {(h, w, 3)}")
        _rgb(data, shape, dims)[...] = pixels
    coded = cur.section()
    if coded:  # else every other byte is zero
        rest = np.frombuffer(_unzstd(coded, h * w * len(shape.rest)), np.uint8)
        data.reshape(dims)[..., shape.rest] = rest.reshape(h, w, len(shape.rest))
    return data.tobytes()


def packed_frames(recording: Any) -> tuple[DepthAt, tuple[float, float, float, float, float]]:
    """What reading a recording's packed messages needs of it: its depth frames by
    timestamp (the last few decoded kept, as a cloud and an image often share one), and its
    camera ``(fx, fy, cx, cy, depth_scale)``."""
    cache: dict[int, npt.NDArray[Any]] = {}

    def depth_at(ts: int) -> npt.NDArray[Any] | None:
        if ts not in cache:
            times = np.asarray(recording.timestamps)
            i = int(np.searchsorted(times, ts))
            if i >= len(times) or int(times[i]) != ts:
                return None
            if len(cache) >= 4:
                del cache[next(iter(cache))]
            cache[ts] = recording.depth(i)
        return cache[ts]

    k = recording.intrinsics
    return depth_at, (k.fx, k.fy, k.cx, k.cy, float(recording.depth_scale))


def kept_packer(mode: Any, depth_codec: Any, camera: Any, depth_scale: float) -> Packer | None:
    """The :class:`Packer` of a writer's ``kept_images`` choice (``"lossless"``: packed where
    exact; ``"raw"``: ``None``, every kept message as it came)."""
    if mode not in KEPT_IMAGES:
        raise InputError(f"kept_images must be one of {', '.join(KEPT_IMAGES)}, got {mode!r}")
    return Packer(depth_codec, camera, depth_scale) if mode == "lossless" else None
