"""Input checks shared by the codecs, the projector and the quality metrics.

Each check returns an array the caller can use directly (C-contiguous, little-endian) or raises
one of the project's input errors naming the value that was wrong and what was expected.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import InputError, InputTypeError

__all__ = [
    "OPEN3D_DEPTH_SCALE",
    "as_uint16_depth",
    "check_choice",
    "check_color",
    "check_depth",
    "check_depth_scale",
    "check_int",
    "check_number",
    "check_output_dtype",
    "check_positive",
]

#: The ``depth_scale`` Open3D assumes when none is given (depth units per metre, millimetres).
#: It lives beside the depth-scale check so that :mod:`pcdcodec.frame` has it without loading
#: :mod:`pcdcodec.geometry.open3d`, which re-exports it.
OPEN3D_DEPTH_SCALE = 1000.0

_DEPTH_DTYPES: dict[str, np.dtype[Any]] = {"uint16": np.dtype("<u2"), "float32": np.dtype("<f4")}

_OUTPUT_DTYPES: dict[str, np.dtype[Any]] = {
    "uint16": np.dtype(np.uint16),
    "float32": np.dtype(np.float32),
}


def _dtype_name(dtype: np.dtype[Any]) -> str:
    if dtype.kind == "u" and dtype.itemsize == 2:
        return "uint16"
    if dtype.kind == "f" and dtype.itemsize == 4:
        return "float32"
    return str(dtype)


def check_depth(
    depth: Any, *, allowed: tuple[str, ...] = ("uint16", "float32"), name: str = "depth"
) -> npt.NDArray[Any]:
    """Validate a depth image and return it as a C-contiguous little-endian 2-D array.

    ``depth`` must be 2-D (height × width), non-empty, and of a dtype in ``allowed``
    (``"uint16"`` for integer depth units, ``"float32"`` for metres with NaN as no measurement).
    Views, non-contiguous arrays and big-endian arrays are accepted and copied only when needed.
    """
    arr: npt.NDArray[Any] = depth if isinstance(depth, np.ndarray) else np.asarray(depth)
    if arr.ndim != 2:
        extra = ""
        if arr.ndim == 3 and arr.shape[2] == 1:
            extra = " (for an H×W×1 array pass depth[..., 0])"
        raise InputError(
            f"{name} must be a 2-D array (height, width), got shape {arr.shape}{extra}"
        )
    if arr.size == 0:
        raise InputError(f"{name} must not be empty, got shape {arr.shape}")
    dname = _dtype_name(arr.dtype)
    if dname not in allowed:
        hint = ""
        if arr.dtype == np.float32 and "float32" not in allowed:
            hint = (
                "; float32 depth needs a codec that takes it (lz4, zstd, jpegxl, depthac), or "
                "depth units: pcdcodec.as_uint16_depth(np.round(metres * depth_scale))"
            )
        elif arr.dtype.kind == "f" and "float32" in allowed:
            hint = "; metres as float32: depth.astype(np.float32)"
        elif "uint16" in allowed and arr.dtype.kind in "iuf":
            hint = "; pcdcodec.as_uint16_depth converts integer-valued arrays exactly"
        raise InputTypeError(f"{name} must be {' or '.join(allowed)}, got {arr.dtype}{hint}")
    out: npt.NDArray[Any] = np.ascontiguousarray(arr, dtype=_DEPTH_DTYPES[dname])
    return out


def check_color(
    color: Any,
    shape: tuple[int, int] | None = None,
    *,
    name: str = "color",
    expected: str = "the depth size",
) -> npt.NDArray[np.uint8]:
    """Validate an 8-bit RGB image (H × W × 3 uint8), optionally of the given (height, width);
    ``expected`` says in an error what that size is."""
    arr = color if isinstance(color, np.ndarray) else np.asarray(color)
    if arr.dtype != np.uint8:
        raise InputTypeError(f"{name} must be uint8, got {arr.dtype}")
    if arr.ndim != 3 or arr.shape[2] != 3:
        extra = (
            " (RGBA is not accepted: pass color[..., :3])"
            if arr.ndim == 3 and arr.shape[2] == 4
            else ""
        )
        raise InputError(f"{name} must have shape (height, width, 3), got {arr.shape}{extra}")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{name} must not be empty, got shape {arr.shape}")
    if shape is not None and arr.shape[:2] != tuple(shape):
        raise InputError(
            f"{name} size {arr.shape[1]}x{arr.shape[0]} differs from {expected} "
            f"{shape[1]}x{shape[0]} (width x height)"
        )
    return np.ascontiguousarray(arr)


def as_uint16_depth(values: Any, *, name: str = "depth") -> npt.NDArray[np.uint16]:
    """Convert integer-valued depth (any integer or float dtype) to uint16, exactly or not at all.

    Use it for depth loaded as int32, int64 or float64 in depth units (not metres). Raises
    :class:`~pcdcodec.InputError` for NaN, negative, fractional or too large (> 65535) values,
    naming the first offending value and where it is.
    """
    arr = values if isinstance(values, np.ndarray) else np.asarray(values)
    if arr.dtype.kind not in "iuf" and arr.dtype.kind != "b":
        raise InputTypeError(f"{name} must be numeric, got {arr.dtype}")
    if arr.ndim != 2:
        raise InputError(f"{name} must be a 2-D array (height, width), got shape {arr.shape}")
    if arr.size == 0:
        raise InputError(f"{name} must not be empty, got shape {arr.shape}")
    if arr.dtype.kind == "f":
        bad = np.isnan(arr)
        if bad.any():
            idx = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
            raise InputError(
                f"{name} has NaN at (row, col) {tuple(int(i) for i in idx)}; uint16 depth "
                "expects 0 for no measurement (use np.nan_to_num(depth, nan=0) first)"
            )
        frac = arr != np.round(arr)
        if frac.any():
            idx = np.unravel_index(int(np.flatnonzero(frac)[0]), arr.shape)
            raise InputError(
                f"{name} has a fractional value {arr[idx].item()!r} at (row, col) "
                f"{tuple(int(i) for i in idx)}; uint16 depth expects whole depth units"
            )
    lo, hi = arr.min().item(), arr.max().item()
    if lo < 0:
        raise InputError(f"{name} has a negative value {lo!r}; uint16 depth expects 0..65535")
    if hi > 65535:
        raise InputError(f"{name} has a value {hi!r} above 65535, the uint16 maximum")
    return arr.astype(np.uint16)


def check_depth_scale(value: Any, name: str = "depth_scale") -> float:
    """``value`` as a float depth scale (depth units per metre); raises
    :class:`~pcdcodec.InputTypeError` for a non-number and :class:`~pcdcodec.InputError` unless
    positive and finite, naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputTypeError(f"{name} must be a number, got {type(value).__name__}")
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"{name} must be positive and finite, got {value}")
    return float(value)


def check_positive(value: Any, name: str, *, finite: bool) -> float:
    """``value`` as a positive float (finite too when ``finite``); raises
    :class:`~pcdcodec.InputTypeError` for a non-number and :class:`~pcdcodec.InputError`
    otherwise, naming ``name`` and the value."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    real = float(value)
    if not real > 0 or (finite and not math.isfinite(real)):
        what = "positive and finite" if finite else "positive"
        raise InputError(f"{name} must be {what}, got {real!r}")
    return real


def check_output_dtype(dtype: Any) -> np.dtype[Any]:
    """The native uint16 or float32 dtype that ``dtype`` names (a depth image's), or
    :class:`~pcdcodec.InputError`."""
    out: np.dtype[Any] | None = None
    if dtype is not None:
        try:
            out = _OUTPUT_DTYPES.get(np.dtype(dtype).name)
        except TypeError:
            out = None
    if out is None:
        raise InputError(f"dtype must be 'uint16' or 'float32', got {dtype!r}")
    return out


def check_int(
    owner: str, name: str, value: Any, lo: int, hi: int, *, none_ok: bool = False
) -> None:
    """Check a codec parameter is an int in ``lo..hi`` (or ``None`` when ``none_ok``)."""
    if value is None and none_ok:
        return
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputTypeError(
            f"{owner} {name} must be an int, got {value!r} ({type(value).__name__})"
        )
    if not lo <= value <= hi:
        raise InputError(f"{owner} {name} must be in {lo}..{hi}, got {value}")


def check_number(owner: str, name: str, value: Any, lo: float, hi: float) -> None:
    """Check a codec parameter is a number in ``lo..hi``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputTypeError(
            f"{owner} {name} must be a number, got {value!r} ({type(value).__name__})"
        )
    if not lo <= value <= hi:
        raise InputError(f"{owner} {name} must be in {lo}..{hi}, got {value}")


def check_choice(owner: str, name: str, value: Any, choices: tuple[Any, ...]) -> None:
    """Check a codec parameter is one of ``choices`` (a bool only where the choices are bools:
    ``1 == True``, but a recorded ``1`` is not the ``true`` a reader of the config expects)."""
    if not any(isinstance(value, bool) == isinstance(c, bool) and value == c for c in choices):
        raise InputError(f"{owner} {name} must be one of {list(choices)}, got {value!r}")


def check_real(value: Any, name: str, *, minimum: float, inclusive: bool, unit: str) -> float:
    """A finite real number above ``minimum`` (or equal to it when ``inclusive``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputTypeError(
            f"{name} must be a number ({unit}), got {type(value).__name__} {value!r}"
        )
    real = float(value)
    ok = real >= minimum if inclusive else real > minimum
    if not (ok and math.isfinite(real)):
        bound = f">= {minimum:g}" if inclusive else f"> {minimum:g}"
        raise InputError(f"{name} must be finite and {bound} ({unit}), got {real!r}")
    return real
