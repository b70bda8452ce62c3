"""The capture loop of ``pcdcodec record``: cameras in, one recording out, in bounded memory.

Each camera (a :class:`~pcdcodec.sources.Source` whose frames arrive live) is read on its own
thread, which copies each frame into one bounded queue and never waits for the encoder: when
the queue is full, the frame is dropped and counted ("dropped by us"), so a camera is never held
up and memory stays bounded whatever the codecs' speed. The calling thread takes frames off the
queue and hands them to the writer, which encodes on its own threads (and itself holds at most
``in_flight`` frames). A source that can wait without losing frames (a playback file read at
full speed) is read with ``block=True`` instead: the queue then holds its thread back.

:meth:`Capture.stop` (from a signal handler, say) ends capture; every frame already queued is
still written, and the writer is closed, so the file is complete.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import PcdcodecError

__all__ = ["POINTCLOUD2_BYTES_PER_POINT", "Camera", "Capture", "CaptureStats"]

#: Bytes per point of a ROS PointCloud2 with float32 x, y, z and packed RGB, padded (as the
#: benchmarks count it: pcdcodec.bench.results).
POINTCLOUD2_BYTES_PER_POINT = 32


@dataclass
class Camera:
    """One camera of a capture: its name in the recording and the source it is read from."""

    name: str
    source: Any
    #: frames read from the source (handed to the queue or dropped by us)
    captured: int = 0
    #: frames the queue had no room for
    dropped_by_us: int = 0
    #: frames handed to the writer
    written: int = 0
    #: valid depth points of the frames handed to the writer
    points: int = 0
    error: BaseException | None = None
    #: arrival times of the last frames, for the frame rate
    arrivals: deque[float] = field(default_factory=lambda: deque(maxlen=61))

    @property
    def camera_drops(self) -> int:
        """Frames the camera dropped (gaps in its depth frame counter), where it counts them."""
        drops = getattr(self.source, "camera_drops", None)
        return int(drops.get("depth", 0)) if drops else 0

    def fps(self, now: float) -> float:
        """Frames per second over the last two seconds of arrivals."""
        recent = [t for t in self.arrivals if now - t <= 2.0]
        if len(recent) < 2:
            return 0.0
        return (len(recent) - 1) / max(recent[-1] - recent[0], 1e-9)


@dataclass(frozen=True)
class CaptureStats:
    """What a capture did so far: per camera, and the bytes written."""

    elapsed: float
    cameras: tuple[dict[str, Any], ...]
    bytes_written: int
    mb_per_s: float

    @property
    def points(self) -> int:
        return sum(int(c["points"]) for c in self.cameras)

    @property
    def ratio(self) -> float:
        """PointCloud2 XYZRGB bytes (32 per valid point) of the frames written, per byte."""
        if not self.bytes_written:
            return 0.0
        return self.points * POINTCLOUD2_BYTES_PER_POINT / self.bytes_written

    def line(self) -> str:
        """The status line: each camera's rate and drops, then MB/s and the ratio so far."""
        parts = [
            f"{c['name']} {c['fps']:.1f} fps, dropped {c['camera_drops']} by camera "
            f"{c['dropped_by_us']} by us"
            for c in self.cameras
        ]
        behind = sum(int(c["dropped_by_us"]) for c in self.cameras)
        warn = " | compression behind" if behind else ""
        return (
            f"{self.elapsed:6.1f} s  "
            + "; ".join(parts)
            + f" | {self.mb_per_s:.2f} MB/s, ratio {self.ratio:.1f}x{warn}"
        )


_END = object()


class Capture:
    """Reads ``cameras`` on their own threads into ``write(index, frame)`` on the calling thread.

    ``queue_size`` bounds the frames waiting between the cameras and the writer. ``block`` makes
    the camera threads wait for room instead of dropping (for playback at full speed).
    ``written_bytes`` says how many bytes the output holds so far. ``duration`` (seconds) stops
    the capture by itself. ``on_frame(index, frame)`` sees each frame handed to the writer
    (the live viewer).
    """

    def __init__(
        self,
        cameras: Sequence[Camera],
        write: Callable[[int, Any], None],
        written_bytes: Callable[[], int],
        *,
        queue_size: int = 8,
        block: bool = False,
        duration: float | None = None,
        on_frame: Callable[[int, Any], None] | None = None,
    ) -> None:
        self.cameras = list(cameras)
        self._write = write
        self._written_bytes = written_bytes
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=max(1, queue_size))
        self.block = block
        self.duration = duration
        self._on_frame = on_frame
        self._stop = threading.Event()
        self._start = time.monotonic()
        self._rate: deque[tuple[float, int]] = deque(maxlen=32)

    # -- the camera side -----------------------------------------------------------------

    def _read(self, index: int) -> None:
        camera = self.cameras[index]
        try:
            for frame in camera.source:
                now = time.monotonic()
                camera.captured += 1
                camera.arrivals.append(now)
                if self.block:
                    while not self._put(index, frame, 0.1):
                        if self._stop.is_set():
                            return
                elif not self._put(index, frame, None):
                    camera.dropped_by_us += 1
                if self._stop.is_set():
                    return
        except BaseException as exc:
            camera.error = exc
            self._stop.set()
        finally:
            self._queue.put(_END)  # the writer waits for one from every camera

    def _put(self, index: int, frame: Any, timeout: float | None) -> bool:
        try:
            if timeout is None:
                self._queue.put_nowait((index, frame))
            else:
                self._queue.put((index, frame), timeout=timeout)
        except queue.Full:
            return False
        return True

    def stop(self) -> None:
        """End the capture: the cameras stop, and what was queued is still written."""
        self._stop.set()
        for camera in self.cameras:
            stop = getattr(camera.source, "stop", None)
            if stop is not None:
                stop()

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    # -- the writer side -----------------------------------------------------------------

    def stats(self) -> CaptureStats:
        """The counts so far, with the rates of the last few seconds."""
        now = time.monotonic()
        written = self._written_bytes()
        self._rate.append((now, written))
        while len(self._rate) > 2 and now - self._rate[0][0] > 3.0:
            self._rate.popleft()
        t0, b0 = self._rate[0]
        rate = (written - b0) / (now - t0) / 1e6 if now > t0 else 0.0
        cams = tuple(
            {
                "name": c.name,
                "fps": c.fps(now),
                "captured": c.captured,
                "written": c.written,
                "camera_drops": c.camera_drops,
                "dropped_by_us": c.dropped_by_us,
                "points": c.points,
            }
            for c in self.cameras
        )
        return CaptureStats(now - self._start, cams, written, rate)

    def run(
        self, status: Callable[[CaptureStats], None] | None = None, every: float = 0.25
    ) -> None:
        """Capture until every camera ends, :meth:`stop` or ``duration``; write each frame.

        ``status`` is called with :meth:`stats` every ``every`` seconds. Raises the first error
        a camera met, after writing what was captured before it.
        """
        self._start = time.monotonic()
        threads = [
            threading.Thread(target=self._read, args=(i,), name=f"capture-{c.name}", daemon=True)
            for i, c in enumerate(self.cameras)
        ]
        for t in threads:
            t.start()
        running = len(threads)
        last = 0.0
        while running:
            try:
                item = self._queue.get(timeout=0.05)
            except queue.Empty:
                item = None
            if item is _END:
                running -= 1
            elif item is not None:
                index, frame = item
                camera = self.cameras[index]
                self._write(index, frame)
                camera.written += 1
                camera.points += int(np.count_nonzero(frame.depth))
                if self._on_frame is not None:
                    self._on_frame(index, frame)
            now = time.monotonic()
            if self.duration is not None and now - self._start >= self.duration:
                self.stop()
            if status is not None and now - last >= every:
                last = now
                status(self.stats())
        for t in threads:
            t.join()
        for camera in self.cameras:
            if camera.error is not None:
                error = camera.error
                if isinstance(error, PcdcodecError) or not isinstance(error, Exception):
                    raise error
                raise PcdcodecError(f"camera {camera.name}: {error}") from error


def file_bytes(path: str | os.PathLike[str]) -> int:
    """The size of ``path`` now (0 when it is not there yet)."""
    try:
        return os.stat(path).st_size
    except OSError:
        return 0
