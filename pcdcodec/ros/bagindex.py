"""Frame indexes of bags: header stamps read from serialised messages, depth and color paired by
stamp (:func:`pair_in_order`, the one rule a bag source's iteration and its index share), the
index rows, and a stretch of frames read back from the messages its rows name.

A bag frame index (:class:`~pcdcodec.sources.FrameIndex`) has one row per frame:
``(timestamp, depth log time, depth stamp, color log time, color stamp)``, the color columns -1
for a frame without color. The log time is what the bag's own index knows (ROS 1 index records,
MCAP message indexes, the sqlite3 ``timestamp`` column), so a reader can ask for just the
messages logged between a stretch's first and last message; the header stamp tells apart
messages logged at the same time.
"""

from __future__ import annotations

import heapq
import io
import itertools
import os
import struct
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ..errors import DecodeError, InputError
from ..sync import Synchronizer

COLUMNS = 5
T = TypeVar("T")
_Row = tuple[int, int, int, int, int]  # one frame of a bag frame index


class _BoundedReader(io.BufferedReader):
    """A file whose reads never ask for more than the bytes left in it.

    A damaged length field in a bag (a 32-bit record or chunk size) makes its reader ask for up
    to 4 GiB; Python allocates the whole request before reading. Capped at what the file holds,
    a damaged length costs at most the file's size and ends in the reader's own error.
    """

    def __init__(self, raw: io.FileIO) -> None:
        super().__init__(raw)
        self._size = os.fstat(raw.fileno()).st_size

    def read(self, size: int | None = -1, /) -> bytes:
        if size is not None and size > 0:
            size = min(size, max(0, self._size - self.tell()))
            if size == 0:
                return b""
        return super().read(size)


class _BoundedPath(type(Path())):  # type: ignore[misc]
    """A path whose binary reads are :class:`_BoundedReader` (rosbags opens bags through the
    path it is given, and paths derived from it)."""

    def open(self, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        if mode == "rb" and not args and not kwargs:
            return _BoundedReader(io.FileIO(self, "rb"))
        return super().open(mode, *args, **kwargs)


def bounded_path(path: str | os.PathLike[str]) -> Path:
    """``path`` as a :class:`~pathlib.Path` that rosbags' readers open as a
    :class:`_BoundedReader`: pass it to ``rosbags.rosbag1.Reader`` or ``AnyReader`` so a damaged
    length field cannot make them allocate gigabytes."""
    return _BoundedPath(path)


def check_ros1_index(reader: Any, where: str) -> None:
    """Raise :class:`~pcdcodec.DecodeError` naming ``where`` when an open ROS 1 bag reader's
    index records disagree with its chunk infos on how many messages each connection has.

    rosbags files the index records of each chunk under the connection they name and keeps only
    the bag's connections: a damaged connection id there moves messages to no connection, and
    they would be left out of every read without a word. A reader that is not a ROS 1 one (no
    chunk infos) passes.
    """
    infos = getattr(reader, "chunk_infos", None)
    indexes = getattr(reader, "indexes", None)
    if infos is None or indexes is None:
        return
    counted: dict[int, int] = {}
    for info in infos:
        for conn_id, count in info.connection_counts.items():
            counted[conn_id] = counted.get(conn_id, 0) + count
    for conn in reader.connections:
        indexed = len(indexes.get(conn.id, ()))
        if indexed != counted.get(conn.id, 0):
            raise DecodeError(
                f"{where}: the bag's index is damaged: its chunk infos count "
                f"{counted.get(conn.id, 0)} message(s) on {conn.topic} (connection {conn.id}), "
                f"its index records {indexed}"
            )


def stamp_value(sec: int, nanosec: int, where: str) -> int:
    """A header stamp in nanoseconds, the one reading of stamps for every path through a bag.

    ROS 1 seconds are unsigned 32-bit and ROS 2 seconds signed: the caller passes ``sec`` as the
    message's format defines it (a ROS 1 stamp at or after 2**31 s is read as such, not as a
    negative number). Raises :class:`~pcdcodec.DecodeError` naming ``where`` for nanoseconds
    outside [0, 10**9), which would move the frame by whole seconds, and for a stamp before
    1970 (negative seconds).
    """
    if not 0 <= nanosec < 1_000_000_000:
        raise DecodeError(
            f"{where}: header stamp {sec} s {nanosec} ns has nanoseconds outside 0 to "
            "999999999; the stamp is damaged"
        )
    if sec < 0:
        raise DecodeError(f"{where}: header stamp {sec} s {nanosec} ns is before 1970")
    return int(sec) * 1_000_000_000 + int(nanosec)


def ros1_stamp(raw: bytes, where: str = "a ROS 1 message") -> int | None:
    """The header stamp (ns) of a ROS 1 message that starts with a std_msgs/Header (seq, then
    the stamp's unsigned seconds and nanoseconds); ``None`` when the message is too short.
    Raises :class:`~pcdcodec.DecodeError` for a damaged stamp (:func:`stamp_value`)."""
    if len(raw) < 12:
        return None
    _, sec, nsec = struct.unpack_from("<III", raw, 0)
    return stamp_value(sec, nsec, where)


def _ros1_op(header: bytes) -> int | None:
    """The ``op`` field of a ROS 1 record header (``len name=value`` fields)."""
    pos = 0
    while pos + 4 <= len(header):
        (size,) = struct.unpack_from("<I", header, pos)
        field = header[pos + 4 : pos + 4 + size]
        if field.startswith(b"op=") and len(field) == 4:
            return field[3]
        pos += 4 + size
    return None


def ros1_index_stamps(reader: Any, conns: list[Any]) -> list[tuple[Any, int, int]] | None:
    """``(connection, log time, header stamp)`` of every message of ``conns`` in a ROS 1 bag,
    in the order ``reader.messages(connections=conns)`` yields them, reading only the first
    bytes of each message through the bag's own index (chunk position and offset of every
    message): a few kilobytes per message instead of the message, so indexing a bag of
    PointCloud2 frames reads a tiny part of it.

    ``reader`` is an open :class:`rosbags.rosbag1.Reader`. Returns ``None`` (the caller then
    reads the messages) when a chunk is compressed, when the reader does not expose its index
    as expected, or when a record is not where the index says.
    """
    try:
        from rosbags.rosbag1.reader import decompressors

        plain = decompressors["none"]
        chunks = reader.chunks
        lists = [(conn, reader.indexes[conn.id]) for conn in conns]
        path = reader.path
    except (ImportError, AttributeError, KeyError):
        return None
    if any(chunk.decompressor is not plain for chunk in chunks.values()):
        return None
    owner = {(e.chunk_pos, e.offset): conn for conn, entries in lists for e in entries}
    out: list[tuple[Any, int, int]] = []
    try:
        with open(path, "rb") as f:
            for entry in heapq.merge(*(entries for _, entries in lists)):
                f.seek(chunks[entry.chunk_pos].datapos + entry.offset)
                while True:  # connection records may come first, as the reader skips them
                    (size,) = struct.unpack("<I", f.read(4))
                    op = _ros1_op(f.read(size))
                    (length,) = struct.unpack("<I", f.read(4))
                    if op != 0x07:
                        break
                    f.seek(length, 1)
                if op != 0x02 or length < 12:
                    return None
                conn = owner[(entry.chunk_pos, entry.offset)]
                stamp = ros1_stamp(f.read(12), f"topic {conn.topic!r}")
                if stamp is None:
                    return None
                out.append((conn, int(entry.time), stamp))
    except (OSError, struct.error, KeyError):
        return None
    return out


def cdr_stamp(raw: bytes, where: str = "a ROS 2 message") -> int | None:
    """The header stamp (ns) of a CDR-serialised ROS 2 message that starts with a Header, or
    ``None`` when the encapsulation is not plain CDR (the caller then deserialises). Raises
    :class:`~pcdcodec.DecodeError` for a damaged stamp (:func:`stamp_value`)."""
    if len(raw) < 12 or raw[0] != 0 or raw[1] not in (0, 1):
        return None
    sec, nsec = struct.unpack_from("<iI" if raw[1] == 1 else ">iI", raw, 4)
    return stamp_value(sec, nsec, where)


def check_rows(rows: Any) -> Any:
    table = np.asarray(rows)
    if table.ndim != 2 or table.shape[1] != COLUMNS:
        raise InputError(
            f"a bag frame index has {COLUMNS} columns per frame, got an array of shape "
            f"{table.shape}"
        )
    return table


@dataclass
class PairStats:
    """What pairing a bag's depth and color left out: messages whose stamp did not increase
    on their stream, and images that found no partner."""

    out_of_order: int = 0
    dropped_color: int = 0
    dropped_depth: int = 0


def pair_in_order(
    messages: Iterable[tuple[bool, int, T]],
    max_difference: int,
    stats: PairStats | None = None,
    left: Callable[[bool, int, T], None] | None = None,
) -> Iterator[tuple[int, T, T, int]]:
    """``(depth stamp, depth item, color item, color stamp)`` for each pair of a bag's depth
    and color messages, from ``(is_depth, stamp, item)`` of each message in bag order: the one
    pairing rule of a bag source's iteration and of its frame index (:func:`index_rows`), so
    both list the same frames in the same order.

    A message whose stamp does not increase on its stream is skipped (counted in ``stats``);
    color and depth are paired by :class:`~pcdcodec.sync.Synchronizer` (``max_difference``
    ns), whose unmatched images ``stats`` counts as they are dropped. ``left``, when given,
    is called with ``(is_depth, stamp, item)`` of each message skipped or dropped, once it is.
    """
    sync: Synchronizer[T, T] = Synchronizer(max_difference=max_difference)
    latest = {True: -1, False: -1}
    held: dict[tuple[bool, int], T] = {}  # with ``left``: the items the synchronizer holds
    gone = {True: 0, False: 0}

    def count() -> None:
        dropped = {False: sync.dropped_color, True: sync.dropped_depth}
        if stats is not None:
            stats.dropped_color = len(dropped[False])
            stats.dropped_depth = len(dropped[True])
        if left is not None:
            for d, stamps in dropped.items():
                for ts in stamps[gone[d] :]:
                    left(d, ts, held.pop((d, ts)))
                gone[d] = len(stamps)

    def paired(ready: list[tuple[int, T, int, T]]) -> Iterator[tuple[int, T, T, int]]:
        for cts, citem, dts, ditem in ready:
            held.pop((True, dts), None)
            held.pop((False, cts), None)
            yield dts, ditem, citem, cts

    for is_depth, ts, item in messages:
        if ts <= latest[is_depth]:
            if stats is not None:
                stats.out_of_order += 1
            if left is not None:
                left(is_depth, ts, item)
            continue
        latest[is_depth] = ts
        if left is not None:
            held[(is_depth, ts)] = item
        ready = sync.add_depth(ts, item) if is_depth else sync.add_color(ts, item)
        count()
        yield from paired(ready)
    ready = sync.flush()
    count()
    yield from paired(ready)


def index_rows(
    stamps: Iterable[tuple[bool, int, int]],
    color: bool,
    max_difference: int,
    limit: int | None = None,
) -> Any:
    """The index rows of a bag's frames, as an ``(n, 5)`` int64 array, from ``(is_depth, log
    time, stamp)`` of each depth (and color) message in bag order: paired by
    :func:`pair_in_order` (without color, each depth message whose stamp increases is a
    frame), so the rows list exactly the frames iteration gives, in its order. At most
    ``limit`` rows; the messages after the last of them are not read.
    """
    rows: Iterable[_Row]
    if color:
        pairs = pair_in_order(((d, ts, (t, ts)) for d, t, ts in stamps), max_difference)
        rows = ((dts, d[0], d[1], c[0], c[1]) for dts, d, c, _ in pairs)
    else:
        rows = _depth_rows(stamps)
    table = list(itertools.islice(rows, limit))
    return np.array(table, dtype=np.int64).reshape(-1, COLUMNS)


def _depth_rows(stamps: Iterable[tuple[bool, int, int]]) -> Iterator[_Row]:
    """Rows of depth-only frames: each depth message whose stamp increases."""
    last = -1
    for _, t, ts in stamps:
        if ts > last:
            last = ts
            yield ts, t, ts, -1, -1


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
) -> Iterator[tuple[int, Any, Any, int | None]]:
    """``(timestamp, depth, color, color stamp)`` for each row, in row order, from
    ``messages``.

    ``messages`` yields ``(is_depth, log time, stamp, item)`` for the messages logged in the
    rows' :func:`window`, in bag order; only the items the rows name are passed to ``decode``
    (with ``is_depth``), each once. ``color`` and its stamp are ``None`` in what is yielded
    when ``color`` is false. Raises :class:`~pcdcodec.DecodeError` naming the first frame
    whose message is missing (the index is another bag's, or the bag changed since it was
    indexed).
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
            depth = take(dkey)
            if color:
                yield ts, depth, take(ckey), cts
            else:
                yield ts, depth, None, None
            i += 1
    if i < len(todo):
        raise DecodeError(
            f"{where} has no message for frame {first + i} (at {todo[i][0]} ns) where its index "
            "says: the index was made from another bag, or the bag changed since"
        )
