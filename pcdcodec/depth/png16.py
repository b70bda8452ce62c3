"""``png16``: 16-bit grayscale PNG, the format of ROS ``compressed_depth`` (png mode)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from .._validate import check_int
from ..errors import DecodeError
from .base import FrameCodec

_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_header(data: bytes | bytearray | memoryview) -> tuple[int, int, int, int]:
    """(height, width, bit depth, color type) from a PNG's IHDR chunk, read without decoding.

    Raises :class:`~pcdcodec.DecodeError` for bytes that do not start like a PNG.
    """
    head = bytes(memoryview(data).cast("B")[:26])
    if len(head) < 26 or head[:8] != _SIGNATURE or head[12:16] != b"IHDR":
        raise DecodeError("PNG body does not start with a PNG signature and IHDR chunk")
    width = int.from_bytes(head[16:20], "big")
    height = int.from_bytes(head[20:24], "big")
    return height, width, head[24], head[25]


class PNG16(FrameCodec):
    """Depth as a standard 16-bit grayscale PNG (libpng through imagecodecs).

    The body is a valid PNG file that any image viewer opens. ``level`` is the zlib level,
    0 to 9. uint16 only: PNG cannot carry float32 depth.
    """

    name: ClassVar[str] = "png16"
    install_hint: ClassVar[str] = "install imagecodecs (pip install imagecodecs)"

    def __init__(
        self,
        *,
        level: int = 1,
        max_error: float | None = None,
        max_rel_error: float | None = None,
    ) -> None:
        check_int(self.name, "level", level, 0, 9)
        self.level = level
        self._set_bound(max_error, max_rel_error)

    @classmethod
    def unavailable_reason(cls) -> str | None:
        try:
            import imagecodecs
        except ImportError:
            return "imagecodecs is not installed"
        return None if imagecodecs.PNG.available else "this imagecodecs build lacks PNG"

    def _encode_body(self, image: npt.NDArray[Any]) -> bytes:
        import imagecodecs

        return bytes(imagecodecs.png_encode(image, level=self.level))

    def _decode_body(
        self, body: memoryview, shape: tuple[int, int], dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        import imagecodecs

        height, width, bit_depth, color_type = png_header(body)
        if (height, width) != shape or bit_depth != 16 or color_type != 0:
            raise DecodeError(
                f"PNG body is a {width}x{height} {bit_depth}-bit image of color type "
                f"{color_type}, header says 16-bit grayscale (type 0) {shape[1]}x{shape[0]}"
            )
        # Decoding into a buffer of the header's shape and dtype: libpng cannot write more.
        out = np.empty(shape, dtype)
        return np.asarray(imagecodecs.png_decode(body, out=out))  # type: ignore[arg-type]
