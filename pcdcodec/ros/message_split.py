"""The envelope of a serialized ``sensor_msgs/Image`` or ``sensor_msgs/PointCloud2`` (ROS 1 or
little-endian CDR): its fields, and where its ``data`` bytes sit, read without deserializing
the message, so the bytes around the data can be kept exactly as they came.

:func:`split_image` and :func:`split_cloud` return ``None`` for anything they do not read (a
big-endian CDR encapsulation, a message too short for its own lengths): the caller then
keeps the message as it is.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["CloudField", "Envelope", "split_cloud", "split_image"]

_U32 = struct.Struct("<I")


@dataclass(frozen=True)
class CloudField:
    """One ``sensor_msgs/PointField``: name, byte offset in a point, datatype, count."""

    name: str
    offset: int
    datatype: int
    count: int


@dataclass(frozen=True)
class Envelope:
    """A message's fields and its data span ``data_start`` to ``data_end``: the message is
    ``raw[:data_start] + data + raw[data_end:]``."""

    height: int
    width: int
    is_bigendian: int
    data_start: int
    data_end: int
    #: Image: its ``encoding`` and ``step``.
    encoding: str = ""
    step: int = 0
    #: PointCloud2: its fields, ``point_step``, ``row_step``.
    fields: tuple[CloudField, ...] = ()
    point_step: int = 0
    row_step: int = 0


class _Reader:
    """Reads ROS 1 (packed) or CDR (aligned to the field's size, after the 4-byte
    encapsulation header) primitives; raises ``ValueError`` past the end."""

    def __init__(self, raw: bytes, cdr: bool) -> None:
        self.raw = raw
        self.cdr = cdr
        self.pos = 4 if cdr else 0

    def _align(self, size: int) -> None:
        if self.cdr:
            rel = self.pos - 4
            self.pos += (-rel) % size

    def u8(self) -> int:
        if self.pos + 1 > len(self.raw):
            raise ValueError("short")
        value = self.raw[self.pos]
        self.pos += 1
        return value

    def u32(self) -> int:
        self._align(4)
        if self.pos + 4 > len(self.raw):
            raise ValueError("short")
        (value,) = _U32.unpack_from(self.raw, self.pos)
        self.pos += 4
        return int(value)

    def string(self) -> str:
        n = self.u32()
        if self.pos + n > len(self.raw):
            raise ValueError("short")
        text = self.raw[self.pos : self.pos + n]
        self.pos += n
        if self.cdr:  # CDR strings carry their terminating NUL in the length
            text = text[:-1] if text.endswith(b"\0") else text
        return text.decode("utf-8", errors="strict")

    def header(self) -> None:
        if not self.cdr:
            self.u32()  # seq
        self.u32()  # stamp seconds
        self.u32()  # stamp nanoseconds
        self.string()  # frame_id

    def byte_span(self) -> tuple[int, int]:
        n = self.u32()
        start = self.pos
        if start + n > len(self.raw):
            raise ValueError("short")
        self.pos += n
        return start, start + n


def _reader(raw: bytes, encoding: str) -> _Reader | None:
    if encoding == "ros1":
        return _Reader(raw, False)
    if encoding == "cdr" and len(raw) >= 4 and raw[0] == 0 and raw[1] == 1:
        return _Reader(raw, True)  # little-endian plain CDR only
    return None


def split_image(raw: bytes, encoding: str) -> Envelope | None:
    """The envelope of a serialized ``sensor_msgs/Image`` (``encoding`` ``"ros1"`` or
    ``"cdr"``), or ``None`` where it cannot be read."""
    r = _reader(raw, encoding)
    if r is None:
        return None
    try:
        r.header()
        height, width = r.u32(), r.u32()
        enc = r.string()
        big = r.u8()
        step = r.u32()
        start, end = r.byte_span()
    except (ValueError, UnicodeDecodeError):
        return None
    return Envelope(height, width, big, start, end, encoding=enc, step=step)


def split_cloud(raw: bytes, encoding: str) -> Envelope | None:
    """The envelope of a serialized ``sensor_msgs/PointCloud2``, or ``None`` where it cannot
    be read."""
    r = _reader(raw, encoding)
    if r is None:
        return None
    try:
        r.header()
        height, width = r.u32(), r.u32()
        fields = []
        for _ in range(r.u32()):
            name = r.string()
            offset = r.u32()
            datatype = r.u8()
            fields.append(CloudField(name, offset, datatype, r.u32()))
        big = r.u8()
        point_step, row_step = r.u32(), r.u32()
        start, end = r.byte_span()
        r.u8()  # is_dense
    except (ValueError, UnicodeDecodeError):
        return None
    return Envelope(
        height, width, big, start, end,
        fields=tuple(fields), point_step=point_step, row_step=row_step,
    )  # fmt: skip
