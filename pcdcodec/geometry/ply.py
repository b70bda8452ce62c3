"""Point clouds as binary PLY files of float32 points, the precision the clouds are made in.

Open3D's legacy writer stores a cloud's points as float64 (its legacy clouds hold doubles),
which doubles the size of the points without adding anything: a cloud made from depth is
float32 (:meth:`~pcdcodec.geometry.projector.Projector.to_points`). :func:`write_ply` writes
the float32 points as they are, and 8-bit colors, in the standard binary PLY layout that
Open3D, PCL, MeshLab and CloudCompare read.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError

__all__ = ["write_ply"]


def write_ply(
    path: str | os.PathLike[str],
    points: npt.NDArray[np.float32],
    colors: npt.NDArray[np.uint8] | None = None,
) -> None:
    """Write ``points`` (N × 3 float32, metres) and their ``colors`` (N × 3 uint8 RGB, or
    ``None``) as a binary little-endian PLY file: properties ``float x, y, z`` and, with
    colors, ``uchar red, green, blue``.

    Raises :class:`~pcdcodec.InputError` for points that are not N × 3 float32 or colors
    that do not match them (the points are never converted: a float64 cloud is the caller's
    to round).
    """
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.dtype != np.float32:
        raise InputError(f"points must be N x 3 float32, got {pts.shape} {pts.dtype}")
    fields: list[tuple[str, Any]] = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        rgb = np.asarray(colors)
        if rgb.shape != pts.shape or rgb.dtype != np.uint8:
            raise InputError(
                f"colors must be {len(pts)} x 3 uint8 like the points, got {rgb.shape} {rgb.dtype}"
            )
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    rows = np.empty(len(pts), dtype=np.dtype(fields))
    rows["x"], rows["y"], rows["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if colors is not None:
        rows["red"], rows["green"], rows["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    kinds = {"<f4": "float", "u1": "uchar"}
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(pts)}"]
    header += [f"property {kinds[kind]} {name}" for name, kind in fields]
    header.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(rows.tobytes())
