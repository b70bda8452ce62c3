"""The writer's threads: color and depth encoded in parallel, frames written in order.

:class:`Pipeline` runs the codecs on two threads while the caller prepares the next frame, and
hands each frame, in the order handed in, to a third thread that writes it as soon as both
halves are encoded. At most ``in_flight`` frames wait, so memory stays bounded; errors met in
the background are kept for the caller's thread, which raises them.
"""

from __future__ import annotations

import contextlib
import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from typing import Any

import numpy.typing as npt

from ..color.base import Packet

#: A frame handed in: its timestamp (ns) and the futures of its color packets and depth bytes.
Pending = tuple[int, Future[list[Packet]] | None, Future[bytes]]


class Pipeline:
    """Encoding threads and the one writing thread of a :class:`~pcdcodec.RecordingWriter`.

    ``write_one`` is called on the writing thread for each frame, once both its halves are
    encoded; it takes the frame off :attr:`pending` (:meth:`next`) and writes it.
    """

    def __init__(self, in_flight: int, write_one: Callable[[], None]) -> None:
        self.in_flight = in_flight
        self._write_one = write_one
        self.pending: deque[Pending] = deque()
        self._color_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-color")
        self._depth_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-depth")
        # One thread writes the file (the MCAP writer is not thread-safe), taking the frames in
        # the order handed in. The condition guards the count of frames handed in and not yet
        # written, and the errors met writing them, which the caller's thread raises.
        self._mux_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-write")
        self._state = threading.Condition()
        self._unwritten = 0
        self._errors: list[BaseException] = []
        self.aborted = False

    def encode_color(self, encode: Callable[..., list[Packet]], *args: Any) -> Future[list[Packet]]:
        """Run a color encode on the color thread."""
        return self._color_pool.submit(encode, *args)

    def submit(
        self,
        timestamp: int,
        fut_color: Future[list[Packet]] | None,
        encode_depth: Callable[[npt.NDArray[Any]], bytes],
        depth: npt.NDArray[Any],
    ) -> None:
        """Hand in a frame: its depth is encoded on the depth thread; blocks while more than
        ``in_flight`` frames are not yet written."""
        fut_depth = self._depth_pool.submit(encode_depth, depth)
        entry = (timestamp, fut_color, fut_depth)
        with self._state:
            self.pending.append(entry)
            self._unwritten += 1
        self._mux_pool.submit(self._mux_one, entry)
        # Memory stays bounded: wait while more than in_flight frames are not yet written.
        with self._state:
            self._state.wait_for(lambda: self._unwritten <= self.in_flight)

    def next(self) -> Pending:
        """The next frame to write, taken off the queue."""
        return self.pending.popleft()

    def _mux_one(self, entry: Pending) -> None:
        """Write one frame handed in, once encoded (on the writing thread, in order)."""
        timestamp, fut_color, fut_depth = entry
        try:
            # No lock is held while the encoders run: the caller keeps handing frames in.
            for future in (fut_color, fut_depth):
                if future is not None:
                    # exception() waits on the future's own condition, which cancel() wakes
                    # (futures.wait() would not: abort() cancels queued encodes).
                    with contextlib.suppress(CancelledError):
                        future.exception()
            if self.aborted:
                return
            try:
                self._write_one()
            except BaseException as exc:  # kept for the caller's thread, which raises it
                add_note = getattr(exc, "add_note", None)  # Python 3.11+
                if add_note is not None:
                    add_note(f"(raised encoding or writing the frame at {timestamp} ns)")
                with self._state:
                    self._errors.append(exc)
        finally:
            with self._state:
                # Each frame gets one try, whether or not it was taken off the queue.
                if self.pending and self.pending[0] is entry:
                    self.pending.popleft()
                self._unwritten -= 1
                self._state.notify_all()

    def raise_error(self) -> None:
        """Raise the first error met writing earlier frames; each is raised once."""
        with self._state:
            errors, self._errors = self._errors, []
        if errors:
            add_note = getattr(errors[0], "add_note", None)
            if len(errors) > 1 and add_note is not None:
                add_note(f"({len(errors) - 1} more frames failed after it)")
            raise errors[0]

    def wait(self) -> None:
        """Wait until every frame handed in has had its one try at being written."""
        with self._state:
            self._state.wait_for(lambda: self._unwritten == 0)

    def finish(self) -> list[BaseException]:
        """Stop taking frames: each frame handed in gets its one try, and every encode still
        running ends; the errors not yet raised."""
        self._mux_pool.shutdown(wait=True)
        with self._state:
            errors, self._errors = self._errors, []
        self.pending.clear()
        # Wait for every encode still running (a frame whose write() failed part way may have
        # left one behind) before the encoder is flushed: an FFmpeg codec context used from
        # two threads at once crashes the process.
        self._color_pool.shutdown(wait=True)
        self._depth_pool.shutdown(wait=True)
        return errors

    def abort(self) -> None:
        """Stop at once: queued frames are dropped, and nothing more is written."""
        self.aborted = True
        # A frame being coded finishes first (milliseconds), so no codec keeps running on a
        # worker thread once abort() returns. The writing thread writes nothing more, and is
        # done before the caller closes the file.
        self._color_pool.shutdown(wait=True, cancel_futures=True)
        self._depth_pool.shutdown(wait=True, cancel_futures=True)
        self._mux_pool.shutdown(wait=True)
