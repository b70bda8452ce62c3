"""Pairing separate color and depth streams by nearest timestamp.

RGB-D sensors often deliver color and depth as two streams whose timestamps never match
exactly, and either stream can drop a frame. This module pairs them the way TUM RGB-D's
``associate.py`` does, and online in the spirit of ROS ``message_filters``' ApproximateTime
policy:

* :func:`associate` pairs two complete lists of timestamps. Candidate pairs are those with
  ``|color - (depth + offset)| <= max_difference``; they are accepted greedily, smallest
  ``|difference|`` first, each stamp used at most once. Equal differences are broken by the
  earlier color stamp, then the earlier depth stamp (the order ``associate.py`` sorts its
  candidates in). Unlike ``associate.py``, the tolerance is inclusive and the arithmetic is
  exact integer nanoseconds rather than float seconds.
* :class:`Synchronizer` does the same while recording: stamps are added one at a time and a
  pair is handed out as soon as no stamp that can still arrive could change it.

All timestamps, differences and tolerances are integer nanoseconds, as everywhere in pcdcodec.

**One rule for every reader.** Every input whose color and depth are two streams (ROS bags,
RealSense ``.bag``, Azure Kinect ``.mkv``, TUM lists, frames handed to a writer one stream at a
time) is paired by this rule, each image used at most once, with one default tolerance,
:data:`MAX_DIFFERENCE` (20 ms, TUM's), and each reader reports the images left without a partner
as ``dropped``. 20 ms is a little over half the frame period of 30 fps streams (16.7 ms) and
under half that of 25 fps ones: a depth image paired with a color image farther away than that
shows the scene closer in time to another color frame than to its own. A reader takes another
tolerance as ``max_difference=`` (ns; the command line's ``--max-difference 150ms``,
:func:`parse_duration`).

How it stays fast (100k stamps per stream take milliseconds, memory O(n + m)): among the stamps
still free, the pair with the smallest difference is always adjacent in the merged time order,
and a pair in which each stamp is the other's nearest free partner (*mutual nearest*) is always
accepted by the greedy rule, since nothing it could lose to comes earlier in the greedy order.
:func:`associate` therefore accepts all mutual-nearest pairs at once with ``np.searchsorted``,
removes them and repeats; when a round finds few, it finishes the leftovers with a heap of
adjacent candidates over a linked list. Both steps give exactly the greedy result.
"""

from __future__ import annotations

import heapq
from bisect import bisect_left
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt

from .errors import InputError, InputTypeError

__all__ = [
    "MAX_DIFFERENCE",
    "Association",
    "Synchronizer",
    "as_max_difference",
    "associate",
    "parse_duration",
]

#: The largest color/depth stamp difference every reader pairs by default, ns (20 ms; see above).
MAX_DIFFERENCE = 20_000_000

_UNITS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": 1_000_000_000}


def as_max_difference(value: Any, name: str = "max_difference") -> int:
    """A pairing tolerance: int nanoseconds, at least 0. Raises
    :class:`~pcdcodec.InputTypeError` for a value that is not an int (a float of seconds, a
    string) and :class:`~pcdcodec.InputError` for a negative one."""
    if isinstance(value, str):
        raise InputTypeError(
            f"{name} must be an int number of nanoseconds, got {value!r}; "
            f"pcdcodec.sync.parse_duration({value!r}) reads a duration with its unit"
        )
    ns = _as_ns(value, name)
    if ns < 0:
        raise InputError(f"{name} must be at least 0 ns, got {ns}")
    return ns


def parse_duration(text: str, name: str = "max_difference") -> int:
    """A duration with its unit (``"150ms"``, ``"0.15 s"``, ``"500us"``, ``"20000000ns"``) as int
    nanoseconds, exact for decimal text. Raises :class:`~pcdcodec.InputError` naming ``name``
    for a number without a unit (other than 0), an unknown unit, or a negative value."""
    import re
    from decimal import Decimal, InvalidOperation

    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([a-zµ]*)\s*", str(text))
    unit = m.group(2) if m else ""
    if m is None or (unit not in _UNITS and (unit or Decimal(m.group(1)) != 0)):
        raise InputError(
            f"{name} {text!r} is not a duration with its unit; expected e.g. 150ms, 0.15s, "
            f"500us or 20000000ns (units: {', '.join(u for u in _UNITS if u != 'µs')})"
        )
    try:
        ns = Decimal(m.group(1)) * _UNITS.get(unit, 1)
    except InvalidOperation:  # pragma: no cover - the pattern admits only numbers
        raise InputError(f"{name} {text!r} is not a number") from None
    if ns != ns.to_integral_value():
        raise InputError(f"{name} {text!r} is not a whole number of nanoseconds")
    return int(ns)


_INT64_MAX = int(np.iinfo(np.int64).max)
_INT64_MIN = int(np.iinfo(np.int64).min)
# A vectorised round that pairs fewer than this fraction of the free stamps hands over to the heap.
_MIN_ROUND_FRACTION = 1 / 32

ColorT = TypeVar("ColorT")
DepthT = TypeVar("DepthT")

IndexArray = npt.NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class Association:
    """The result of :func:`associate`: which color frame goes with which depth frame.

    ``pairs`` is a K×2 int64 array of ``(color_index, depth_index)`` rows sorted by color index;
    ``differences`` holds ``color - depth - offset`` for each pair, in nanoseconds;
    ``unmatched_color`` and ``unmatched_depth`` are the sorted indices left without a partner.
    The arrays are read-only.
    """

    pairs: IndexArray
    differences: IndexArray
    unmatched_color: IndexArray
    unmatched_depth: IndexArray

    def __len__(self) -> int:
        return int(self.pairs.shape[0])

    def __iter__(self) -> Iterator[tuple[int, int]]:
        for color_index, depth_index in self.pairs.tolist():
            yield int(color_index), int(depth_index)

    def summary(self) -> str:
        """One line for logs, e.g. ``"paired 98 of 100 color and 99 depth frames; max |Δt|
        3.1 ms; 2 color and 1 depth frames unmatched"``."""
        k = len(self)
        n_color = k + len(self.unmatched_color)
        n_depth = k + len(self.unmatched_depth)
        parts = [f"paired {k} of {n_color} color and {n_depth} depth frames"]
        if k:
            worst_ms = int(np.abs(self.differences).max()) / 1e6
            parts.append(f"max |Δt| {worst_ms:.3g} ms")
        parts.append(
            f"{len(self.unmatched_color)} color and {len(self.unmatched_depth)} depth "
            "frames unmatched"
        )
        return "; ".join(parts)


def associate(
    color_stamps: Sequence[int] | npt.ArrayLike,
    depth_stamps: Sequence[int] | npt.ArrayLike,
    *,
    max_difference: int = MAX_DIFFERENCE,
    offset: int = 0,
) -> Association:
    """Pair color and depth frames by nearest timestamp, each frame used at most once.

    ``color_stamps`` and ``depth_stamps`` are 1-D sequences or arrays of integer nanoseconds,
    each strictly increasing; either may be empty (an empty list is accepted whatever dtype
    numpy gives it). A color stamp ``c`` and a depth stamp ``d`` may pair when
    ``|c - (d + offset)| <= max_difference`` (ns); ``offset`` (ns) is added to every depth
    stamp before comparing, so a depth clock running 30 ms behind takes ``offset=30_000_000``.
    Pairs are accepted greedily, smallest difference first, with ties going to the earlier
    color and then the earlier depth stamp, which reproduces TUM's ``associate.py`` (whose
    tolerance is exclusive and in float seconds). Runs in O((n + m) log(n + m)) time and
    O(n + m) memory.

    Raises :class:`~pcdcodec.InputTypeError` when stamps are not integers (float seconds must
    be converted to int ns first) or when ``max_difference``/``offset`` are not ints, and
    :class:`~pcdcodec.InputError` when stamps are not 1-D, not strictly increasing (naming the
    first index that is not), do not fit int64 after the offset, or when ``max_difference`` is
    negative.
    """
    colors = _as_stamps(color_stamps, "color_stamps")
    depths = _as_stamps(depth_stamps, "depth_stamps")
    tolerance = _as_ns(max_difference, "max_difference")
    if tolerance < 0:
        raise InputError(f"max_difference must be at least 0 ns, got {tolerance}")
    shift = _as_ns(offset, "offset")
    shifted = _shift(colors, depths, shift)

    color_index, depth_index = _greedy_match(colors, shifted, tolerance)
    order = np.argsort(color_index, kind="stable")
    color_index, depth_index = color_index[order], depth_index[order]
    pairs = np.stack([color_index, depth_index], axis=1).reshape(-1, 2)
    differences = colors[color_index] - shifted[depth_index]
    unmatched_color = _complement(color_index, colors.size)
    unmatched_depth = _complement(depth_index, depths.size)
    for arr in (pairs, differences, unmatched_color, unmatched_depth):
        arr.setflags(write=False)
    return Association(pairs, differences, unmatched_color, unmatched_depth)


Ready = tuple[int, ColorT, int, DepthT]


class Synchronizer(Generic[ColorT, DepthT]):
    """Pair color and depth frames while they arrive, with the same rule as :func:`associate`.

    Feed each stream in its own time order with :meth:`add_color` and :meth:`add_depth` (the two
    streams may interleave in any way); each call returns the pairs that became final, as
    ``(color_ts, color_item, depth_ts, depth_item)`` tuples sorted by color time. Call
    :meth:`flush` at the end of the recording for the rest. Timestamps are int nanoseconds;
    ``max_difference`` and ``offset`` mean what they mean for :func:`associate`.

    **When a pair is final.** A free color ``c`` and free depth ``d`` (``d' = d + offset``,
    ``δ = |c - d'|``) are handed out once all of these hold:

    * ``δ <= max_difference``;
    * ``d`` is the free depth nearest to ``c`` and ``c`` the free color nearest to ``d`` (ties
      to the earlier stamp), so nothing already queued can take either of them first;
    * the latest color stamp ``L`` added so far satisfies ``L + 1 - d' >= δ``, and the latest
      depth stamp ``L'`` satisfies ``L' + offset + 1 - c >= δ``: stamps increase, so every
      color still to come is at least ``L + 1`` and cannot be closer to ``d`` than ``c`` is (a
      tie goes to ``c``), and the same for depth.

    The last rule holds at once for the stream whose stamp is the later of the two; the other
    stream must show a stamp past the pair's later stamp by ``δ - 1`` ns. In practice a pair is
    final when the next frame of the stream whose stamp came first arrives. A queued stamp with
    no free partner within ``max_difference`` is dropped as unmatched once the other stream has
    passed it by ``max_difference``.

    **Equivalence with associate().** Each pair handed out is one that :func:`associate` would
    accept on the full streams, whatever arrives later, and :meth:`flush` finishes the
    remainder with the same greedy rule; so, fed two complete streams, a Synchronizer returns
    exactly ``associate(...)``'s pairs unless the queue limit forced a stamp out (counted in
    :attr:`overflow_count`). That happens when stamps stay undecided for more than
    ``max_queue`` frames: one stream stalls or lags far behind the other, or the streams are so
    dense relative to ``max_difference`` that a greedy choice hinges on stamps far ahead.

    **Order.** With ``ordered=True`` (the default) pairs come out in increasing color time
    across all calls, as a video encoder needs: a final pair is held back while an earlier
    color stamp is still undecided (this happens when that color waits on a chain of close
    stamps, mostly when jitter approaches ``max_difference``). With ``ordered=False`` pairs come
    out as soon as they are final, in color order within one call but not always across calls.
    Depth order follows color order when ``max_difference`` is under half the depth frame
    period; with a larger tolerance a pair can nest inside another (a depth paired with a later
    color than the next depth is), as with :func:`associate` and ``associate.py``.

    **Memory.** ``max_queue`` bounds each stream's queue: undecided depth stamps, and undecided
    color stamps plus pairs held back for order. Going over drops that stream's oldest undecided
    stamp, counted as unmatched and in :attr:`overflow_count`. So at most ``max_queue`` color
    items and ``2 * max_queue`` depth items are held.

    Raises :class:`~pcdcodec.InputTypeError` for a timestamp or setting that is not an int and
    :class:`~pcdcodec.InputError` for a timestamp not after the previous one of its stream, a
    negative ``max_difference`` or a ``max_queue`` below 1.
    """

    def __init__(
        self,
        *,
        max_difference: int = MAX_DIFFERENCE,
        offset: int = 0,
        max_queue: int = 100,
        ordered: bool = True,
    ) -> None:
        self.max_difference = _as_ns(max_difference, "max_difference")
        if self.max_difference < 0:
            raise InputError(f"max_difference must be at least 0 ns, got {self.max_difference}")
        self.offset = _as_ns(offset, "offset")
        self.max_queue = _as_int(max_queue, "max_queue")
        if self.max_queue < 1:
            raise InputError(f"max_queue must be at least 1, got {self.max_queue}")
        if not isinstance(ordered, bool):
            raise InputTypeError(f"ordered must be True or False, got {ordered!r}")
        self.ordered = ordered
        # Free (undecided) stamps, sorted; depth keys are shifted by the offset.
        self._color_ts: list[int] = []
        self._color_items: list[ColorT] = []
        self._depth_keys: list[int] = []
        self._depth_items: list[DepthT] = []
        # Final pairs held back until every earlier color stamp is decided (ordered=True).
        self._held: list[Ready[ColorT, DepthT]] = []
        self._last_color: int | None = None
        self._last_depth: int | None = None
        self._dropped_color: list[int] = []
        self._dropped_depth: list[int] = []
        self._overflow = 0
        self._paired = 0

    def __repr__(self) -> str:
        return (
            f"Synchronizer(max_difference={self.max_difference}, offset={self.offset}, "
            f"max_queue={self.max_queue}, ordered={self.ordered})"
        )

    @property
    def dropped_color(self) -> list[int]:
        """Color stamps (ns) dropped without a partner so far, in the order they were dropped."""
        return list(self._dropped_color)

    @property
    def dropped_depth(self) -> list[int]:
        """Depth stamps (ns, as given, without the offset) dropped without a partner so far."""
        return list(self._dropped_depth)

    @property
    def overflow_count(self) -> int:
        """How many of the dropped stamps were pushed out by ``max_queue``, not proven
        unmatched. While it is 0 the pairs so far agree with :func:`associate`."""
        return self._overflow

    @property
    def paired_count(self) -> int:
        """How many pairs have been handed out so far."""
        return self._paired

    @property
    def pending(self) -> tuple[int, int]:
        """How many color and depth stamps are queued, still undecided (pairs held back for
        order are not counted)."""
        return len(self._color_ts), len(self._depth_keys)

    def add_color(self, timestamp: int, item: ColorT) -> list[Ready[ColorT, DepthT]]:
        """Queue a color frame taken at ``timestamp`` (ns); return the pairs now final.

        Raises :class:`~pcdcodec.InputError` when ``timestamp`` is not after the previous color
        timestamp or (with the offset) beyond ±2**62 ns, :class:`~pcdcodec.InputTypeError` when
        it is not an int.
        """
        ts = _as_stamp(timestamp, "color timestamp", 0)
        if self._last_color is not None and ts <= self._last_color:
            raise InputError(
                f"color timestamp {ts} ns is not after the previous color timestamp "
                f"{self._last_color} ns; each stream must be fed in increasing time order"
            )
        self._last_color = ts
        self._color_ts.append(ts)
        self._color_items.append(item)
        return self._settle()

    def add_depth(self, timestamp: int, item: DepthT) -> list[Ready[ColorT, DepthT]]:
        """Queue a depth frame taken at ``timestamp`` (ns); return the pairs now final.

        Raises :class:`~pcdcodec.InputError` when ``timestamp`` is not after the previous depth
        timestamp or (with the offset) beyond ±2**62 ns, :class:`~pcdcodec.InputTypeError` when
        it is not an int.
        """
        ts = _as_stamp(timestamp, "depth timestamp", self.offset)
        if self._last_depth is not None and ts <= self._last_depth:
            raise InputError(
                f"depth timestamp {ts} ns is not after the previous depth timestamp "
                f"{self._last_depth} ns; each stream must be fed in increasing time order"
            )
        self._last_depth = ts
        self._depth_keys.append(ts + self.offset)
        self._depth_items.append(item)
        return self._settle()

    def flush(self) -> list[Ready[ColorT, DepthT]]:
        """Pair what is still queued as if both streams had ended; drop the rest as unmatched.

        Returns the pairs sorted by color time and leaves the queues empty. Later stamps must
        still be after the last ones added.
        """
        out = self._held
        self._held = []
        if self._color_ts and self._depth_keys:
            colors = np.array(self._color_ts, dtype=np.int64)
            depths = np.array(self._depth_keys, dtype=np.int64)
            ci, di = _greedy_match(colors, depths, self.max_difference)
            out.extend(self._ready(i, j) for i, j in zip(ci.tolist(), di.tolist(), strict=True))
            taken_c, taken_d = set(ci.tolist()), set(di.tolist())
        else:
            taken_c, taken_d = set(), set()
        self._dropped_color.extend(t for i, t in enumerate(self._color_ts) if i not in taken_c)
        self._dropped_depth.extend(
            k - self.offset for j, k in enumerate(self._depth_keys) if j not in taken_d
        )
        self._color_ts.clear()
        self._color_items.clear()
        self._depth_keys.clear()
        self._depth_items.clear()
        out.sort(key=_color_time)
        self._paired += len(out)
        return out

    # -- internals ------------------------------------------------------------------------

    def _ready(self, i: int, j: int) -> Ready[ColorT, DepthT]:
        return (
            self._color_ts[i],
            self._color_items[i],
            self._depth_keys[j] - self.offset,
            self._depth_items[j],
        )

    def _settle(self) -> list[Ready[ColorT, DepthT]]:
        out = self._held
        self._held = []
        while True:
            while self._settle_once(out):
                pass
            # The queue limit: drop the oldest stamps, then settle again as that may free pairs.
            over_color = len(self._color_ts) + self._count_held(out) > self.max_queue
            over_depth = len(self._depth_keys) > self.max_queue
            if not (over_color or over_depth):
                break
            if over_color:
                self._dropped_color.append(self._color_ts.pop(0))
                self._color_items.pop(0)
                self._overflow += 1
            if over_depth:
                self._dropped_depth.append(self._depth_keys.pop(0) - self.offset)
                self._depth_items.pop(0)
                self._overflow += 1
        out.sort(key=_color_time)
        if self.ordered and self._color_ts:
            # Release only pairs before the earliest undecided color; later colors are later.
            cut = bisect_left([pair[0] for pair in out], self._color_ts[0])
            out, self._held = out[:cut], out[cut:]
        self._paired += len(out)
        return out

    def _count_held(self, final: list[Ready[ColorT, DepthT]]) -> int:
        """How many of the ``final`` pairs must wait for an earlier undecided color."""
        if not (self.ordered and self._color_ts):
            return 0
        first = self._color_ts[0]
        return sum(1 for pair in final if pair[0] > first)

    def _settle_once(self, out: list[Ready[ColorT, DepthT]]) -> bool:
        """Hand out the final pairs and drop the hopeless stamps; True when anything changed."""
        colors, depths, tol = self._color_ts, self._depth_keys, self.max_difference
        last_c = self._last_color
        last_d = None if self._last_depth is None else self._last_depth + self.offset
        near_d = [_nearest(depths, c) for c in colors] if depths else []
        near_c = [_nearest(colors, d) for d in depths] if colors else []
        take: list[tuple[int, int]] = []
        drop_c: list[int] = []
        drop_d: list[int] = []
        for i, c in enumerate(colors):
            if near_d:
                j, gap = near_d[i]
                if gap <= tol:
                    # last_c and last_d are set: c and depths[j] were added.
                    assert last_c is not None
                    assert last_d is not None
                    if (
                        near_c[j][0] == i
                        and gap <= last_c + 1 - depths[j]
                        and gap <= last_d + 1 - c
                    ):
                        take.append((i, j))
                    continue
            if last_d is not None and last_d >= c + tol:
                drop_c.append(i)
        for j, d in enumerate(depths):
            if near_c and near_c[j][1] <= tol:
                continue
            if last_c is not None and last_c >= d + tol:
                drop_d.append(j)
        if not (take or drop_c or drop_d):
            return False
        out.extend(self._ready(i, j) for i, j in take)
        gone_c = set(drop_c) | {i for i, _ in take}
        gone_d = set(drop_d) | {j for _, j in take}
        self._dropped_color.extend(colors[i] for i in drop_c)
        self._dropped_depth.extend(depths[j] - self.offset for j in drop_d)
        self._color_ts = [t for i, t in enumerate(colors) if i not in gone_c]
        self._color_items = [x for i, x in enumerate(self._color_items) if i not in gone_c]
        self._depth_keys = [t for j, t in enumerate(depths) if j not in gone_d]
        self._depth_items = [x for j, x in enumerate(self._depth_items) if j not in gone_d]
        return True


def _color_time(pair: tuple[int, Any, int, Any]) -> int:
    return pair[0]


def _nearest(sorted_values: list[int], value: int) -> tuple[int, int]:
    """Index of the entry nearest to ``value`` (ties to the lower index) and its distance."""
    k = bisect_left(sorted_values, value)
    if k == len(sorted_values):
        return k - 1, value - sorted_values[k - 1]
    if k > 0 and value - sorted_values[k - 1] <= sorted_values[k] - value:
        return k - 1, value - sorted_values[k - 1]
    return k, sorted_values[k] - value


def _as_int(value: Any, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{name} must be an int, got {value!r} ({type(value).__name__})")
    return int(value)


def _as_ns(value: Any, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        hint = " (20 ms is 20_000_000)" if isinstance(value, (float, np.floating)) else ""
        raise InputTypeError(
            f"{name} must be an int number of nanoseconds, got {value!r} "
            f"({type(value).__name__}){hint}"
        )
    return int(value)


def _as_stamp(value: Any, name: str, offset: int) -> int:
    """One streamed timestamp: an int whose shifted value still fits int64 nanoseconds."""
    ts = _as_ns(value, name)
    if not _INT64_MIN // 2 <= ts + offset <= _INT64_MAX // 2:
        raise InputError(f"{name} {ts} ns (offset {offset} ns) is outside ±2**62 ns")
    return ts


def _as_stamps(values: Any, name: str) -> IndexArray:
    """Validate one list of timestamps and return it as a contiguous int64 array."""
    is_array = isinstance(values, np.ndarray)
    try:
        arr = values if is_array else np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a 1-D sequence of int nanoseconds: {exc}") from None
    if arr.ndim != 1:
        raise InputError(f"{name} must be 1-D, got shape {arr.shape}")
    if arr.size == 0 and not is_array:
        return np.empty(0, dtype=np.int64)
    if arr.dtype.kind not in "iu":
        hint = ""
        if arr.dtype.kind == "f":
            hint = "; convert seconds to int ns exactly (parse the text, do not multiply floats)"
        raise InputTypeError(f"{name} must be integer nanoseconds, got dtype {arr.dtype}{hint}")
    if arr.dtype.kind == "u" and arr.size and int(arr.max()) > _INT64_MAX:
        raise InputError(f"{name} has a value {int(arr.max())} above the int64 maximum")
    out: IndexArray = np.ascontiguousarray(arr, dtype=np.int64)
    bad = np.flatnonzero(out[1:] <= out[:-1])
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(
            f"{name} must be strictly increasing, but index {i} ({int(out[i])} ns) is not after "
            f"index {i - 1} ({int(out[i - 1])} ns)"
        )
    return out


def _shift(colors: IndexArray, depths: IndexArray, offset: int) -> IndexArray:
    """``depths + offset``, after checking that it and all differences fit in int64."""
    if depths.size == 0:
        return np.empty(0, dtype=np.int64)
    lo, hi = int(depths[0]) + offset, int(depths[-1]) + offset
    if lo < _INT64_MIN or hi > _INT64_MAX:
        raise InputError(f"depth_stamps + offset {offset} ns leaves the int64 range")
    if colors.size:
        span = max(hi, int(colors[-1])) - min(lo, int(colors[0]))
        if span > _INT64_MAX:
            raise InputError(
                f"color and depth stamps span {span} ns, too far apart to subtract in int64"
            )
    out: IndexArray = depths + np.int64(offset)
    return out


def _complement(taken: IndexArray, n: int) -> IndexArray:
    mask = np.ones(n, dtype=bool)
    mask[taken] = False
    out: IndexArray = np.flatnonzero(mask).astype(np.int64)
    return out


def _nearest_all(values: IndexArray, other: IndexArray) -> tuple[IndexArray, IndexArray]:
    """For each of ``values``, the index of the nearest of sorted ``other`` (ties to the lower
    index) and the distance to it."""
    k = np.searchsorted(other, values, side="left")
    lo = np.maximum(k - 1, 0)
    hi = np.minimum(k, other.size - 1)
    gap_lo = np.abs(values - other[lo])
    gap_hi = np.abs(other[hi] - values)
    use_hi = gap_hi < gap_lo
    index: IndexArray = np.where(use_hi, hi, lo).astype(np.int64)
    gap: IndexArray = np.where(use_hi, gap_hi, gap_lo)
    return index, gap


def _greedy_match(
    colors: IndexArray, depths: IndexArray, tolerance: int, *, vector_rounds: bool = True
) -> tuple[IndexArray, IndexArray]:
    """Greedy smallest-difference-first matching of two sorted int64 arrays (depths already
    shifted by the offset). Returns matched color and depth indices, in no particular order."""
    free_c = np.arange(colors.size, dtype=np.int64)
    free_d = np.arange(depths.size, dtype=np.int64)
    found_c: list[IndexArray] = []
    found_d: list[IndexArray] = []
    while vector_rounds and free_c.size and free_d.size:
        cv, dv = colors[free_c], depths[free_d]
        near_d, gap_c = _nearest_all(cv, dv)
        near_c, gap_d = _nearest_all(dv, cv)
        # Mutual nearest pairs within the tolerance are accepted by the greedy rule.
        mutual = (near_c[near_d] == np.arange(cv.size)) & (gap_c <= tolerance)
        taken = np.flatnonzero(mutual)
        found_c.append(free_c[taken])
        found_d.append(free_d[near_d[taken]])
        # Stamps with no partner within the tolerance never get one: removals only widen gaps.
        keep_c = gap_c <= tolerance
        keep_d = gap_d <= tolerance
        keep_c[taken] = False
        keep_d[near_d[taken]] = False
        before = free_c.size + free_d.size
        free_c, free_d = free_c[keep_c], free_d[keep_d]
        if 2 * taken.size < _MIN_ROUND_FRACTION * before:
            break
    if free_c.size and free_d.size:
        heap_c, heap_d = _heap_match(colors, depths, free_c, free_d, tolerance)
        found_c.append(heap_c)
        found_d.append(heap_d)
    if not found_c:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    return np.concatenate(found_c), np.concatenate(found_d)


def _heap_match(
    colors: IndexArray,
    depths: IndexArray,
    free_c: IndexArray,
    free_d: IndexArray,
    tolerance: int,
) -> tuple[IndexArray, IndexArray]:
    """Exact greedy matching of the free stamps: a heap of candidate pairs that are adjacent in
    the merged time order, over a doubly linked list from which matched stamps are unlinked."""
    values = np.concatenate([colors[free_c], depths[free_d]])
    is_depth = np.concatenate([np.zeros(free_c.size, bool), np.ones(free_d.size, bool)])
    index = np.concatenate([free_c, free_d])
    order = np.argsort(values, kind="stable")
    values, is_depth, index = values[order], is_depth[order], index[order]
    n = values.size
    gaps = values[1:] - values[:-1]
    start = np.flatnonzero((is_depth[1:] != is_depth[:-1]) & (gaps <= tolerance))
    vals: list[int] = values.tolist()
    kind: list[bool] = is_depth.tolist()
    idx: list[int] = index.tolist()

    def entry(p: int, q: int) -> tuple[int, int, int, int, int]:
        c, d = (q, p) if kind[p] else (p, q)
        return vals[q] - vals[p], idx[c], idx[d], p, q

    heap = [entry(p, p + 1) for p in start.tolist()]
    heapq.heapify(heap)
    prev = list(range(-1, n - 1))
    nxt = list(range(1, n + 1))
    alive = [True] * n
    out_c: list[int] = []
    out_d: list[int] = []
    while heap:
        _, ci, di, p, q = heapq.heappop(heap)
        if not (alive[p] and alive[q]):
            continue
        # Nothing is ever inserted, so two live stamps that were adjacent still are.
        out_c.append(ci)
        out_d.append(di)
        alive[p] = alive[q] = False
        a, b = prev[p], nxt[q]
        if a >= 0:
            nxt[a] = b
        if b < n:
            prev[b] = a
        if a >= 0 and b < n and kind[a] != kind[b] and vals[b] - vals[a] <= tolerance:
            heapq.heappush(heap, entry(a, b))
    return np.array(out_c, dtype=np.int64), np.array(out_d, dtype=np.int64)
