"""Compiled loop of :meth:`Projector.to_point_cloud` with ``tensor=True`` (numba, cached on disk).

The numpy path of the projector makes a point cloud in about ten passes over the image and its
valid pixels (mask, indices, gathers, products, the colors' division); this loop makes the
float32 positions and colors in one pass after counting, from the same tables, so every value
is the one the numpy path computes: depth units to metres by the projector's table, ``x`` and
``y`` as the float32 products of the ray factors and ``z``, colors as ``uint8 / 255`` in
float32. Only uint16 depth at the projector's own scale, with color registered to depth (or
none), takes this path.

The arrays a cloud holds are fresh memory, and on a machine where page faults are dear, faulting
in a few megabytes per frame costs as much as filling them. :func:`cloud_arrays` therefore
reuses, per thread, the arrays of a cloud made earlier once nothing holds them any more (no
cloud, no view: only the pool's reference is left), and otherwise makes new ones, with a
little headroom so that the next frames fit.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["SHADES", "cloud_arrays", "metres_table"]

#: ``uint8 / 255`` in float32, computed as the numpy path computes it.
SHADES = np.divide(np.arange(256, dtype=np.uint8), np.float32(255.0), dtype=np.float32)

_NO_COLOR = np.zeros((0, 3), dtype=np.uint8)
_NO_MASK = np.zeros(0, dtype=np.bool_)


@njit(cache=True, nogil=True, error_model="numpy")
def _count(depth: Any, top: int, ok: Any) -> int:
    """How many pixels have depth in 1 … ``top`` (and a valid ray where ``ok`` is given)."""
    n = 0
    if ok.size:
        for i in range(depth.size):
            d = depth[i]
            n += d != 0 and d <= top and ok[i]
    else:
        for i in range(depth.size):
            d = depth[i]
            n += d != 0 and d <= top
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def _fill(
    depth: Any,
    top: int,
    ok: Any,
    metres: Any,
    ray_x: Any,
    ray_y: Any,
    color: Any,
    shades: Any,
    positions: Any,
    colors: Any,
) -> None:
    """The points (and colors) of the valid pixels in row-major order (see :func:`_count`)."""
    check = ok.size > 0
    paint = color.shape[0] > 0
    j = 0
    for i in range(depth.size):
        d = depth[i]
        if d == 0 or d > top or (check and not ok[i]):
            continue
        z = metres[d]
        positions[j, 0] = ray_x[i] * z
        positions[j, 1] = ray_y[i] * z
        positions[j, 2] = z
        if paint:
            colors[j, 0] = shades[color[i, 0]]
            colors[j, 1] = shades[color[i, 1]]
            colors[j, 2] = shades[color[i, 2]]
        j += 1


def _pooled(pool: dict[str, Any], key: str) -> tuple[npt.NDArray[np.float32] | None, int]:
    """The pool's ``key`` array (or ``None``) and its reference count as seen from here."""
    buf: npt.NDArray[np.float32] | None = pool.get(key)
    refs = sys.getrefcount(buf)  # counted before ``buf`` is on the stack for the tuple
    return buf, refs


#: The count :func:`_pooled` sees for an array that only the pool holds, measured rather than
#: assumed: which references ``sys.getrefcount`` counts (a local name, its own argument) differs
#: between Python versions, and a count one too high would hand out an array still in use. It
#: is never above 3 (the pool's, the local name's, the argument's), so that a measurement taken
#: while something else held the array (a tracer keeping frame locals) errs only towards
#: making new arrays.
_FREE = min(3, _pooled({"free": np.empty(0)}, "free")[1])


def _array(pool: dict[str, Any], key: str, n: int) -> npt.NDArray[np.float32]:
    """An N × 3 float32 array: the start of the pool's ``key`` array when nothing else holds it
    and it is at most 1/8 larger, else a new one (1/16 larger), kept in the pool."""
    buf, refs = _pooled(pool, key)
    if buf is not None and refs <= _FREE and n <= len(buf) <= n + n // 8 + 256:
        return buf[:n]
    buf = pool[key] = np.empty((n + n // 16 + 64, 3), dtype=np.float32)
    return buf[:n]


def cloud_arrays(
    depth: npt.NDArray[np.uint16],
    top: int,
    ok: npt.NDArray[np.bool_] | None,
    metres: npt.NDArray[np.float32],
    ray_x: npt.NDArray[np.float32],
    ray_y: npt.NDArray[np.float32],
    color: npt.NDArray[np.uint8] | None,
    pool: dict[str, Any] | None = None,
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32] | None]:
    """N × 3 float32 positions and colors (in [0, 1], or ``None`` without ``color``) of the
    pixels of ``depth`` (native uint16, any layout) with depth in 1 … ``top`` and, where ``ok``
    is given, a valid ray; ``metres[d]`` is the depth of ``d`` units, ``ray_x`` and ``ray_y``
    the flat per-pixel ray factors, ``color`` an H × W × 3 uint8 image of the depth's size.
    ``pool`` (one per thread) holds arrays to reuse once their clouds are gone."""
    flat = np.ascontiguousarray(depth).reshape(-1)
    mask = _NO_MASK if ok is None else ok
    n = _count(flat, top, mask)
    pool = {} if pool is None else pool
    positions = _array(pool, "cloud positions", n)
    if color is None:
        _fill(flat, top, mask, metres, ray_x, ray_y, _NO_COLOR, SHADES, positions, positions)
        return positions, None
    rgb = np.ascontiguousarray(color).reshape(-1, 3)
    colors = _array(pool, "cloud colors", n)
    _fill(flat, top, mask, metres, ray_x, ray_y, rgb, SHADES, positions, colors)
    return positions, colors


def metres_table(lut: npt.NDArray[np.float32], scale: float) -> npt.NDArray[np.float32]:
    """Metres of every uint16 depth value as the projector's numpy path computes them: a float32
    division where the scale is a float32 exactly, else the projector's table ``lut``."""
    s32 = np.float32(scale)
    if float(s32) != scale:
        return lut
    table: npt.NDArray[np.float32] = np.divide(
        np.arange(65536, dtype=np.uint16), s32, dtype=np.float32
    )
    return table
