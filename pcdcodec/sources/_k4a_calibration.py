"""The Azure Kinect's ``calibration.json`` (an attachment of its ``.mkv`` files): cameras and
their extrinsics, every field checked, errors naming the field."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..geometry.camera import CameraIntrinsics

__all__ = ["camera_of", "field", "numbers", "rt"]


def field(value: Any, keys: tuple[str | int, ...], where: str) -> Any:
    """``value[k0][k1]...``, or an :class:`~pcdcodec.InputError` naming the missing field."""
    path = "calibration.json"
    for k in keys:
        path += f"[{k}]" if isinstance(k, int) else f".{k}"
        ok = (
            isinstance(value, dict) and k in value
            if isinstance(k, str)
            else (isinstance(value, list) and 0 <= k < len(value))
        )
        if not ok:
            raise InputError(f"{where}: {path} is missing or not of the expected type")
        value = value[k]
    return value


def numbers(value: Any, n: int | None, field: str, where: str) -> list[float]:
    """A list of ``n`` (or at least 1) finite numbers from the calibration, or an
    :class:`~pcdcodec.InputError` naming ``field`` and what it holds."""
    if not isinstance(value, list) or (len(value) != n if n is not None else not value):
        got = f"{len(value)} values" if isinstance(value, list) else repr(value)[:60]
        raise InputError(
            f"{where}: calibration.json {field} holds {got}; expected a list of "
            f"{n if n is not None else 'some'} numbers"
        )
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise InputError(
                f"{where}: calibration.json {field}[{i}] is {v!r}; expected a finite number"
            )
    return [float(v) for v in value]


def camera_of(
    cal: dict[str, Any],
    mode: tuple[tuple[int, int], tuple[int, int], tuple[int, int]],
    what: str,
    where: str,
) -> CameraIntrinsics:
    raw = field(cal, ("Intrinsics", "ModelParameters"), where)
    if not isinstance(raw, list) or len(raw) < 14:
        got = f"{len(raw)}" if isinstance(raw, list) else repr(raw)[:60]
        raise InputError(
            f"{where}: {what} calibration has {got} model parameters, expected 14 numbers"
        )
    params = numbers(raw[:14], 14, f"{what} Intrinsics.ModelParameters", where)
    (bw, bh), (ox, oy), (w, h) = mode
    cx, cy, fx, fy = params[:4]
    if not (fx > 0 and fy > 0):
        raise InputError(f"{where}: {what} calibration has focal lengths {fx}, {fy}; expected > 0")
    k1, k2, k3, k4, k5, k6 = params[4:10]
    p2, p1 = params[12], params[13]
    try:
        return CameraIntrinsics(
            w,
            h,
            fx * bw,
            fy * bh,
            cx * bw - ox - 0.5,
            cy * bh - oy - 0.5,
            "rational_polynomial",
            (k1, k2, p1, p2, k3, k4, k5, k6),
        )
    except InputError as exc:
        raise InputError(f"{where}: calibration.json {what} Intrinsics: {exc}") from None


def rt(cal: dict[str, Any], what: str, where: str) -> npt.NDArray[np.float64]:
    """The 4 × 4 transform from the depth camera to this camera (``Rt``: rotation row-major,
    translation in metres)."""
    rotation = numbers(field(cal, ("Rt", "Rotation"), where), 9, f"{what} Rt.Rotation", where)
    translation = numbers(
        field(cal, ("Rt", "Translation"), where), 3, f"{what} Rt.Translation", where
    )
    m = np.eye(4)
    m[:3, :3] = np.reshape(rotation, (3, 3))
    m[:3, 3] = translation
    with np.errstate(all="ignore"):
        orthonormal = np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-3)
    if not orthonormal:
        raise InputError(
            f"{where}: calibration.json {what} Rt.Rotation {rotation} is not a rotation matrix"
        )
    return m
