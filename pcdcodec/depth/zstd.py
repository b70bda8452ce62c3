"""``zstd``: Zstandard over the raw pixels."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from .._validate import check_int
from .base import FrameCodec, bytes_body


class Zstd(FrameCodec):
    """Depth as a standard Zstandard frame of the raw little-endian pixels, row by row.

    About 1.7× smaller than LZ4 on Kinect depth at level 3 and still fast; higher levels trade
    encode time for size (decoding speed barely changes). ``level`` ranges from -7 (fastest)
    to 22. float32 depth is stored as raw float bytes.
    """

    name: ClassVar[str] = "zstd"
    dtypes: ClassVar[tuple[str, ...]] = ("uint16", "float32")
    native_dtypes: ClassVar[tuple[str, ...]] = ("uint16", "float32")

    def __init__(self, *, level: int = 3) -> None:
        check_int(self.name, "level", level, -7, 22)
        self.level = level

    def _encode_body(self, image: npt.NDArray[Any]) -> bytes:
        import zstandard

        compressor = zstandard.ZstdCompressor(level=self.level, write_content_size=True)
        return compressor.compress(image.data)

    def _decode_body(
        self, body: memoryview, shape: tuple[int, int], dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        import zstandard

        expected = shape[0] * shape[1] * dtype.itemsize
        raw = zstandard.ZstdDecompressor().decompress(body, max_output_size=expected)
        return bytes_body(raw, shape, dtype)
