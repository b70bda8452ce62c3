"""Frame indexes of bags: header stamps read from serialised messages, and a stretch of frames
read back from the messages its index rows name.

A bag frame index (:class:`~pcdcodec.sources.FrameIndex`) has one row per frame:
``(timestamp, depth log time, depth stamp, color log time, color stamp)``, the color columns -1
for a frame without color. The log time is what the bag's own index knows (ROS 1 index records,
MCAP message indexes, the sqlite3 ``timestamp`` column), so a reader can ask for just the
messages logged between a stretch's first and last message; the header stamp tells apart
messages logged at the same time.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from ..errors import DecodeError, InputError

COLUMNS = 5


def ros1_stamp(raw: bytes) -> int | None:
    """The header stamp (ns) of a ROS 1 message that starts with a std_msgs/Header (seq, then
    the stamp's seconds and nanoseconds); ``None`` when the message is too short."""
    if len(raw) < 12:
        return None
    _, sec, nsec = struct.unpack_from("<III", raw, 0)
    return int(sec) * 1_000_000_000 + int(nsec)


def cdr_stamp(raw: bytes) -> int | None:
    """The header stamp (ns) of a CDR-serialised ROS 2 message that starts with a Header, or
    ``None`` when the encapsulation is not plain CDR (the caller then deserialises)."""
    if len(raw) < 12 or raw[0] != 0 or raw[1] not in (0, 1):
        return None
    sec, nsec = struct.unpack_from("<iI" if raw[1] == 1 else ">iI", raw, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


def check_rows(rows: Any) -> Any:
    import numpy as np

    table = np.asarray(rows)
    if table.ndim != 2 or table.shape[1] != COLUMNS:
        raise InputError(
            f"a bag frame index has {COLUMNS} columns per frame, got an array of shape "
            f"{table.shape}"
        )
    return table


def window(rows: Any, color: bool) -> tuple[int, int]:
    """The log times ``[start, stop)`` that hold every message the rows name."""
    logs = rows[:, [1, 3]] if color else rows[:, [1]]
    return int(logs.min()), int(logs.max()) + 1


def read_rows(
    rows: Any,
    first: int,
    color: bool,
    messages: Iterable[tuple[bool, int, int, Any]],
    decode: Callable[[bool, Any], Any],
    where: str,
) -> Iterator[tuple[int, Any, Any]]:
    """``(timestamp, depth, color)`` for each row, in row order, from ``messages``.

    ``messages`` yields ``(is_depth, log time, stamp, item)`` for the messages logged in the
    rows' :func:`window`, in bag order; only the items the rows name are passed to ``decode``
    (with ``is_depth``), each once. ``color`` is ``None`` in what is yielded when ``color`` is
    false. Raises :class:`~pcdcodec.DecodeError` naming the first frame whose message is
    missing (the index is another bag's, or the bag changed since it was indexed).
    """
    todo = rows.tolist()
    # How many rows use each message: a color frame can go with two depth frames.
    wanted: dict[tuple[bool, int, int], int] = {}
    for row in todo:
        keys = [(True, row[1], row[2])] + ([(False, row[3], row[4])] if color else [])
        for key in keys:
            wanted[key] = wanted.get(key, 0) + 1
    got: dict[tuple[bool, int, int], list[Any]] = {}  # key -> [item, uses left]

    def take(key: tuple[bool, int, int]) -> Any:
        entry = got[key]
        entry[1] -= 1
        if entry[1] == 0:
            del got[key]
        return entry[0]

    i = 0
    for is_depth, log, stamp, item in messages:
        key = (is_depth, log, stamp)
        uses = wanted.pop(key, 0)
        if not uses:
            continue
        got[key] = [decode(is_depth, item), uses]
        while i < len(todo):
            ts, dlog, dts, clog, cts = todo[i]
            dkey, ckey = (True, dlog, dts), (False, clog, cts)
            if dkey not in got or (color and ckey not in got):
                break
            yield ts, take(dkey), take(ckey) if color else None
            i += 1
    if i < len(todo):
        raise DecodeError(
            f"{where} has no message for frame {first + i} (at {todo[i][0]} ns) where its index "
            "says: the index was made from another bag, or the bag changed since"
        )
