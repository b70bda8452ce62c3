"""Camera messages kept exactly: a depth or color message made into a frame, with its pixels
cut out (an *envelope*), and the message rebuilt from the envelope and the frame
(``docs/format.md``, "Format version 4: kept topics").

A ``sensor_msgs/Image`` and a ``sensor_msgs/CompressedImage`` both end with their ``data``
field: a 4-byte length, then the bytes (ROS 1 and CDR alike). An envelope holds the serialized
message up to that length (the header with ``frame_id``, stamp and ``seq``, the size,
``encoding``, ``step`` and ``is_bigendian``, or the ``format`` string), the first bytes of the
payload that the frame does not hold (compressedDepth's 12-byte header), how the payload is
rebuilt from the frame (its *layout*), and the frame's timestamp, to find the frame back.

Each layout says what comes back: raw Images byte for byte (from lossless frames), PNG and
compressedDepth depth as PNG (or RVL) of the same depth bit for bit, JPEG color re-encoded at
:data:`JPEG_QUALITY`. :func:`make_envelope` refuses (returns ``None``) a message it cannot give
back as the layout promises, and the source keeps that message raw instead.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError

__all__ = [
    "ENVELOPE_VERSION",
    "JPEG_QUALITY",
    "Envelope",
    "make_envelope",
    "payload_of",
]

ENVELOPE_VERSION = 1
#: The quality JPEG color is re-encoded at when a message is rebuilt (libjpeg's scale).
JPEG_QUALITY = 95
_MAGIC = b"PCDE"
# magic, version, flags (bit 0: length field big-endian), layout length, frame timestamp,
# original payload length, prefix length, kept payload head length
_HEAD = struct.Struct("<4sBBHqQII")
_CDEPTH_HEADER = 12
_COLOR_BYTES = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
_DEPTH_TYPES = {"16UC1": "u2", "mono16": "u2", "32FC1": "f4"}


@dataclass(frozen=True)
class Envelope:
    """A camera message without its pixels (see the module).

    ``layout`` is ``image:<encoding>:<byte order>`` for an Image, ``png16`` (a 16-bit PNG
    depth), ``cdepth-png`` / ``cdepth-rvl`` (compressedDepth, its 12-byte header in ``head``),
    ``jpeg`` / ``jpeg-gray`` / ``png`` / ``png-gray`` (color)."""

    timestamp: int
    layout: str
    prefix: bytes
    head: bytes = b""
    big: bool = False
    length: int = 0  # the original payload's length (head included)

    def pack(self) -> bytes:
        layout = self.layout.encode()
        fields = _HEAD.pack(
            _MAGIC, ENVELOPE_VERSION, int(self.big), len(layout), self.timestamp,
            self.length, len(self.prefix), len(self.head),
        )  # fmt: skip
        return fields + layout + self.prefix + self.head

    @classmethod
    def unpack(cls, data: bytes, where: str) -> Envelope:
        """Raises :class:`~pcdcodec.DecodeError` naming ``where`` for bytes that are not a
        whole envelope of this version."""
        if len(data) < _HEAD.size:
            raise DecodeError(f"{where}: a camera envelope of {len(data)} bytes is cut short")
        magic, version, flags, n_layout, ts, length, n_prefix, n_head = _HEAD.unpack_from(data)
        if magic != _MAGIC or version != ENVELOPE_VERSION:
            raise DecodeError(
                f"{where}: not a camera envelope of version {ENVELOPE_VERSION} "
                f"(starts {bytes(data[:5])!r})"
            )
        end = _HEAD.size + n_layout + n_prefix + n_head
        if end != len(data):
            raise DecodeError(f"{where}: a camera envelope says {end} bytes but holds {len(data)}")
        at = _HEAD.size
        layout = bytes(data[at : at + n_layout]).decode(errors="replace")
        prefix = bytes(data[at + n_layout : at + n_layout + n_prefix])
        head = bytes(data[at + n_layout + n_prefix : end])
        return cls(ts, layout, prefix, head, bool(flags & 1), length)

    def rebuild(self, payload: bytes) -> bytes:
        """The serialized message with ``payload`` (after :attr:`head`) as its data."""
        n = len(self.head) + len(payload)
        size = struct.pack(">I" if self.big else "<I", n)
        return b"".join((self.prefix, size, self.head, payload))


def _split(raw: bytes, n: int, cdr: bool) -> tuple[bytes, bool] | None:
    """(prefix, big-endian length) of a message whose last field is ``n`` data bytes, or
    ``None`` when its bytes do not end so."""
    big = cdr and len(raw) > 1 and raw[1] == 0
    start = len(raw) - n
    if start < 4 or raw[start - 4 : start] != struct.pack(">I" if big else "<I", n):
        return None
    return raw[: start - 4], big


def _layout(msg: Any, role: str) -> str | None:
    """How a message's payload is rebuilt from its frame, or ``None`` for one whose payload
    the frame cannot give back as it promises."""
    from ..color.images import image_header

    if hasattr(msg, "encoding"):
        enc = str(msg.encoding)
        known = _DEPTH_TYPES if role == "depth" else _COLOR_BYTES
        if enc not in known:
            return None
        return f"image:{enc}:{'>' if msg.is_bigendian else '<'}"
    fmt = str(msg.format)
    data = msg.data.tobytes() if isinstance(msg.data, np.ndarray) else bytes(msg.data)
    head = fmt.split(";")[0].strip() if ";" in fmt else ""
    if role == "depth":
        if "compresseddepth" in fmt.lower():
            if head == "32FC1":
                return None  # quantized inverse depth: the float depth is not the payload
            tail = fmt.split(";", 1)[1].lower() if ";" in fmt else fmt.lower()
            return "cdepth-rvl" if "rvl" in tail else "cdepth-png"
        return "png16"
    try:
        h = image_header(data, "color")
    except Exception:
        return None
    if h.channels not in (1, 3) or h.bits != 8:
        return None  # alpha: the frame holds none of it
    return h.format + ("-gray" if h.channels == 1 else "")


def payload_of(layout: str, image: npt.NDArray[Any], where: str) -> bytes:
    """The payload of ``layout`` (after an envelope's head) from a frame's depth or color.
    Raises :class:`~pcdcodec.DecodeError` naming ``where`` for a layout this reader does not
    know or an image of the wrong kind."""
    if layout.startswith("image:"):
        _, enc, order = layout.split(":")
        if enc in _DEPTH_TYPES:
            return np.ascontiguousarray(image).astype(order + _DEPTH_TYPES[enc]).tobytes()
        if enc not in _COLOR_BYTES or image.ndim != 3:
            raise DecodeError(f"{where}: envelope layout {layout!r} does not fit the frame")
        px = image[..., :3]
        if enc.startswith("bgr"):
            px = px[..., ::-1]
        if enc == "mono8":
            px = px[..., :1]
        elif enc in ("rgba8", "bgra8"):
            alpha = np.full((*px.shape[:2], 1), 255, np.uint8)
            px = np.concatenate([px, alpha], axis=2)
        return np.ascontiguousarray(px, dtype=np.uint8).tobytes()
    import imagecodecs

    if layout in ("png16", "cdepth-png", "cdepth-rvl"):
        depth = np.ascontiguousarray(image, dtype=np.uint16)
        if layout == "cdepth-rvl":
            from .messages import compressed_depth_encode

            return compressed_depth_encode(depth, rvl=True)[_CDEPTH_HEADER:]
        return bytes(imagecodecs.png_encode(depth))
    if layout in ("jpeg", "jpeg-gray", "png", "png-gray") and image.ndim == 3:
        px = np.ascontiguousarray(image[..., 0] if layout.endswith("-gray") else image[..., :3])
        if layout.startswith("jpeg"):
            return bytes(imagecodecs.jpeg8_encode(px, level=JPEG_QUALITY))
        return bytes(imagecodecs.png_encode(px))
    raise DecodeError(f"{where}: unknown camera envelope layout {layout!r}")


def make_envelope(
    raw: bytes, msg: Any, role: str, image: npt.NDArray[Any], timestamp: int, *, cdr: bool
) -> bytes | None:
    """The envelope of ``raw`` (the serialized message, ``msg`` deserialized), made into the
    frame at ``timestamp`` whose ``role`` image is ``image``; ``None`` where the message cannot
    be given back as its layout promises (its bytes not ending with the data field, an Image
    whose pixels the frame does not rebuild byte for byte: row padding, alpha, a byte order
    not reproduced; a compressed image with alpha or quantized float depth)."""
    data = msg.data
    n = data.size if isinstance(data, np.ndarray) else len(data)
    layout = _layout(msg, role)
    found = _split(raw, n, cdr)
    if layout is None or found is None:
        return None
    prefix, big = found
    head = b""
    if layout.startswith("cdepth"):
        if n < _CDEPTH_HEADER:
            return None
        head = raw[len(raw) - n : len(raw) - n + _CDEPTH_HEADER]
    env = Envelope(timestamp, layout, prefix, head, big, n)
    if layout.startswith("image:"):
        try:
            rebuilt = payload_of(layout, image, "")
        except DecodeError:
            return None
        if len(rebuilt) != n or rebuilt != raw[len(raw) - n :]:
            return None
    return env.pack()
