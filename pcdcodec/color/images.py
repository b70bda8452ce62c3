"""Structure checks of compressed images (JPEG, PNG: color, or 16-bit depth) before and instead
of trusting a decoder. Every reader of camera files and bags shares them.

JPEG and PNG decoders fill what they cannot read: a JPEG cut in half decodes to an image whose
lower part is grey, without an error. These checks walk the container structure, which costs
microseconds, so that a reader can refuse a cut or damaged image, and learn the size an image
declares before decoding it, so that a few hundred bytes declaring 30000×30000 pixels are refused
instead of allocating gigabytes.

What they cannot see: a flipped bit inside JPEG entropy-coded data (JPEG has no checksum) decodes
to wrong pixels in any decoder. PNG chunks carry CRCs, and every one is checked.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

from ..errors import DecodeError

__all__ = ["ImageHeader", "check_compressed", "image_header"]

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_SOI = b"\xff\xd8"
#: JPEG start-of-frame markers (baseline, extended, progressive, lossless; Huffman and arithmetic)
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
#: markers that stand alone, without a length: TEM, RST0-7, SOI, EOI
_STANDALONE = {0x01, *range(0xD0, 0xD8), 0xD8, 0xD9}
_PNG_BIT_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}


@dataclass(frozen=True)
class ImageHeader:
    """What a compressed image says of itself: its format, size and sample layout."""

    format: str  # "jpeg" or "png"
    width: int
    height: int
    channels: int
    bits: int

    @property
    def decoded_bytes(self) -> int:
        """Bytes of the decoded image (at least one byte a sample)."""
        return self.width * self.height * self.channels * max(1, self.bits // 8)


def image_header(data: bytes, where: str) -> ImageHeader:
    """The header of a JPEG or PNG image, after checking its whole structure.

    ``where`` names the image in errors (the file, and the topic or frame). Raises
    :class:`~pcdcodec.DecodeError` for data that is neither format, or is cut short or damaged
    (see :func:`check_compressed`).
    """
    if data.startswith(_PNG_MAGIC):
        return _png(data, where)
    if data.startswith(_SOI):
        return _jpeg(data, where)
    raise DecodeError(
        f"{where}: the compressed image is neither JPEG nor PNG (starts with {data[:8]!r})"
    )


def check_compressed(data: bytes, where: str, shape: tuple[int, int] | None = None) -> ImageHeader:
    """Check a JPEG or PNG before decoding it: whole, undamaged where the format can tell, and
    (when ``shape`` is given as ``(height, width)``) of that size.

    Raises :class:`~pcdcodec.DecodeError` naming ``where`` and what is wrong.
    """
    header = image_header(data, where)
    if shape is not None and (header.height, header.width) != tuple(shape):
        raise DecodeError(
            f"{where}: the {header.format.upper()} image declares {header.width}x{header.height} "
            f"pixels, expected {shape[1]}x{shape[0]} (the camera's size)"
        )
    return header


def _jpeg(data: bytes, where: str) -> ImageHeader:
    """Walk a JPEG's markers: every segment whole, at least one frame header and one scan, and
    the end-of-image marker after the last scan."""
    n = len(data)
    i = 2
    header: ImageHeader | None = None
    scans = 0
    while True:
        if i >= n:
            raise DecodeError(
                f"{where}: the JPEG image is cut short: no end-of-image marker after {n} bytes"
            )
        if data[i] != 0xFF:
            raise DecodeError(
                f"{where}: the JPEG image is damaged: byte offset {i} holds 0x{data[i]:02x} "
                "where a marker should start"
            )
        while i < n and data[i] == 0xFF:  # fill bytes may precede a marker
            i += 1
        if i >= n:
            continue
        marker = data[i]
        i += 1
        if marker == 0xD9:
            break
        if marker in _STANDALONE:
            if marker == 0xD8:
                raise DecodeError(f"{where}: the JPEG image is damaged: a second start marker")
            continue
        if i + 2 > n:
            continue
        (length,) = struct.unpack_from(">H", data, i)
        if length < 2 or i + length > n:
            raise DecodeError(
                f"{where}: the JPEG image is cut short or damaged: the segment at byte offset "
                f"{i - 2} declares {length} bytes, {n - i} remain"
            )
        if marker in _SOF:
            if length < 8:
                raise DecodeError(f"{where}: the JPEG frame header is {length} bytes, too short")
            bits, height, width, comps = struct.unpack_from(">BHHB", data, i + 2)
            if width == 0 or height == 0 or comps == 0:
                raise DecodeError(
                    f"{where}: the JPEG image declares {width}x{height} pixels with {comps} "
                    "components"
                )
            header = ImageHeader("jpeg", width, height, comps, bits)
        i += length
        if marker == 0xDA:  # start of scan: entropy-coded data up to the next real marker
            if header is None:
                raise DecodeError(f"{where}: the JPEG image has a scan before its frame header")
            scans += 1
            while True:
                j = data.find(b"\xff", i)
                if j < 0 or j + 1 >= n:
                    i = n
                    break
                nxt = data[j + 1]
                if nxt == 0x00 or 0xD0 <= nxt <= 0xD7 or nxt == 0xFF:
                    i = j + (1 if nxt == 0xFF else 2)
                    continue
                i = j
                break
    if header is None or scans == 0:
        raise DecodeError(f"{where}: the JPEG image has no frame header or no scan")
    return header


def _png(data: bytes, where: str) -> ImageHeader:
    """Walk a PNG's chunks, checking each CRC, up to IEND."""
    n = len(data)
    i = len(_PNG_MAGIC)
    header: ImageHeader | None = None
    while True:
        if i + 8 > n:
            raise DecodeError(f"{where}: the PNG image is cut short: no IEND chunk after {n} bytes")
        length, kind = struct.unpack_from(">I4s", data, i)
        end = i + 8 + length
        if end + 4 > n:
            raise DecodeError(
                f"{where}: the PNG image is cut short: the {kind!r} chunk at byte offset {i} "
                f"declares {length} bytes, {n - i - 12} remain"
            )
        (crc,) = struct.unpack_from(">I", data, end)
        if zlib.crc32(data[i + 4 : end]) != crc:
            raise DecodeError(
                f"{where}: the PNG image is damaged: the {kind!r} chunk at byte offset {i} "
                "fails its CRC"
            )
        if header is None:
            if kind != b"IHDR" or length != 13:
                raise DecodeError(f"{where}: the PNG image does not start with its IHDR chunk")
            width, height, bits, color = struct.unpack_from(">IIBB", data, i + 8)
            if width == 0 or height == 0 or bits not in _PNG_BIT_DEPTHS.get(color, ()):
                raise DecodeError(
                    f"{where}: the PNG image declares {width}x{height} pixels, bit depth "
                    f"{bits}, color type {color}"
                )
            header = ImageHeader("png", width, height, _PNG_CHANNELS[color], bits)
        i = end + 4
        if kind == b"IEND":
            return header
