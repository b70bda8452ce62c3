"""Live RealSense cameras as a :class:`Source`, through ``pyrealsense2`` (``pcdcodec[realsense]``).

:func:`realsense_live` opens a connected camera (by serial number, or the first one found), or
plays a librealsense ``.bag`` back as if it were one (``playback=``), and yields its frames as
they arrive. Depth comes as the camera gives it, with the depth camera's intrinsics and the
device's depth units; color comes either unregistered (the color camera's own intrinsics and the
depth-to-color extrinsic, the default) or aligned to depth by librealsense (``align=True``).
Depth and color are paired by the rule of every reader (:class:`pcdcodec.sync.Synchronizer`):
each image used at most once, within ``max_difference`` ns (default
:data:`pcdcodec.sync.MAX_DIFFERENCE`, 20 ms), the images left without a partner counted in
:attr:`RealSenseLiveSource.dropped`, as the ``.bag`` reader (:mod:`.realsense`) pairs and counts
them (a played-back ``.bag`` gives the frames that reader gives, of those librealsense hands
over). With ``align=True`` only the pairs librealsense put in one frameset can be aligned: a
pair it never did is dropped and counted too. Timestamps are the device's, in the domain it
reports (``metadata["timestamp_domain"]``), in nanoseconds.

The source counts what the camera dropped: gaps in the frame counters of the depth and color
streams (:attr:`RealSenseLiveSource.camera_drops`). A frame is copied out of librealsense's
frame pool as soon as it is taken, so a slow consumer never holds the camera's buffers.

``pyrealsense2`` is imported when a source opens, never by ``import pcdcodec``. Several physical
cameras, hardware sync (``sync="master"``/``"slave"``) and ``serial=`` of a real device are
written to librealsense's documented API but are tested through playback only.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError, PcdcodecError
from ..geometry.camera import CameraIntrinsics
from ..ros.bagindex import PairStats, pair_in_order
from ..sync import MAX_DIFFERENCE, as_max_difference
from .base import InputStream, Source

__all__ = ["RealSenseLiveSource", "connected_serials", "realsense_live"]

_INSTALL = 'pip install "pcdcodec[realsense]"'
_NS_PER_MS = 1_000_000
#: librealsense's names of its distortion models, as camera info files spell them
_DISTORTION = {
    "none": "none",
    "brown_conrady": "Brown Conrady",
    "inverse_brown_conrady": "Inverse Brown Conrady",
    "modified_brown_conrady": "Modified Brown Conrady",
    "kannala_brandt4": "Kannala Brandt4",
    "ftheta": "F-Theta",
}
_SYNC_MODES = {"default": 0, "master": 1, "slave": 2}


def _rs() -> Any:
    """The ``pyrealsense2`` module, or a :class:`~pcdcodec.PcdcodecError` saying how to get it."""
    try:
        import pyrealsense2 as rs
    except ImportError:
        raise PcdcodecError(f"live RealSense capture needs pyrealsense2: {_INSTALL}") from None
    return rs


def connected_serials() -> list[str]:
    """The serial numbers of the RealSense devices connected now (empty when there are none)."""
    rs = _rs()
    return [d.get_info(rs.camera_info.serial_number) for d in rs.context().query_devices()]


def _intrinsics(rs: Any, profile: Any) -> CameraIntrinsics:
    """A video stream profile's intrinsics as the project's camera."""
    k = profile.as_video_stream_profile().get_intrinsics()
    model = str(k.model).rsplit(".", 1)[-1]
    return CameraIntrinsics.from_camera_info(
        {
            "width": int(k.width),
            "height": int(k.height),
            "K": [k.fx, 0.0, k.ppx, 0.0, k.fy, k.ppy, 0.0, 0.0, 1.0],
            "D": [float(c) for c in k.coeffs],
            "distortion_model": _DISTORTION.get(model, model),
        }
    )


def _extrinsics(src: Any, dst: Any) -> npt.NDArray[np.float64]:
    """The rigid 4 × 4 transform from stream ``src``'s frame to ``dst``'s (metres)."""
    e = src.get_extrinsics_to(dst)
    out = np.eye(4)
    out[:3, :3] = np.asarray(e.rotation, dtype=np.float64).reshape(3, 3).T  # column-major
    out[:3, 3] = np.asarray(e.translation, dtype=np.float64)
    return out


def _color_pixels(frame: Any, where: str) -> npt.NDArray[np.uint8]:
    """A color frame's pixels as H×W×3 RGB, copied out of librealsense's buffer."""
    fmt = str(frame.get_profile().format()).rsplit(".", 1)[-1]
    data = np.asanyarray(frame.get_data())
    if fmt in ("rgb8", "rgba8"):
        return np.array(data[..., :3], order="C")  # a copy: the buffer goes back to the pool
    if fmt in ("bgr8", "bgra8"):
        return np.array(data[..., 2::-1], order="C")
    raise InputError(f"{where}: color frames are {fmt}; pcdcodec reads rgb8, bgr8, rgba8, bgra8")


class _Counter:
    """One stream's frame counter: what the camera dropped (gaps), and repeats to skip."""

    def __init__(self) -> None:
        self.last: tuple[int, int] | None = None  # (frame number, timestamp ns)
        self.dropped = 0

    def new(self, number: int, stamp: int) -> bool:
        """Whether frame ``number`` at ``stamp`` is new: later than every frame before (a
        repeat, or a frame from before the last one, is not); counts a gap in the numbers (a
        number lower than the last one starts the count again: a looped playback)."""
        if self.last is not None:
            if stamp <= self.last[1]:
                return False
            if number > self.last[0] + 1:
                self.dropped += number - self.last[0] - 1
        self.last = (number, stamp)
        return True


class RealSenseLiveSource(Source):
    """Frames from a RealSense camera as they arrive (see :func:`realsense_live`)."""

    def __init__(
        self,
        serial: str | None = None,
        *,
        playback: str | Path | None = None,
        width: int | None = None,
        height: int | None = None,
        fps: int | None = None,
        color_width: int | None = None,
        color_height: int | None = None,
        color_fps: int | None = None,
        color: bool = True,
        align: bool = False,
        real_time: bool = False,
        loop: bool = False,
        max_frames: int | None = None,
        duration: float | None = None,
        global_time: bool | None = None,
        sync: str | None = None,
        timeout: float = 5.0,
        max_difference: int = MAX_DIFFERENCE,
    ) -> None:
        self.max_difference = as_max_difference(max_difference)
        rs = _rs()
        self._rs = rs
        for name, value in (("max_frames", max_frames), ("duration", duration)):
            if value is not None and not value > 0:
                raise InputError(f"{name} must be positive, got {value!r}")
        if sync is not None and sync not in _SYNC_MODES:
            raise InputError(f"sync must be one of {', '.join(_SYNC_MODES)}, got {sync!r}")
        if loop and playback is None:
            raise InputError("loop=True repeats a playback file; pass playback=")
        self.path = Path(playback) if playback is not None else Path(f"realsense:{serial or ''}")
        if playback is not None and not self.path.is_file():
            raise InputError(f"{str(self.path)!r} is not a file (playback takes a RealSense .bag)")
        self.playback = playback is not None
        self.real_time, self.loop, self.align = real_time, loop, align
        self.max_frames, self.duration, self.timeout = max_frames, duration, timeout
        self.has_color = color
        self._stop = threading.Event()
        self._depth = _Counter()
        self._color = _Counter()
        self._stats = PairStats()
        self._unaligned = 0  # pairs librealsense never put in one frameset (align=True)
        self.frames_read = 0
        self._config = rs.config()
        if playback is not None:
            self._config.enable_device_from_file(str(self.path), repeat_playback=False)
            self._config.enable_stream(rs.stream.depth)
            if color:
                self._config.enable_stream(rs.stream.color)
        else:
            if serial is not None:
                self._config.enable_device(str(serial))
            self._config.enable_stream(
                rs.stream.depth, width or 0, height or 0, rs.format.z16, fps or 0
            )
            if color:
                self._config.enable_stream(
                    rs.stream.color,
                    color_width or width or 0,
                    color_height or height or 0,
                    rs.format.rgb8,
                    color_fps or fps or 0,
                )
        self._pipeline = rs.pipeline()
        self._running = False
        self._first: Any = None
        self._start()
        try:
            self._describe(global_time, sync, (width, height, fps))
            # The first frames say which clock stamps them, before anything is written.
            self._first = self._wait()
            if self._first is not None:
                self._first.keep()
                depth = self._first.get_depth_frame()
                if depth:
                    self._domain(depth)
        except BaseException:
            self.close()
            raise

    # -- opening ----------------------------------------------------------------------

    def _start(self) -> None:
        try:
            self._profile = self._pipeline.start(self._config)
        except RuntimeError as exc:
            what = f"{str(self.path)!r}" if self.playback else "the RealSense camera"
            raise InputError(f"{what} does not start: {exc}") from None
        self._running = True
        if self.playback:
            device = self._profile.get_device().as_playback()
            device.set_real_time(bool(self.real_time))

    def _describe(self, global_time: bool | None, sync: str | None, asked: tuple[Any, ...]) -> None:
        rs = self._rs
        profile = self._profile
        device = profile.get_device()
        sensor = device.first_depth_sensor()
        depth = profile.get_stream(rs.stream.depth)
        if self.playback and any(v is not None for v in asked):
            k = depth.as_video_stream_profile()
            got = (k.width(), k.height(), k.fps())
            if any(a is not None and a != g for a, g in zip(asked, got, strict=True)):
                raise InputError(
                    f"{str(self.path)!r} holds depth at {got[0]}x{got[1]} {got[2]} fps; "
                    f"asked for {asked}"
                )
        for option, value in (
            (rs.option.global_time_enabled, global_time),
            (rs.option.inter_cam_sync_mode, None if sync is None else _SYNC_MODES[sync]),
        ):
            if value is not None and not self.playback and sensor.supports(option):
                sensor.set_option(option, float(value))
        # The option is a float32: its shortest decimal form is the value that was set.
        metres = float(str(np.float32(sensor.get_depth_scale())))
        if not metres > 0:
            raise InputError(f"{str(self.path)!r}: the device reports depth units {metres}")
        self.depth_scale = 1.0 / metres
        self.intrinsics = _intrinsics(rs, depth)
        self.fps = float(depth.fps())
        self.color_intrinsics = None
        self.depth_to_color = None
        if self.has_color:
            color = profile.get_stream(rs.stream.color)
            if self.align:
                self._aligner = rs.align(rs.stream.depth)
            else:
                self.color_intrinsics = _intrinsics(rs, color)
                self.depth_to_color = _extrinsics(depth, color)
        info = rs.camera_info
        self.metadata = {"source": "realsense-live"}
        for key, label in (
            (info.name, "device"),
            (info.serial_number, "serial"),
            (info.firmware_version, "firmware"),
            (info.product_id, "product_id"),
        ):
            if device.supports(key):
                self.metadata[label] = str(device.get_info(key))
        if self.playback:
            self.metadata["playback"] = str(self.path)
        if self.align:
            self.metadata["color"] = "aligned to depth by librealsense"
        self.serial = self.metadata.get("serial")

    # -- frames -----------------------------------------------------------------------

    @property
    def camera_drops(self) -> dict[str, int]:
        """Frames the camera dropped so far, by stream: gaps in its frame counters."""
        return {"depth": self._depth.dropped, "color": self._color.dropped}

    @property
    def dropped(self) -> dict[str, int]:
        """Images taken but left out so far for want of a partner within ``max_difference``,
        by stream, as every reader counts them (with ``align=True``, also the pairs that
        librealsense never put in one frameset, which cannot be aligned)."""
        return {
            "color": self._stats.dropped_color + self._unaligned,
            "depth": self._stats.dropped_depth + self._unaligned,
        }

    def stop(self) -> None:
        """Make iterating end after the frame it is waiting for (from any thread)."""
        self._stop.set()

    def _wait(self) -> Any | None:
        """The next frameset, or ``None`` at the end of a playback file or after :meth:`stop`."""
        rs = self._rs
        waited = 0.0
        while not self._stop.is_set():
            ok, frames = self._pipeline.try_wait_for_frames(100)
            if ok:
                return frames
            if self.playback:
                status = self._profile.get_device().as_playback().current_status()
                if status == rs.playback_status.stopped:
                    return None
            waited += 0.1
            if waited >= self.timeout:
                raise DecodeError(f"{str(self.path)!r}: no frames for {self.timeout:g} s")
        return None

    def _stamp(self, frame: Any) -> int:
        return round(float(frame.get_timestamp()) * _NS_PER_MS)

    def _framesets(self) -> Iterator[Any]:
        """Every frameset, through the loops of a looped playback; the time offset of each
        loop (so that timestamps keep increasing) is in ``self._offset``."""
        self._offset = 0
        first: int | None = None  # the earliest depth stamp of the file, as the device gives it
        while True:
            frames = self._first if self._first is not None else self._wait()
            self._first = None
            if frames is None:
                last = self._depth.last
                if not self.loop or self._stop.is_set() or last is None or first is None:
                    return
                self._pipeline.stop()
                self._start()
                # The next pass starts one frame period after the last frame of this one; a
                # frame that would still come earlier (the file's first frames, missed in the
                # first pass) is left out, as the frame counters keep their last stamps.
                self._offset = last[1] + round(1e9 / (self.fps or 30.0)) - first
                continue
            d = frames.get_depth_frame()
            if d:
                raw = self._stamp(d)
                first = raw if first is None else min(first, raw)
            yield frames

    def _events(self) -> Iterator[tuple[bool, int, Any]]:
        """``(is_depth, stamp, item)`` of each new frame, in arrival order: the pixels, or with
        ``align=True`` see :meth:`_aligned_events`."""
        if self.has_color and self.align:
            yield from self._aligned_events()
            return
        where = repr(str(self.path))
        for frames in self._framesets():
            got: list[tuple[bool, int, Any]] = []
            d = frames.get_depth_frame()
            if d:
                stamp = self._stamp(d) + self._offset
                if self._depth.new(int(d.get_frame_number()), stamp):
                    self._domain(d)
                    got.append((True, stamp, np.array(np.asanyarray(d.get_data()))))
            c = frames.get_color_frame() if self.has_color else None
            if c:
                stamp = self._stamp(c) + self._offset
                if self._color.new(int(c.get_frame_number()), stamp):
                    got.append((False, stamp, _color_pixels(c, where)))
            got.sort(key=lambda e: (e[1], not e[0]))
            yield from got

    def _aligned_events(self) -> Iterator[tuple[bool, int, Any]]:
        """``(is_depth, stamp, item)`` of each new frame with color aligned to depth by
        librealsense. A depth item is ``(pixels, aligned)``, where ``aligned`` maps the stamp of
        each color frame librealsense put in a frameset with it to that color aligned to it
        (filled while the depth waits for its partner); a color item is its stamp. Each
        frameset is aligned as it comes and copied out, so none is held."""
        where = repr(str(self.path))
        current: tuple[int, dict[int, Any]] | None = None  # the latest depth's stamp, aligned
        for frames in self._framesets():
            got: list[tuple[bool, int, Any]] = []
            d, c = frames.get_depth_frame(), frames.get_color_frame()
            if d:
                stamp = self._stamp(d) + self._offset
                if self._depth.new(int(d.get_frame_number()), stamp):
                    self._domain(d)
                    current = (stamp, {})
                    got.append((True, stamp, (np.array(np.asanyarray(d.get_data())), current[1])))
                if c and current is not None and current[0] == stamp:
                    color_stamp = self._stamp(c) + self._offset
                    if color_stamp not in current[1]:
                        aligned = self._aligner.process(frames).get_color_frame()
                        current[1][color_stamp] = _color_pixels(aligned, where)
            if c:
                stamp = self._stamp(c) + self._offset
                if self._color.new(int(c.get_frame_number()), stamp):
                    got.append((False, stamp, stamp))
            got.sort(key=lambda e: (e[1], not e[0]))
            yield from got

    def _domain(self, frame: Any) -> None:
        if "timestamp_domain" not in self.metadata:
            domain = str(frame.get_frame_timestamp_domain()).rsplit(".", 1)[-1]
            self.metadata["timestamp_domain"] = domain

    def _pairs(self) -> Iterator[tuple[int, Any, Any, int | None]]:
        """``(stamp, depth, color, color stamp)``: depth and color paired by the rule of every
        reader (:func:`~pcdcodec.ros.bagindex.pair_in_order`: each image used once, within
        ``max_difference``), depth alone when the source has no color."""
        events = self._events()
        if not self.has_color:
            yield from ((stamp, depth, None, None) for _, stamp, depth in events)
            return
        pairs = pair_in_order(events, self.max_difference, self._stats)
        for stamp, depth, color, color_stamp in pairs:
            if not self.align:
                yield stamp, depth, color, color_stamp
                continue
            pixels, aligned = depth
            rgb = aligned.get(color)
            if rgb is None:  # librealsense never put these two in one frameset
                self._unaligned += 1
                continue
            yield stamp, pixels, rgb, color_stamp

    def __iter__(self) -> Iterator[Any]:
        from ..frame import Frame

        start = time.monotonic()
        for stamp, depth, rgb, color_stamp in self._pairs():
            # The frame is at the depth's time; the color keeps its own.
            yield Frame(rgb, depth, stamp, index=self.frames_read, color_timestamp_ns=color_stamp)
            self.frames_read += 1
            if self.max_frames is not None and self.frames_read >= self.max_frames:
                return
            if self.duration is not None and time.monotonic() - start >= self.duration:
                return

    def _played_bag(self) -> Any:
        """The played-back ``.bag`` read by pcdcodec's own reader, for its topics (``None`` for a
        camera, or a bag that reader refuses)."""
        if not self.playback:
            return None
        found = getattr(self, "_bag_topics", None)
        if found is None:
            from .realsense import RealSenseBagSource

            try:
                found = RealSenseBagSource(self.path)
            except PcdcodecError:
                found = False
            self._bag_topics = found
        return None if found is False else found

    def input_streams(self) -> list[InputStream]:
        """Of a played-back ``.bag``, its topics (a camera's other streams, infrared and IMU,
        are never opened: nothing of them is read)."""
        bag = self._played_bag()
        return [] if bag is None else bag.input_streams()

    def recorded_streams(self) -> set[str]:
        """The topics a played-back ``.bag`` gives the frames, camera and depth units from
        (without color, not the color stream's)."""
        bag = self._played_bag()
        if bag is None:
            return set()
        kept: set[str] = bag.recorded_streams()
        if not self.has_color and bag.color_topic:
            color = bag.color_topic[: -len("/image/data")]
            depth = bag.depth_topic[: -len("/image/data")]
            kept = {t for t in kept if not t.startswith(color + "/") and t != f"{depth}/tf/0"}
        return kept

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        out["camera_drops"] = self.camera_drops
        out["dropped"] = self.dropped
        out["timestamp_domain"] = self.metadata.get("timestamp_domain")
        return out

    def close(self) -> None:
        """Stop the camera (or the playback)."""
        self._stop.set()
        if self._running:
            self._running = False
            with contextlib.suppress(RuntimeError):  # already stopped
                self._pipeline.stop()


def realsense_live(serial: str | None = None, **options: Any) -> RealSenseLiveSource:
    """A RealSense camera as a :class:`~pcdcodec.sources.Source` whose frames arrive live.

    ``serial`` picks a connected device (default: the first one); ``playback`` plays a
    librealsense ``.bag`` instead, as fast as frames are taken (``real_time=True``: at the
    recorded pace, dropping what is not taken in time, as a camera does; ``loop=True``:
    again and again, with timestamps that keep increasing). ``width``, ``height`` and ``fps``
    choose the depth stream (default: the device's), ``color_width``, ``color_height`` and
    ``color_fps`` the color stream (default: as depth); a playback file gives the streams it
    holds, and a depth size or rate that differs from them is an error. ``color=False``
    records depth only. ``align=True`` gives color aligned to depth by librealsense
    (``rs.align``), at the depth camera's size, instead of the color camera's own images with
    ``color_intrinsics`` and ``depth_to_color``. Depth and color are paired as every reader
    pairs them (:mod:`pcdcodec.sync`): each image used once, within ``max_difference`` ns
    (default :data:`~pcdcodec.sync.MAX_DIFFERENCE`, 20 ms); the images left without a partner
    are counted in :attr:`~RealSenseLiveSource.dropped`.

    Iterating ends after ``max_frames`` frames, after ``duration`` seconds, at the end of a
    playback file, or after :meth:`~RealSenseLiveSource.stop`. ``global_time`` turns the
    device's global timestamps on or off (host-aligned hardware time, which lets several
    cameras share a clock); ``sync`` sets the depth sensor's inter-camera sync mode
    (``"master"``, ``"slave"``, ``"default"``) for cameras wired together. Timestamps are the
    device's (``metadata["timestamp_domain"]`` says which clock), in nanoseconds; what the
    camera dropped is in ``camera_drops``. Raises :class:`~pcdcodec.PcdcodecError` when
    pyrealsense2 is not installed and :class:`~pcdcodec.InputError` when no device (or file)
    starts with these settings, and ``TypeError`` for an option it does not take.
    """
    return RealSenseLiveSource(serial, **options)
