"""ROS 2 message encodings (ros2msg schema text, CDR data) of two Foxglove schemas.

Color packets of H.264, H.265, AV1 and VP9 are stored as ``foxglove_msgs/msg/CompressedVideo``
and the camera as ``foxglove_msgs/msg/CameraCalibration``, so Foxglove and ROS 2 tools can read
them. CDR here is little-endian XCDR1: a 4-byte encapsulation header, then each field aligned to
its own size, counted from the end of the header.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from ..errors import DecodeError

_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_SEPARATOR = "=" * 80 + "\n"

COMPRESSED_VIDEO = "foxglove_msgs/msg/CompressedVideo"
COMPRESSED_VIDEO_SCHEMA = (
    "builtin_interfaces/Time timestamp\n"
    "string frame_id\n"
    "uint8[] data\n"
    "string format\n" + _SEPARATOR + _TIME
).encode()

CAMERA_CALIBRATION = "foxglove_msgs/msg/CameraCalibration"
CAMERA_CALIBRATION_SCHEMA = (
    "builtin_interfaces/Time timestamp\n"
    "string frame_id\n"
    "uint32 width\n"
    "uint32 height\n"
    "string distortion_model\n"
    "float64[] d\n"
    "float64[9] k\n"
    "float64[9] r\n"
    "float64[12] p\n" + _SEPARATOR + _TIME
).encode()

_HEADER = b"\x00\x01\x00\x00"  # CDR, little-endian


class _Writer:
    def __init__(self) -> None:
        self.buf = bytearray(_HEADER)

    def align(self, n: int) -> None:
        self.buf += b"\x00" * (-(len(self.buf) - 4) % n)

    def u32(self, value: int) -> None:
        self.align(4)
        self.buf += struct.pack("<I", value)

    def time(self, ns: int) -> None:
        sec, nsec = divmod(ns, 1_000_000_000)
        self.align(4)
        self.buf += struct.pack("<iI", sec, nsec)

    def string(self, text: str) -> None:
        raw = text.encode()
        self.u32(len(raw) + 1)
        self.buf += raw + b"\x00"

    def octets(self, data: bytes) -> None:
        self.u32(len(data))
        self.buf += data

    def doubles(self, values: list[float], *, sized: bool) -> None:
        if sized:
            self.u32(len(values))
        if values:
            self.align(8)
            self.buf += struct.pack(f"<{len(values)}d", *values)


class _Reader:
    def __init__(self, data: bytes, what: str) -> None:
        if data[:2] != _HEADER[:2]:
            raise DecodeError(f"{what} is not little-endian CDR (header {data[:4]!r})")
        self.data, self.pos, self.what = data, 4, what

    def _take(self, n: int, align: int) -> bytes:
        self.pos += -(self.pos - 4) % align
        if self.pos + n > len(self.data):
            raise DecodeError(f"{self.what} is truncated at byte {self.pos} of {len(self.data)}")
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def u32(self) -> int:
        value: int = struct.unpack("<I", self._take(4, 4))[0]
        return value

    def time(self) -> int:
        sec, nsec = struct.unpack("<iI", self._take(8, 4))
        return int(sec) * 1_000_000_000 + int(nsec)

    def string(self) -> str:
        n = self.u32()
        return self._take(n, 1)[:-1].decode(errors="replace") if n else ""

    def octets(self) -> bytes:
        return self._take(self.u32(), 1)

    def doubles(self, count: int | None = None) -> list[float]:
        n = self.u32() if count is None else count
        return list(struct.unpack(f"<{n}d", self._take(8 * n, 8))) if n else []


@dataclass(frozen=True)
class CompressedVideo:
    timestamp: int
    frame_id: str
    data: bytes
    format: str

    def encode(self) -> bytes:
        w = _Writer()
        w.time(self.timestamp)
        w.string(self.frame_id)
        w.octets(self.data)
        w.string(self.format)
        return bytes(w.buf)

    @classmethod
    def decode(cls, data: bytes) -> CompressedVideo:
        r = _Reader(data, "CompressedVideo message")
        return cls(r.time(), r.string(), r.octets(), r.string())


@dataclass(frozen=True)
class CameraCalibration:
    timestamp: int
    frame_id: str
    width: int
    height: int
    distortion_model: str
    d: list[float]
    k: list[float]
    r: list[float]
    p: list[float]

    def encode(self) -> bytes:
        w = _Writer()
        w.time(self.timestamp)
        w.string(self.frame_id)
        w.u32(self.width)
        w.u32(self.height)
        w.string(self.distortion_model)
        w.doubles(self.d, sized=True)
        for fixed in (self.k, self.r, self.p):
            w.doubles(fixed, sized=False)
        return bytes(w.buf)

    @classmethod
    def decode(cls, data: bytes) -> CameraCalibration:
        r = _Reader(data, "CameraCalibration message")
        return cls(
            r.time(),
            r.string(),
            r.u32(),
            r.u32(),
            r.string(),
            r.doubles(),
            r.doubles(9),
            r.doubles(9),
            r.doubles(12),
        )


FRAME_TRANSFORM = "foxglove_msgs/msg/FrameTransform"
FRAME_TRANSFORM_SCHEMA = (
    "builtin_interfaces/Time timestamp\n"
    "string parent_frame_id\n"
    "string child_frame_id\n"
    "geometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation\n"
    + _SEPARATOR
    + _TIME
    + _SEPARATOR
    + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
    + _SEPARATOR
    + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
).encode()


@dataclass(frozen=True)
class FrameTransform:
    """The pose of ``child_frame_id`` in ``parent_frame_id``: a point ``p`` of the child frame
    is ``R(rotation) @ p + translation`` in the parent frame (metres, quaternion x, y, z, w)."""

    timestamp: int
    parent_frame_id: str
    child_frame_id: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]

    def encode(self) -> bytes:
        w = _Writer()
        w.time(self.timestamp)
        w.string(self.parent_frame_id)
        w.string(self.child_frame_id)
        w.doubles([float(v) for v in (*self.translation, *self.rotation)], sized=False)
        return bytes(w.buf)

    @classmethod
    def decode(cls, data: bytes) -> FrameTransform:
        r = _Reader(data, "FrameTransform message")
        timestamp, parent, child = r.time(), r.string(), r.string()
        v = r.doubles(7)
        return cls(timestamp, parent, child, (v[0], v[1], v[2]), (v[3], v[4], v[5], v[6]))
