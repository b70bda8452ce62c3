"""Bounded-error depth: reconstruction levels that keep every valid pixel within a stated error.

A depth codec given ``max_error`` (absolute) and/or ``max_rel_error`` (a fraction of depth)
stores a frame lossily with the guarantee that every valid pixel decodes within

    B(v) = max(max_error, max_rel_error · v)

of its value ``v`` (the larger bound wins where both are given). Units are those of the frame:
depth units for uint16 (millimetres at a depth scale of 1000), metres for float32.

The frame is mapped onto a monotone table ``T`` of reconstruction levels and coded as an image
of level indices (0 = no measurement, valid pixels ≥ 1). A codec may code that index image with
a tolerance of ``near`` indices (near-lossless, the error bounded inside its prediction loop):
the table and the map ``f`` from values to indices are built so that *every* level within
``near`` indices of ``f(v)`` is within ``B(v)`` of ``v``. The property is verified before use:
exhaustively over all 65,535 uint16 values, and for float32 on the frame's own pixels after
decoding. The decoder rebuilds ``T`` from a few parameters written into the frame
(``docs/format.md``, bounded-error layout).

uint16 levels are integers, one per value where the bound is below one unit (so small depths
stay exact) and spaced geometrically where the relative bound dominates. Holes stay holes,
valid pixels never become holes, and float32 NaN stays NaN.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError, InputTypeError

__all__ = [
    "ErrorBound",
    "LatticeParams",
    "check_bound",
    "decode_levels",
    "float_frame_levels",
    "float_lattice",
    "frame_levels",
    "quantise_float",
    "uint16_lattice",
]

#: Safety factors tried in turn when a lattice fails its verification (the first that passes is
#: written into the frame, so the decoder rebuilds the same table).
_SAFETY = (1.0, 0.995, 0.98, 0.95, 0.9, 0.8, 0.6)
#: The most level indices an index image can hold (0 is the hole).
MAX_LEVELS = 65535

# lattice version, kind (KIND_*), near, safety index,
# max_error, max_rel_error, lo, hi (float64), hole bits, level count (uint32)
_PARAMS = struct.Struct("<BBBBddddII")
PARAMS_SIZE = _PARAMS.size
_LATTICE_VERSION = 1


def _real(value: Any, name: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, str):  # from a codec spec such as "depthac:max_rel_error=abc"
        try:
            value = float(value)
        except ValueError:
            raise InputTypeError(f"{name} must be a number such as 0.005, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputTypeError(
            f"{name} must be a number such as 0.005 (or None for no bound), got {value!r}"
        )
    out = float(value)
    if not math.isfinite(out) or out < 0:
        raise InputError(f"{name} must be a finite number >= 0, got {value!r}")
    return out


def check_bound(
    max_error: Any, max_rel_error: Any, *, codec: str = "depth codec"
) -> tuple[float | None, float | None]:
    """Validate the two bound options of a depth codec; returns them as floats (or ``None``).

    ``max_error`` must be finite and ≥ 0; ``max_rel_error`` finite, ≥ 0 and < 1. Raises
    :class:`~pcdcodec.InputError` (or :class:`~pcdcodec.InputTypeError`) naming the value.
    """
    abs_b = _real(max_error, f"{codec} max_error")
    rel_b = _real(max_rel_error, f"{codec} max_rel_error")
    if rel_b is not None and rel_b >= 1:
        raise InputError(
            f"{codec} max_rel_error is a fraction of depth and must be < 1 "
            f"(0.01 is 1 %), got {max_rel_error!r}"
        )
    return abs_b, rel_b


@dataclass(frozen=True)
class ErrorBound:
    """A maximum depth error: ``max(abs_error, rel_error · depth)`` in the frame's units."""

    abs_error: float
    rel_error: float

    @property
    def exact(self) -> bool:
        """True when the bound allows no error at all (lossless coding is used)."""
        return self.abs_error == 0 and self.rel_error == 0

    def of(self, values: npt.NDArray[Any]) -> npt.NDArray[np.float64]:
        """The bound at each value, in float64."""
        v = np.asarray(values, dtype=np.float64)
        out: npt.NDArray[np.float64] = np.maximum(self.abs_error, self.rel_error * v)
        return out


# -- the level tables -----------------------------------------------------------------------


def _choose_index(
    levels: npt.NDArray[np.float64], values: npt.NDArray[np.float64], near: int
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """For each value, the index (1..n-near, into ``levels`` with a dummy at 0) whose window of
    indices ±``near`` (clamped below at 1, as the near-lossless decoder clamps) strays least
    from the value; returns the indices and that worst distance."""
    n = levels.size - 1
    top = n - near
    pos = np.searchsorted(levels[1:], values) + 1  # first level >= value (n + 1 if none)
    if near == 0:
        # The window is the level itself: the nearer of the two levels around the value.
        below = np.maximum(pos - 1, 1)
        above = np.minimum(pos, n)
        d_below = np.abs(values - levels[below])
        d_above = np.abs(levels[above] - values)
        nearer = d_above < d_below
        return np.where(nearer, above, below), np.where(nearer, d_above, d_below)
    best_k = np.ones(values.shape, dtype=np.int64)
    best_cost = np.full(values.shape, np.inf)
    for shift in range(-near - 1, near + 1):
        k = np.clip(pos + shift, 1, max(top, 1))
        hi = levels[np.minimum(k + near, n)]
        lo = levels[np.maximum(k - near, 1)]
        cost = np.maximum(np.abs(hi - values), np.abs(values - lo))
        better = cost < best_cost
        best_k = np.where(better, k, best_k)
        best_cost = np.where(better, cost, best_cost)
    return best_k, best_cost


def _uint16_levels(bound: ErrorBound, near: int, safety: float) -> npt.NDArray[np.float64]:
    """Integer levels covering 1..65535 (index 0 is a dummy for the hole)."""
    width = 2 * near + 1
    levels: list[int] = [0]
    v = 1
    prev = 1
    a, r = bound.abs_error * safety, bound.rel_error * safety
    while v <= 65535:
        # Integer data: only whole units of the bound count. The bound is taken a window's
        # width below the cell, so the larger steps above stay inside the bound of this cell.
        low = max(1, v - (near + 1) * prev) if near else v
        b = math.floor(max(a, r * low))
        step = (2 * b + 1) // width
        if step % 2 == 0 and step * width > 2 * b:
            step -= 1
        if step < 1:
            # The bound is below the tolerance: each value gets its own run of indices.
            levels.extend([v] * width)
            v += 1
            prev = 1
        else:
            # The level sits in the middle of the values it stands for.
            levels.append(min(v + (step - 1) // 2, 65535))
            v += step
            prev = step
        if len(levels) > MAX_LEVELS + 1:
            break
    levels.extend([levels[-1]] * near)
    return np.asarray(levels, dtype=np.float64)


@lru_cache(maxsize=32)
def _uint16_table(
    abs_error: float, rel_error: float, near: int, safety: float
) -> tuple[npt.NDArray[np.uint16], npt.NDArray[np.uint16]] | None:
    bound = ErrorBound(abs_error, rel_error)
    levels = _uint16_levels(bound, near, safety)
    if levels.size - 1 > MAX_LEVELS:
        return None
    values = np.arange(1, 65536, dtype=np.float64)
    index, cost = _choose_index(levels, values, near)
    if not np.all(cost <= bound.of(values)):
        return None
    lut = np.zeros(65536, dtype=np.uint16)
    lut[1:] = index
    table = levels.astype(np.uint16)
    table.flags.writeable = False
    lut.flags.writeable = False
    return table, lut


def uint16_lattice(
    bound: ErrorBound, near: int
) -> tuple[int, npt.NDArray[np.uint16], npt.NDArray[np.uint16]] | None:
    """The verified uint16 lattice for ``bound`` and tolerance ``near``: (safety index, level
    table with a 0 at index 0, map from value to index), or ``None`` when none fits 65,535
    levels. Every level within ``near`` indices of ``map[v]`` is within the bound of ``v``,
    checked for every v in 1..65535. Cached per bound."""
    for i, safety in enumerate(_SAFETY):
        built = _uint16_table(bound.abs_error, bound.rel_error, near, safety)
        if built is not None:
            return (i, *built)
    return None


def _float_levels(
    bound: ErrorBound, near: int, safety: float, lo: float, hi: float
) -> npt.NDArray[np.float64] | None:
    """Levels from ``lo`` up past ``hi`` in float64 (index 0 a dummy), or ``None`` when more than
    :data:`MAX_LEVELS` are needed. Built with additions and products only, so every machine
    rebuilds the same table."""
    frac = 2.0 * safety / (2 * near + 1)
    a = bound.abs_error * frac
    g = 1.0 + bound.rel_error * frac
    parts: list[npt.NDArray[np.float64]] = [np.zeros(1)]
    count = 0
    start = lo
    # Uniform steps while the absolute bound dominates.
    cross = bound.abs_error / bound.rel_error if bound.rel_error > 0 else math.inf
    if a > 0 and start < cross:
        end = min(cross, hi)
        n = int((end - start) // a) + 1
        if n + near > MAX_LEVELS:
            return None
        uniform = start + a * np.arange(n, dtype=np.float64)
        parts.append(uniform)
        count += n
        start = float(uniform[-1]) + a
        if start > hi:
            parts.append(start + a * np.arange(near + 1, dtype=np.float64))
            return np.concatenate(parts)
    if g <= 1.0:
        return None
    # Geometric steps where the relative bound dominates, in chunks until past hi.
    chunk = 1024
    last = start
    first = True
    while True:
        factors = np.full(chunk, g)
        if first:
            factors[0] = 1.0
            first = False
        seq = last * np.cumprod(factors)
        count += chunk
        if count > MAX_LEVELS + chunk:
            return None
        parts.append(seq)
        last = float(seq[-1]) * g
        if seq[-1] > hi:
            break
    levels = np.concatenate(parts)
    above = int(np.searchsorted(levels[1:], hi)) + 1  # first level >= hi
    levels = levels[: min(levels.size, above + near + 1)]
    if levels.size - 1 > MAX_LEVELS:
        return None
    return levels


@lru_cache(maxsize=16)
def float_lattice(
    abs_error: float, rel_error: float, near: int, safety_index: int, lo: float, hi: float
) -> npt.NDArray[np.float32] | None:
    """The float32 level table (index 0 a dummy) for a frame whose valid values span
    ``lo``..``hi`` metres, or ``None`` when it would need more than 65,535 levels."""
    if not 0 <= safety_index < len(_SAFETY):
        return None
    levels = _float_levels(ErrorBound(abs_error, rel_error), near, _SAFETY[safety_index], lo, hi)
    if levels is None:
        return None
    table = levels.astype(np.float32)
    table[0] = 0
    table.flags.writeable = False
    return table


def quantise_float(
    image: npt.NDArray[np.float32], valid: npt.NDArray[np.bool_], bound: ErrorBound, near: int
) -> tuple[int, float, float, npt.NDArray[np.float32], npt.NDArray[np.uint16]] | None:
    """Map a float32 frame onto its lattice: (safety index, lo, hi, table, index image), or
    ``None`` when no lattice of at most 65,535 levels keeps the bound at tolerance ``near``.
    The caller verifies the decoded values again (the near-lossless coder picks any index in
    the window)."""
    values = image[valid].astype(np.float64)
    lo, hi = float(values.min()), float(values.max())
    for i in range(len(_SAFETY)):
        table = float_lattice(bound.abs_error, bound.rel_error, near, i, lo, hi)
        if table is None:
            return None
        index, cost = _choose_index(table.astype(np.float64), values, near)
        if np.all(cost <= bound.of(values)):
            out = np.zeros(image.shape, dtype=np.uint16)
            out[valid] = index
            return i, lo, hi, table, out
    return None


def frame_levels(
    image: npt.NDArray[np.uint16], bound: ErrorBound, *, centre: bool = True
) -> tuple[npt.NDArray[np.uint16], int] | None:
    """Levels fitted to a uint16 frame's own values: the image with every valid value replaced
    by its level, and the number of levels; ``None`` if the check below fails (it cannot).

    The fewest levels that cover the frame's distinct values are found greedily: from the
    smallest value s not yet covered, the level may be as high as s + ⌊B(s)⌋ and then also
    covers larger values v with v − ⌊B(v)⌋ at or below it. With ``centre`` each group's level
    then moves, within what keeps every member's bound, to the one nearest the mean of the
    group's pixels (the same count, smaller errors). Levels fall on the sensor's own values
    where it quantises more coarsely than the bound, and every valid value is checked against
    its bound.
    """
    import bisect

    hist = np.bincount(image.ravel(), minlength=65536)
    u = np.flatnonzero(hist[1:]) + 1  # distinct valid values, ascending
    if u.size == 0:
        return image.copy(), 0
    uf = u.astype(np.float64)
    slack = np.floor(np.maximum(bound.abs_error, bound.rel_error * uf)).astype(np.int64)
    reach = (u - slack).tolist()  # nondecreasing: v - floor(B(v)) grows with v
    ul = u.tolist()
    sl = slack.tolist()
    n = len(ul)
    starts: list[int] = []
    levels: list[int] = []
    i = 0
    while i < n:
        top = min(ul[i] + sl[i], 65535)
        j = bisect.bisect_right(ul, top, i) - 1
        k = max(j, bisect.bisect_right(reach, top, i) - 1)
        starts.append(i)
        levels.append(top if k > j else ul[(i + j) // 2])
        i = k + 1
    first = np.asarray(starts)
    counts = np.diff(np.asarray([*starts, n]))
    if centre:
        # Any level between the group's highest v - floor(B(v)) and its lowest
        # v + floor(B(v)) keeps the bound: take the one nearest the group's mean pixel.
        weight = hist[u].astype(np.float64)
        mean = np.add.reduceat(weight * uf, first) / np.add.reduceat(weight, first)
        low = np.asarray(reach)[first + counts - 1]
        high = np.minimum(u[first] + slack[first], 65535)
        chosen = np.clip(np.rint(mean).astype(np.int64), low, high)
    else:
        chosen = np.asarray(levels, dtype=np.int64)
    mapped = np.repeat(chosen, counts)
    if not np.all(np.abs(mapped - u) <= slack):
        return None
    lut = np.zeros(65536, dtype=np.uint16)
    lut[u] = mapped
    return lut[image], len(levels)


def float_frame_levels(
    image: npt.NDArray[np.float32], valid: npt.NDArray[np.bool_], bound: ErrorBound
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint16]] | None:
    """Levels fitted to a float32 frame's own values, as :func:`frame_levels` does for uint16:
    (the float32 levels, ascending, and the index image: 0 for holes, 1..K into the levels),
    or ``None`` when the frame has more than 65,535 distinct valid values or a level rounded to
    float32 would leave a value's bound (then the fixed lattice is used)."""
    import bisect

    from ._table_kernels import distinct_values

    values = image[valid]
    # Positive floats sort as their bit patterns do.
    found, first_seen, status = distinct_values(values.view(np.uint32), MAX_LEVELS)
    if status == 1:
        return None
    if status == 0:
        order = np.argsort(found)
        rank = np.empty(order.size, dtype=np.int64)
        rank[order] = np.arange(order.size)
        u32 = found[order].view(np.float32)
        inverse = rank[first_seen]
        hist = np.bincount(inverse, minlength=order.size)
    else:  # keys built to collide: sort instead
        u32, inverse, hist = np.unique(values, return_inverse=True, return_counts=True)
        if u32.size > MAX_LEVELS:
            return None
    u = u32.astype(np.float64)
    slack = bound.of(u)
    reach = (u - slack).tolist()  # nondecreasing since the relative bound is below 1
    ul = u.tolist()
    top_of = (u + slack).tolist()
    n = len(ul)
    starts: list[int] = []
    i = 0
    while i < n:
        top = top_of[i]
        j = bisect.bisect_right(ul, top, i) - 1
        starts.append(i)
        i = max(j, bisect.bisect_right(reach, top, i) - 1) + 1
    first = np.asarray(starts)
    counts = np.diff(np.asarray([*starts, n]))
    weight = hist.astype(np.float64)
    mean = np.add.reduceat(weight * u, first) / np.add.reduceat(weight, first)
    low = np.asarray(reach)[first + counts - 1]
    high = u[first] + slack[first]
    # Keep a few float32 steps inside the interval, so rounding to float32 stays in it.
    margin = np.minimum((high - low) / 2, np.abs(high) * 2.5e-7)
    levels = np.clip(mean, low + margin, high - margin).astype(np.float32)
    group = np.repeat(np.arange(first.size), counts)
    if not np.all(np.abs(levels[group].astype(np.float64) - u) <= slack):
        return None
    if not np.all(levels > 0) or np.any(np.diff(levels) <= 0):
        return None
    index = np.zeros(image.shape, dtype=np.uint16)
    index[valid] = (group[inverse.ravel()] + 1).astype(np.uint16)
    return levels, index


# -- the parameter block ---------------------------------------------------------------------


#: Kinds of level table a bounded-error frame names.
KIND_U16_LATTICE = 1  # uint16: the fixed lattice of (bound, near); the image holds indices
KIND_F32_LATTICE = 2  # float32: the lattice over the frame's range; the image holds indices
KIND_U16_FRAME = 3  # uint16: levels fitted to the frame; the image holds the levels themselves
KIND_F32_FRAME = 4  # float32: levels fitted to the frame, stored after the parameters


@dataclass(frozen=True)
class LatticeParams:
    """What a bounded-error frame states so its decoder rebuilds the level table."""

    kind: int
    near: int
    safety_index: int
    abs_error: float
    rel_error: float
    lo: float
    hi: float
    hole_bits: int
    levels: int

    @property
    def is_float(self) -> bool:
        return self.kind in (KIND_F32_LATTICE, KIND_F32_FRAME)

    def pack(self) -> bytes:
        return _PARAMS.pack(
            _LATTICE_VERSION,
            self.kind,
            self.near,
            self.safety_index,
            self.abs_error,
            self.rel_error,
            self.lo,
            self.hi,
            self.hole_bits,
            self.levels,
        )

    @classmethod
    def unpack(cls, data: memoryview) -> LatticeParams:
        if len(data) < _PARAMS.size:
            raise DecodeError("bounded-error frame is truncated inside its lattice parameters")
        ver, kind, near, si, a, r, lo, hi, hole, n = _PARAMS.unpack_from(data, 0)
        if ver != _LATTICE_VERSION:
            raise DecodeError(f"bounded-error frame has unknown lattice version {ver}")
        if kind not in (KIND_U16_LATTICE, KIND_F32_LATTICE, KIND_U16_FRAME, KIND_F32_FRAME):
            raise DecodeError(f"bounded-error frame has unknown lattice kind {kind}")
        fitted = kind in (KIND_U16_FRAME, KIND_F32_FRAME)
        if si >= len(_SAFETY) or near > 16 or (fitted and near) or n > MAX_LEVELS:
            raise DecodeError(
                f"bounded-error frame has invalid lattice parameters (kind {kind}, near {near}, "
                f"step {si})"
            )
        finite = all(math.isfinite(x) for x in (a, r, lo, hi))
        if not finite or a < 0 or not 0 <= r < 1 or (a == 0 and r == 0) or lo > hi:
            raise DecodeError(
                f"bounded-error frame has invalid bounds (max_error {a}, max_rel_error {r}, "
                f"range {lo}..{hi})"
            )
        return cls(kind, near, si, a, r, lo, hi, hole, n)

    def table(self) -> npt.NDArray[Any]:
        """The level table these parameters describe; raises DecodeError if it cannot be built."""
        bound = ErrorBound(self.abs_error, self.rel_error)
        table: npt.NDArray[Any] | None
        if self.is_float:
            if not self.lo > 0:
                raise DecodeError(f"bounded-error float frame has an invalid range start {self.lo}")
            table = float_lattice(
                bound.abs_error, bound.rel_error, self.near, self.safety_index, self.lo, self.hi
            )
        else:
            built = _uint16_table(
                bound.abs_error, bound.rel_error, self.near, _SAFETY[self.safety_index]
            )
            table = None if built is None else built[0]
        if table is None or table.size - 1 != self.levels:
            raise DecodeError(
                f"bounded-error frame states {self.levels} levels, but its parameters give "
                f"{'none' if table is None else table.size - 1}"
            )
        return table


def decode_levels(
    params: LatticeParams,
    index: npt.NDArray[np.uint16],
    dtype: np.dtype[Any],
    stored: npt.NDArray[np.float32] | None = None,
) -> npt.NDArray[Any]:
    """Turn a decoded index image back into depth of ``dtype`` (``stored``: the levels a kind 4
    frame carries); raises DecodeError on an index outside the table."""
    if params.kind == KIND_U16_FRAME:
        return index  # the levels themselves, checked by the frame's CRC
    if params.kind == KIND_F32_FRAME:
        if stored is None or stored.size != params.levels:
            raise DecodeError(
                f"bounded-error frame states {params.levels} levels but stores "
                f"{0 if stored is None else stored.size}"
            )
        table = np.concatenate([np.zeros(1, dtype=np.float32), stored])
    else:
        table = params.table()
    if index.size and int(index.max()) > params.levels:
        raise DecodeError(
            f"bounded-error frame holds level index {int(index.max())}, "
            f"beyond its {params.levels} levels"
        )
    if params.is_float:
        out = table[index]
        out[index == 0] = np.uint32(params.hole_bits).view(np.float32)
        return out.astype(dtype, copy=False)
    values: npt.NDArray[Any] = table[index]  # table[0] is 0, the hole
    return values.astype(dtype, copy=False)
