"""Decoding a recording's frames in order: the color stream's state, and reading ahead on threads.

:class:`ColorStream` turns a recording's color packets into images, keeping its decoder between
calls so that frames asked for in order decode each packet once. :class:`ReadAhead` yields the
frames of a recording in order while worker threads decode the next few: one thread runs a
color stream of its own (color decodes in sequence), the others decode depth frames, which are
independent, several at once. Each frame is still put together, and its errors raised, by the
caller's thread, as :meth:`Recording.frame` does it one frame at a time.
:func:`codec_with_threads` makes a recording's codecs with the ``threads`` a reader was given.
"""

from __future__ import annotations

import bisect
import threading
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt

from ..color.base import DecodedPicture, StreamCodec
from ..errors import DecodeError, InputError, UnknownCodecError
from ..registry import codec_for_reading
from ._packets import PacketAccess

__all__ = [
    "KEEP_PICTURES",
    "ColorStream",
    "ReadAhead",
    "ThreadsError",
    "codec_with_threads",
    "with_threads",
]

T = TypeVar("T")
Image = npt.NDArray[np.uint8]

#: Bytes of decoded pictures a recording keeps for ``rec[i]``: the current group of pictures,
#: so that reading backwards or again within it converts a kept picture instead of decoding
#: from the keyframe (a 640×480 4:2:0 picture is 450 KiB: 72 of them; 1280×720: 23).
KEEP_PICTURES = 32 << 20


class ColorStream:
    """The color images of a recording, decoded from its packets by one decoder kept between
    calls. Not thread-safe: each thread that decodes keeps its own stream (or holds a lock).

    A frame asked for after the decoder's position in the same group of pictures continues
    from there; any other starts again at the keyframe before it. Of the frames decoded on the
    way, only the one asked for is converted to RGB. ``keep`` (bytes) keeps the decoded pictures
    of the current group of pictures, unconverted, so that frames asked for again or backwards
    within it are converted, not decoded again; 0 (reading in order) drops each once shown.
    """

    def __init__(
        self,
        rec: PacketAccess,
        shape: tuple[int, int],
        codec: StreamCodec | None = None,
        *,
        keep: int = 0,
    ) -> None:
        self._rec = rec
        self._codec = codec or rec.color_codec
        self._shape = shape
        self._keep = keep
        self._decoder: Any = None
        self._next_packet = 0
        #: The packet the decoder started at, and the pts of the last picture it put out (in
        #: display order, so a later one fed but not yet out will still come).
        self._start = 0
        self._last_out = -1 << 63
        self._pictures: dict[int, DecodedPicture] = {}

    def reset(self) -> None:
        """Start afresh from a keyframe at the next call (the decoder's state is unknown)."""
        self._decoder = None
        self._pictures.clear()

    def color(self, i: int) -> Image | None:
        """The color image of frame ``i`` (an index from 0), or ``None`` without color.

        Every packet the image comes from is checked against its frame digest first. Raises
        :class:`DecodeError` naming the file, the frame and the packet that failed.
        """
        rec = self._rec
        if self._codec is None:
            return None
        name = str(rec.path)
        ts = int(rec._times[i])
        if ts in rec._color_missing:
            return None  # lost to damage: ``recover`` kept the frame's depth alone
        j = rec._packet_of_pts.get(ts, -1)
        if j < 0 or j < rec._keyframes[0]:
            raise DecodeError(
                f"{name!r}: frame {i} (t={ts} ns): no decodable color packet has its time"
            )
        k = rec._keyframes[bisect.bisect_right(rec._keyframes, j) - 1]
        with rec._lock:
            # Every packet this frame's color comes from, checked before it is shown.
            rec._check_packets(k, j, f"{name!r}: frame {i} (t={ts} ns)")
        picture = self._pictures.get(ts)
        if picture is None:
            picture = self._decode_to(i, ts, j, k)
        rgb = picture.rgb()
        self._forget(ts, int(rec._packet_pts[k]))
        return rgb

    def _decode_to(self, i: int, ts: int, j: int, k: int) -> DecodedPicture:
        """Decode up to the picture shown at ``ts`` (packet ``j``, keyframe ``k`` before it)."""
        rec = self._rec
        ahead = j >= self._next_packet and k <= self._next_packet  # no keyframe in between
        held = self._start <= j < self._next_packet and ts > self._last_out  # reordered
        if self._decoder is None or not (ahead or held):
            assert self._codec is not None
            ch, cw = self._shape
            self._decoder = self._codec.decoder(cw, ch, rec._extradata)
            self._next_packet = self._start = k
            self._last_out = -1 << 63
            self._pictures.clear()
        while ts not in self._pictures:
            if self._next_packet < len(rec._packet_pts):
                j_next = self._next_packet
                self._next_packet += 1
                try:
                    out = self._decoder.decode_pictures(rec._packet(j_next))
                except DecodeError as exc:
                    self.reset()  # the decoder's state is unknown now: start afresh next time
                    raise DecodeError(
                        f"frame {i} (t={ts} ns): color packet at byte offset "
                        f"{int(rec._packet_offsets[j_next])}: {exc}"
                    ) from exc
            else:
                out = self._decoder.flush_pictures()
                if not out:
                    raise DecodeError(f"frame {i} (t={ts} ns): its color frame never decoded")
            for picture in out:
                self._pictures[picture.timestamp] = picture
                self._last_out = max(self._last_out, picture.timestamp)
        return self._pictures[ts]

    def _forget(self, ts: int, group: int) -> None:
        """Drop the pictures no longer kept after showing ``ts`` (in the group from ``group``)."""
        pictures = self._pictures
        if not self._keep:
            # Read in order: frames up to this one will not be asked for again.
            for old in [t for t in pictures if t <= ts]:
                del pictures[old]
            return
        # Pictures of earlier groups go; of this one, the earliest while over the budget.
        for old in [t for t in pictures if t < group]:
            del pictures[old]
        held = sum(p.nbytes for p in pictures.values())
        for old in sorted(pictures):
            if held <= self._keep:
                break
            held -= pictures.pop(old).nbytes


def with_threads(codec: StreamCodec | None, threads: int) -> StreamCodec | None:
    """``codec`` with ``threads`` decoder threads, where it takes them. Reading ahead already
    keeps the cores busy with whole frames: slice threads on top add mostly waiting."""
    if codec is None or "threads" not in codec.runtime_params:
        return codec
    made = codec_for_reading(codec.stored_config(), kind="color", threads=threads)
    return made if isinstance(made, StreamCodec) else codec


class ReadAhead(Generic[T]):
    """Frames ``start`` … ``stop - 1`` in order, the next ``ahead`` decoded on threads meanwhile.

    ``color(i)`` runs on one thread of its own, frame after frame; ``rest(i)`` (the depth and
    pose of frame ``i``) on ``workers`` threads; ``build(i, color, rest)`` puts frame ``i``
    together on the caller's thread from two callables that return those results or raise what
    they raised. At most ``ahead`` frames are decoded beyond the one the caller holds.
    :meth:`close` (or leaving the loop) cancels what has not started and waits for the rest, so
    no thread is left running; frames asked for after that are decoded on the caller's thread.
    """

    def __init__(
        self,
        start: int,
        stop: int,
        *,
        color: Callable[[int], Any],
        rest: Callable[[int], Any],
        build: Callable[[int, Callable[[], Any], Callable[[], Any]], T],
        workers: int,
        ahead: int,
    ) -> None:
        self._stop = stop
        self._next = start
        self._color, self._rest, self._build = color, rest, build
        self._ahead = max(1, ahead)
        self._pending: deque[tuple[int, Future[Any], Future[Any]]] = deque()
        self._closed = False
        self._close_lock = threading.Lock()
        self._color_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-read-color")
        self._pool = ThreadPoolExecutor(max(1, workers), thread_name_prefix="pcdcodec-read-depth")

    def _fill(self) -> None:
        with self._close_lock:
            while not self._closed and self._next < self._stop and len(self._pending) < self._ahead:
                i = self._next
                self._pending.append(
                    (i, self._color_pool.submit(self._color, i), self._pool.submit(self._rest, i))
                )
                self._next += 1

    def __iter__(self) -> Iterator[T]:
        try:
            while True:
                self._fill()
                with self._close_lock:
                    item = self._pending.popleft() if self._pending else None
                if item is not None:
                    i, color, rest = item
                    self._fill()  # frames i+1 … i+ahead decode while frame i is in use
                    yield self._build(
                        i, _result(color, self._color, i), _result(rest, self._rest, i)
                    )
                elif self._closed and self._next < self._stop:
                    i = self._next
                    self._next += 1
                    yield self._build(i, _call(self._color, i), _call(self._rest, i))
                else:
                    return
        finally:
            self.close()

    def close(self) -> None:
        """Stop the workers: cancel the frames not started, wait for those being decoded."""
        with self._close_lock:
            if self._closed:
                return
            self._closed = True
            if self._pending:
                self._next = self._pending[0][0]  # the frames not handed out yet
            for _, color, rest in self._pending:
                color.cancel()
                rest.cancel()
            self._pending.clear()
        self._color_pool.shutdown(wait=True, cancel_futures=True)
        self._pool.shutdown(wait=True, cancel_futures=True)


def _call(fn: Callable[[int], T], i: int) -> Callable[[], T]:
    return lambda: fn(i)


def _result(future: Future[T], fn: Callable[[int], T], i: int) -> Callable[[], T]:
    """What ``future`` returns or raises; ``fn(i)`` on this thread if :meth:`ReadAhead.close`
    (from another thread) cancelled it before it started."""

    def get() -> T:
        try:
            return future.result()
        except CancelledError:
            return fn(i)

    return get


class ThreadsError(InputError):
    """A ``threads`` that a codec of the recording does not take."""


def codec_with_threads(config: Any, kind: str, threads: int | None) -> Any:
    """The codec of ``config`` with ``threads`` where it takes them: ``0`` (automatic) leaves a
    codec that has no automatic setting at its default; another count it does not take is a
    :class:`ThreadsError`, not a fault of the file."""
    try:
        return codec_for_reading(config, kind=kind, threads=threads)
    except UnknownCodecError:
        raise
    except Exception as exc:
        if threads is None:
            raise
        try:
            codec = codec_for_reading(config, kind=kind)
        except Exception:
            raise exc from None
        if threads == 0:
            return codec
        raise ThreadsError(
            f"threads={threads} is more than the {kind} codec {codec.name} takes: {exc}"
        ) from None
