"""``png16``: 16-bit grayscale PNG, the format of ROS ``compressed_depth`` (png mode)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from .._validate import check_int
from .base import FrameCodec


class PNG16(FrameCodec):
    """Depth as a standard 16-bit grayscale PNG (libpng through imagecodecs).

    The body is a valid PNG file that any image viewer opens. ``level`` is the zlib level,
    0 to 9. uint16 only: PNG cannot carry float32 depth.
    """

    name: ClassVar[str] = "png16"
    install_hint: ClassVar[str] = "install imagecodecs (pip install imagecodecs)"

    def __init__(self, *, level: int = 1) -> None:
        check_int(self.name, "level", level, 0, 9)
        self.level = level

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

        return np.asarray(imagecodecs.png_decode(body))  # type: ignore[arg-type]
