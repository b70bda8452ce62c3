"""Rigid transforms: checking 4 × 4 matrices, quaternions, and interpolating poses.

A rigid transform is a 4 × 4 float64 matrix ``[[R, t], [0, 0, 0, 1]]`` with ``R`` a rotation
(orthonormal, determinant +1) and ``t`` a translation in metres. It maps a point ``p`` of one
frame to ``R @ p + t`` in another. Camera poses are camera-to-world transforms; the extrinsic
``depth_to_color`` maps points of the depth camera's frame into the color camera's frame.

Quaternions are ``(x, y, z, w)``, the order of ROS ``geometry_msgs/Quaternion``, Foxglove and
TUM trajectories. :func:`check_color_camera` checks the pair a color camera apart from the depth
camera is given by: its intrinsics and the ``depth_to_color`` transform.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, InputTypeError
from .camera import CameraIntrinsics

__all__ = [
    "MAX_BASELINE",
    "as_rigid",
    "check_color_camera",
    "interpolate_poses",
    "matrix_to_quaternion",
    "quaternion_to_matrix",
    "rigid_from_quaternion",
    "slerp",
]

#: How far ``R.T @ R`` may be from the identity: poses saved as text (7-Scenes) are off by
#: up to 2e-4; a scale or shear of a few per mille is refused.
RIGID_TOLERANCE = 1e-3


def as_rigid(value: Any, name: str = "transform") -> npt.NDArray[np.float64]:
    """``value`` as a rigid 4 × 4 float64 matrix (a new array), or a clear error.

    Raises :class:`~pcdcodec.InputTypeError` for something that is not an array of numbers and
    :class:`~pcdcodec.InputError` naming ``name`` when it is not 4 × 4, not finite, its last row
    is not ``[0, 0, 0, 1]``, or its rotation is not orthonormal with determinant +1 (within
    :data:`RIGID_TOLERANCE`; a scale, shear or mirror is refused).
    """
    try:
        m = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputTypeError(
            f"{name} must be a 4x4 array of numbers, got {type(value).__name__}"
        ) from None
    if m.shape != (4, 4):
        raise InputError(f"{name} must be a 4x4 rigid transform, got shape {m.shape}")
    if not np.isfinite(m).all():
        raise InputError(f"{name} must be finite, got {m.tolist()}")
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9, rtol=0):
        raise InputError(f"the last row of {name} must be [0, 0, 0, 1], got {m[3].tolist()}")
    r = m[:3, :3]
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    det = float(np.linalg.det(r))
    if err > RIGID_TOLERANCE or det < 0:
        raise InputError(
            f"{name} is not a rigid transform: its 3x3 rotation part {np.round(r, 6).tolist()} "
            f"is not a rotation (|R^T R - I| = {err:.3g}, det = {det:.6g}; expected 0 and +1)"
        )
    m[3] = (0.0, 0.0, 0.0, 1.0)
    return m


def quaternion_to_matrix(q: Any) -> npt.NDArray[np.float64]:
    """The 3 × 3 rotation of a quaternion ``(x, y, z, w)`` (normalised first)."""
    x, y, z, w = np.asarray(q, dtype=np.float64)
    n = x * x + y * y + z * z + w * w
    if not n > 1e-12:
        raise InputError(f"quaternion {list(map(float, (x, y, z, w)))} has zero length")
    s = 2.0 / n
    return np.array(
        [
            [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
            [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
            [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)],
        ]
    )


def matrix_to_quaternion(r: Any) -> npt.NDArray[np.float64]:
    """The unit quaternion ``(x, y, z, w)``, ``w >= 0``, of a 3 × 3 rotation matrix."""
    m = np.asarray(r, dtype=np.float64)[:3, :3]
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    out = np.asarray(q, dtype=np.float64)
    out /= np.linalg.norm(out)
    return -out if out[3] < 0 else out


def rigid_from_quaternion(translation: Any, quaternion: Any) -> npt.NDArray[np.float64]:
    """A 4 × 4 rigid transform from a translation ``(x, y, z)`` and a quaternion
    ``(x, y, z, w)``."""
    m = np.eye(4)
    m[:3, :3] = quaternion_to_matrix(quaternion)
    m[:3, 3] = np.asarray(translation, dtype=np.float64)
    return m


def slerp(q0: Any, q1: Any, t: float) -> npt.NDArray[np.float64]:
    """Spherical linear interpolation between unit quaternions, ``t`` in [0, 1], shortest arc."""
    a = np.asarray(q0, dtype=np.float64) / np.linalg.norm(q0)
    b = np.asarray(q1, dtype=np.float64) / np.linalg.norm(q1)
    dot = float(a @ b)
    if dot < 0:
        b, dot = -b, -dot
    if dot > 0.9995:  # nearly equal: linear interpolation is exact to float precision
        out: npt.NDArray[np.float64] = a + t * (b - a)
    else:
        theta = np.arccos(dot)
        out = (np.sin((1 - t) * theta) * a + np.sin(t * theta) * b) / np.sin(theta)
    result: npt.NDArray[np.float64] = out / np.linalg.norm(out)
    return result


def interpolate_poses(
    times: Any, poses: Any, query: Any, *, max_gap: int | None = None
) -> list[npt.NDArray[np.float64] | None]:
    """Poses at the ``query`` times, interpolated between the given timed poses.

    ``times`` (increasing, ns) and ``poses`` (4 × 4 each) are the trajectory; for each query
    time the two poses around it are blended: translation linearly, rotation by
    :func:`slerp`. A query outside the trajectory, or between two poses more than ``max_gap``
    ns apart, gets ``None`` (no pose) rather than an extrapolated guess.
    """
    t = np.asarray(times, dtype=np.int64)
    out: list[npt.NDArray[np.float64] | None] = []
    if t.size == 0:
        return [None for _ in np.atleast_1d(query)]
    if np.any(np.diff(t) <= 0):
        raise InputError("pose times must increase")
    quats = [matrix_to_quaternion(p) for p in poses]
    for q in np.atleast_1d(np.asarray(query, dtype=np.int64)).tolist():
        i = int(np.searchsorted(t, q, side="left"))
        if i < t.size and t[i] == q:
            out.append(np.array(poses[i], dtype=np.float64))
            continue
        if i == 0 or i == t.size:
            out.append(None)
            continue
        t0, t1 = int(t[i - 1]), int(t[i])
        if max_gap is not None and t1 - t0 > max_gap:
            out.append(None)
            continue
        a = (q - t0) / (t1 - t0)
        p0, p1 = np.asarray(poses[i - 1], np.float64), np.asarray(poses[i], np.float64)
        m = np.eye(4)
        m[:3, :3] = quaternion_to_matrix(slerp(quats[i - 1], quats[i], a))
        m[:3, 3] = (1 - a) * p0[:3, 3] + a * p1[:3, 3]
        out.append(m)
    return out


# -- two cameras ------------------------------------------------------------------------------

#: The largest distance (metres) between a depth and a color camera that is taken as metres.
MAX_BASELINE = 5.0


def check_color_camera(
    color_intrinsics: Any, depth_to_color: Any
) -> tuple[CameraIntrinsics | None, npt.NDArray[np.float64] | None]:
    """Validated ``(color_intrinsics, depth_to_color)`` of a second camera, or ``(None, None)``.

    ``depth_to_color`` defaults to the identity when only ``color_intrinsics`` is given (a
    color camera at the depth camera's centre, of another size or lens). Raises
    :class:`~pcdcodec.InputError` for a transform without color intrinsics, a transform that
    is not rigid, or a translation longer than :data:`MAX_BASELINE` (millimetres given as
    metres, most likely).
    """
    if color_intrinsics is None:
        if depth_to_color is not None:
            raise InputError(
                "depth_to_color was given without color_intrinsics: the transform needs the "
                "color camera it leads to"
            )
        return None, None
    if not isinstance(color_intrinsics, CameraIntrinsics):
        raise InputTypeError(
            "color_intrinsics must be a pcdcodec.CameraIntrinsics, got "
            f"{type(color_intrinsics).__name__}"
        )
    d2c = np.eye(4) if depth_to_color is None else as_rigid(depth_to_color, "depth_to_color")
    baseline = float(np.linalg.norm(d2c[:3, 3]))
    if baseline > MAX_BASELINE:
        raise InputError(
            f"depth_to_color moves the camera by {baseline:.4g} m; expected a translation in "
            f"metres of at most {MAX_BASELINE} m between the depth and color cameras "
            "(was it given in millimetres?)"
        )
    return color_intrinsics, d2c
