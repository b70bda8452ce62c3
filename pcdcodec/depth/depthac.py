"""``depthac``: a lossless depth codec built for sensor depth (context-adaptive arithmetic coding).

Depth images are not photographs: the values a sensor can produce are few (a Kinect v1 frame
holds a few hundred distinct depths, quantised disparities), invalid pixels (0) form large
blobs with sharp borders, and surfaces are smooth between sharp steps. ``depthac`` codes each
of these on its own, in one pass over the pixels with one adaptive binary range coder:

* the distinct non-zero values of the frame form a sorted table (coded as gaps), and the image
  is coded as indices into it, so quantised depth becomes a smooth image of small steps;
* the validity mask is coded pixel by pixel, each bit with a context of ten neighbouring mask
  bits;
* each valid pixel is predicted from valid neighbours only (the median edge detector of
  LOCO-I when the west, north and north-west neighbours are valid, simpler fallbacks
  otherwise), and the residual is binarised (zero flag, sign, unary exponent, mantissa bits) with
  contexts from the local gradient and the neighbours' residuals.

The bitstream is in ``docs/format.md``. The loops are compiled with numba and cached on disk.
"""

from __future__ import annotations

import threading
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError
from .base import FrameCodec

__all__ = ["DepthAC"]

#: The encoder needs about 11 bytes per pixel of working arrays and output (its output buffer
#: grows a row at a time when a frame does not compress), the decoder 11 bytes per pixel;
#: larger frames (over 8192×8192) are refused.
_MAX_PIXELS = 2**26

#: ``recon`` argument of the kernel encoder when coding losslessly (it is not written then).
_NO_RECON = np.zeros((0, 0), dtype=np.uint16)

_ERRORS = {
    1: "its value table runs past 65535",
    2: "a pixel decodes to an index outside its value table",
    3: "its body length does not match the coded pixels (truncated or extended)",
    4: "its flags byte has unknown bits set",
    5: "the decoder's working arrays do not fit the frame",
}


_WORK = threading.local()


def _working_arrays(shape: tuple[int, int]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """This thread's working arrays for coding frames of ``shape`` (the encoder's and the
    decoder's alike), kept from its last frame of that shape: fresh ones every frame cost page
    faults, about as much as a tenth of the decode. One shape is kept per thread (a few MB)."""
    kept = getattr(_WORK, "arrays", None)
    if kept is None or kept[0] != shape:
        size = _kernels().working_size(*shape)
        kept = (shape, np.zeros(size, dtype=np.int64), np.empty(65536, dtype=np.int64))
        _WORK.arrays = kept
    return kept[1], kept[2]


def _kernels() -> Any:
    from . import _depthac_kernels

    return _depthac_kernels


class DepthAC(FrameCodec):
    """Depth as a context-adaptive arithmetic-coded index image (``depthac``).

    Lossless and bit-exact. Smaller than lossless JPEG XL on real sensor depth and about as
    fast: see ``docs/codecs.md`` for the measured table. uint16 depth is coded directly;
    float32 metres go through the value-table layout. No parameters.
    The first use in a process loads the compiled loops from numba's disk cache (compiling
    them once, a few seconds, when the cache is cold).
    """

    name: ClassVar[str] = "depthac"
    dtypes: ClassVar[tuple[str, ...]] = ("uint16", "float32")
    bounded_near: ClassVar[int] = 0

    def __init__(
        self, *, max_error: float | None = None, max_rel_error: float | None = None
    ) -> None:
        self._set_bound(max_error, max_rel_error)

    def _encode_body(self, image: npt.NDArray[Any]) -> bytes:
        if image.size > _MAX_PIXELS:
            raise InputError(
                f"depthac codes at most {_MAX_PIXELS} pixels per frame, got {image.size}"
            )
        px, rank = _working_arrays(image.shape)
        body: npt.NDArray[np.uint8] = _kernels().encode_into(image, True, 0, _NO_RECON, px, rank)
        return body.tobytes()

    def _encode_levels(
        self, index: npt.NDArray[np.uint16], near: int
    ) -> tuple[bytes, npt.NDArray[np.uint16]]:
        if index.size > _MAX_PIXELS:
            raise InputError(
                f"depthac codes at most {_MAX_PIXELS} pixels per frame, got {index.size}"
            )
        recon = np.zeros(index.shape, dtype=np.uint16) if near else _NO_RECON
        px, rank = _working_arrays(index.shape)
        body: npt.NDArray[np.uint8] = _kernels().encode_into(
            index, near == 0, near, recon, px, rank
        )
        return body.tobytes(), (recon if near else index)

    def _decode_levels(
        self, body: memoryview, shape: tuple[int, int], near: int
    ) -> npt.NDArray[np.uint16]:
        return self._decode_near(body, shape, near)

    def _decode_body(
        self, body: memoryview, shape: tuple[int, int], dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        return self._decode_near(body, shape, 0)

    def _decode_near(
        self, body: memoryview, shape: tuple[int, int], near: int
    ) -> npt.NDArray[np.uint16]:
        if shape[0] * shape[1] > _MAX_PIXELS:
            raise DecodeError(
                f"depthac frame claims {shape[0]}x{shape[1]} pixels, more than {_MAX_PIXELS}"
            )
        buf = np.frombuffer(body, dtype=np.uint8)
        image = np.empty(shape, dtype=np.uint16)
        px, table = _working_arrays(shape)
        status = _kernels().decode_into(buf, image, near, px, table)
        if status:
            reason = _ERRORS.get(status, f"status {status}")
            raise DecodeError(f"depthac frame {shape[1]}x{shape[0]} is corrupt: {reason}")
        return image
