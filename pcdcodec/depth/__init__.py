"""Depth codecs: lossless frame codecs, one module per codec.

Adding a codec means adding one module with a :class:`FrameCodec` subclass and one line below.
"""

from __future__ import annotations

import numpy as np

from ..registry import register_codec
from .base import DEFAULT_MAX_PIXELS, FORMAT_VERSION, FrameCodec, FrameHeader, read_header
from .depthac import DepthAC
from .jpegxl import JPEGXL
from .lz4 import LZ4
from .png16 import PNG16
from .rvl import RVL
from .zstd import Zstd

__all__ = [
    "DEFAULT_DEPTH_CODEC",
    "DEFAULT_MAX_PIXELS",
    "FORMAT_VERSION",
    "JPEGXL",
    "LZ4",
    "PNG16",
    "RVL",
    "DepthAC",
    "FrameCodec",
    "FrameHeader",
    "Zstd",
    "decode_depth",
    "read_header",
]

#: The depth codec used when none is named.
DEFAULT_DEPTH_CODEC = "depthac"

for _cls in (LZ4, Zstd, PNG16, RVL, JPEGXL, DepthAC):
    register_codec(_cls)


def decode_depth(
    data: bytes | bytearray | memoryview,
    *,
    shape: tuple[int, int] | None = None,
    max_pixels: int | None = DEFAULT_MAX_PIXELS,
) -> np.ndarray:
    """Decode a depth frame written by any registered depth codec, read from its header.

    ``shape`` and ``max_pixels`` bound what may be decoded, as in :meth:`FrameCodec.decode`
    (default limit :data:`DEFAULT_MAX_PIXELS` pixels; ``None`` for none).
    """
    from ..registry import codec_class

    header = read_header(data)
    cls = codec_class(header.codec, "depth")
    codec = cls()
    assert isinstance(codec, FrameCodec)
    return codec.decode(data, shape=shape, max_pixels=max_pixels)
