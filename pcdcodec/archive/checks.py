"""What an archive run checks of its outputs: a decoded frame against its source's (depth bit
for bit, or within a bounded codec's bound) and the decoded color against its segment's own
decode, by digest."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from typing import Any

from ..errors import VerificationError

__all__ = [
    "check_frames",
    "check_kept",
    "depth_bound",
    "depth_mismatch",
    "digest",
    "in_window",
    "kept_in",
]


def digest(array: Any) -> str:
    """A digest of an image's values, shape and dtype, whatever its memory layout ("" for
    ``None``)."""
    import numpy as np

    if array is None:
        return ""
    a = np.ascontiguousarray(array)
    h = hashlib.blake2b(f"{a.dtype.str}{a.shape}".encode(), digest_size=16)
    h.update(a.data)
    return h.hexdigest()


def check_frames(
    name: str, decoded: Iterator[Any], source: Any, bound: Any, colors: list[str] | None
) -> int:
    """Compare the frames ``decoded`` from an output with ``source``'s, and the decoded color
    with the segments' digests ``colors``; raise :class:`~pcdcodec.VerificationError` naming
    ``name`` on any difference. Returns the frames compared."""
    n = 0
    count = 0 if colors is None else len(colors)
    for original in source:
        frame = next(decoded, None)
        if frame is None:
            raise VerificationError(f"{name}: frame {n} of the source is missing")
        if frame.timestamp_ns != original.timestamp_ns:
            raise VerificationError(
                f"{name}: frame {n} is at {frame.timestamp_ns} ns, the source's at "
                f"{original.timestamp_ns} ns"
            )
        problem = depth_mismatch(frame.depth, original.depth, bound)
        if problem:
            raise VerificationError(f"{name}: frame {n} depth {problem}")
        if colors is not None and (n >= count or digest(frame.color) != colors[n]):
            raise VerificationError(
                f"{name}: frame {n} color differs from the codec's decode of its segment"
            )
        n += 1
    if next(decoded, None) is not None:
        raise VerificationError(f"{name}: more frames than the source ({n})")
    if colors is not None and count != n:
        raise VerificationError(f"{name}: {n} frames, but its segments decoded {count}")
    return n


def depth_bound(config: dict[str, Any]) -> Any:
    """The error bound a depth codec config states, or ``None`` for lossless coding."""
    from ..depth import FrameCodec
    from ..registry import get_codec

    codec = get_codec(config)
    return codec.error_bound if isinstance(codec, FrameCodec) else None


def depth_mismatch(decoded: Any, original: Any, bound: Any) -> str:
    """Why decoded depth does not stand for the source's ('' when it does).

    Lossless codecs must give the same bits (NaN, float32 "no measurement", equals itself);
    a codec with an error bound must keep every hole, and every valid pixel within its bound.
    """
    if decoded.dtype != original.dtype or decoded.shape != original.shape:
        return f"is {decoded.dtype} {decoded.shape}, the source's {original.dtype} {original.shape}"
    import numpy as np

    floats = decoded.dtype.kind == "f"
    if bound is None:
        same = np.array_equal(decoded, original, equal_nan=floats)
        return "" if same else "differs from the source"
    holes = ~np.isfinite(original) if floats else original == 0
    kept = ~np.isfinite(decoded) if floats else decoded == 0
    if not np.array_equal(holes, kept):
        return "has holes where the source has none, or the other way round"
    ref = original[~holes].astype(np.float64)
    err = np.abs(decoded[~holes].astype(np.float64) - ref)
    over = err > bound.of(ref)
    if over.any():
        i = int(np.argmax(over))
        return (
            f"is off by {err[i]:g} at a value of {ref[i]:g}, more than the codec's bound "
            f"(max_error={bound.abs_error:g}, max_rel_error={bound.rel_error:g})"
        )
    return ""


def kept_in(source: Any, window: tuple[int | None, int | None]) -> Iterator[Any]:
    """The kept messages of ``source`` whose log time falls in ``window`` (``[low, high)``,
    ``None``: open): a segment's share of its input's other topics, so that the segments'
    shares, joined, hold each message once. A source whose ``kept_messages`` takes ``start``
    and ``stop`` (a bag's) reads only those."""
    import inspect

    if window != (None, None) and "stop" in inspect.signature(source.kept_messages).parameters:
        return in_window(source.kept_messages(start=window[0], stop=window[1]), window)
    return in_window(source.kept_messages(), window)


def in_window(messages: Iterator[Any], window: tuple[int | None, int | None]) -> Iterator[Any]:
    """The messages whose log time falls in ``window`` (``[low, high)``, ``None``: open)."""
    low, high = window
    for m in messages:
        if (low is None or m.log_time >= low) and (high is None or m.log_time < high):
            yield m


def check_kept(name: str, output: Iterator[Any], source: Iterator[Any]) -> int:
    """Compare the kept messages of an output with its source's: each message (topic, times,
    bytes) there once; raise :class:`~pcdcodec.VerificationError` naming ``name`` on any
    difference. Returns the messages compared."""
    from collections import Counter

    def key(m: Any) -> tuple[str, int, int, str]:
        return m.topic.topic, m.log_time, m.published, hashlib.blake2b(m.data).hexdigest()

    want = Counter(key(m) for m in source)
    got = Counter(key(m) for m in output)
    if got != want:
        missing, extra = want - got, got - want
        first = min(missing or extra)
        raise VerificationError(
            f"{name}: the kept messages differ from the source's: {sum(missing.values())} "
            f"missing, {sum(extra.values())} not in the source or more than once (the first "
            f"on {first[0]!r} at t={first[1]} ns)"
        )
    return sum(want.values())
