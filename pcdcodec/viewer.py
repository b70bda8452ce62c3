"""Looking at a recording: color, depth, the point cloud, the camera and its trajectory, over time.

:func:`view` sends a ``.pcdc`` recording to the Rerun viewer (``pip install "pcdcodec[view]"``),
or writes a ``.rrd`` file that the viewer opens later (``rerun out.rrd``). Each frame is logged
at its recorded time (timeline ``time``) and by number (timeline ``frame``), kept small:

* ``world/camera``: the pinhole camera (intrinsics, image size; x right, y down, z forward),
  placed by the frame's pose where the recording has poses;
* ``world/camera/image/depth``: the depth image, lossless as a 16-bit PNG (or RVL) in Rerun's
  ``EncodedDepthImage`` with its scale (``meter``): the viewer back-projects it into a cloud
  through the pinhole itself;
* ``world/camera/image/rgb``: the color stream. H.264, H.265 and AV1 recordings pass their own
  packets to Rerun's ``VideoStream`` as written, without re-encoding; MJPEG packets are logged as
  the JPEG images they are; other codecs are decoded and logged as JPEG images;
* ``world/camera/points``: the colored point cloud, only when asked (``points``; every
  ``stride``-th pixel in each direction);
* ``world/trajectory``: the positions of the frames shown as one line (static), where poses
  exist.

Rerun 0.23 lacks ``VideoStream`` (0.24 on) and releases before ``EncodedDepthImage`` (later)
lack encoded depth: there color falls back to JPEG images and depth to the raw ``DepthImage``,
as it does for float32 depth, which neither PNG nor RVL holds (``docs/view.md``).

A recording of several cameras is shown by frame sets (``RigRecording.framesets()``: one frame
per camera, matched by time; timeline ``frame`` is the set's number, and each camera's frame is
logged at its own time): ``world`` is the rig frame, and each camera is ``world/<name>``, placed
by its rig pose, with its pinhole, ``image/rgb``, ``image/depth`` and ``points`` as above;
``world/fused`` is the set's fused cloud in the rig frame (each camera's thinned points moved by
its rig pose), also only with ``points``. Frames that no set took are not shown.

:func:`view_open3d` plays the point clouds in Open3D's own window, for machines with a display
and without Rerun. :class:`LiveView` streams frames to a Rerun viewer as they are recorded
(``pcdcodec record --view``), one entity tree per camera (``world/<name>/...``). rerun and open3d
are imported only here, when called.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ._atomic import atomic_output
from .errors import InputError, PcdcodecError

__all__ = ["DEPTH_FORMATS", "LiveView", "view", "view_open3d"]

_INSTALL = 'pip install "pcdcodec[view]"'

#: How :func:`view` logs depth: a 16-bit PNG, RVL (both lossless, in ``EncodedDepthImage``),
#: or Rerun's raw ``DepthImage``.
DEPTH_FORMATS = ("png", "rvl", "raw")
#: Rerun's names of the video codecs whose packets it decodes as they are.
_VIDEO_CODECS = {"h264": "H264", "h265": "H265", "av1": "AV1"}


def _rerun() -> Any:
    try:
        import rerun as rr
    except ImportError:
        raise PcdcodecError(f"the viewer needs rerun-sdk: {_INSTALL}") from None
    return rr


@dataclass(frozen=True)
class _Options:
    """What :func:`view` logs and how."""

    stride: int
    jpeg_quality: int | None
    points: bool
    depth_format: str
    png_level: int = 6
    video: bool = True


def _depth_blob(rr: Any, depth: Any, fmt: str, png_level: int = 6) -> tuple[bytes, str] | None:
    """``depth`` encoded for Rerun's ``EncodedDepthImage`` (bytes and media type, lossless),
    or ``None`` where it is logged raw: ``fmt`` ``"raw"``, float32 depth (neither PNG nor RVL
    holds it) or an installed rerun without ``EncodedDepthImage``."""
    depth = _native(depth)
    if fmt == "raw" or depth.dtype != np.uint16 or not hasattr(rr, "EncodedDepthImage"):
        return None
    depth = np.ascontiguousarray(depth)
    if fmt == "rvl":
        from .ros.messages import compressed_depth_encode

        return compressed_depth_encode(depth, rvl=True), "application/rvl"
    import imagecodecs

    return bytes(imagecodecs.png_encode(depth, level=png_level)), "image/png"


def _native(depth: Any) -> Any:
    """``depth`` in the machine's byte order (a copy only where it is not)."""
    return depth.astype(depth.dtype.newbyteorder("="), copy=False)


def _depth_image(
    rr: Any, depth: Any, meter: float, fmt: str, png_level: int = 6, blob: Any = False
) -> Any:
    """``depth`` as a Rerun archetype, encoded where :func:`_depth_blob` encodes it (``blob``:
    what it gave, when already called), else the raw ``DepthImage``."""
    depth = _native(depth)  # Rerun takes an image's bytes as little-endian
    if blob is False:
        blob = _depth_blob(rr, depth, fmt, png_level)
    if blob is None:
        return rr.DepthImage(depth, meter=meter)
    return rr.EncodedDepthImage(blob=blob[0], media_type=blob[1], meter=meter)


def _color_mode(rr: Any, recording: Any, video: bool) -> str:
    """How the color of ``recording`` is logged: ``"stream"`` (its packets in a
    ``VideoStream``), ``"jpeg"`` (its MJPEG packets as images), ``"images"`` (decoded, then
    JPEG) or ``"none"`` (no color)."""
    codec = recording.color_codec
    if codec is None:
        return "none"
    if not video:
        return "images"
    if codec.name == "mjpeg":
        return "jpeg"
    height, width = recording.color_shape
    padded = getattr(codec, "padded_size", None)
    name = _VIDEO_CODECS.get(getattr(codec, "video_format", None) or "")
    if (
        name is not None
        and hasattr(rr, "VideoStream")
        and hasattr(rr.VideoCodec, name)  # a release's VideoStream may lack some codecs
        and getattr(codec, "pix_fmt", "yuv420p") == "yuv420p"
        and recording.extradata is None  # parameter sets travel in the packets
        and (padded is None or padded(width, height) == (width, height))
        # Decode order is display order (no B-frames): Rerun gives a sample one time.
        and bool(np.all(np.diff(recording.packet_timestamps) > 0))
    ):
        return "stream"
    return "images"


def _log_packets(
    rr: Any, rec: Any, recording: Any, entity: str, mode: str, shown: dict[int, int]
) -> None:
    """The color packets of ``recording`` at their times, up to the last frame shown.

    ``shown`` maps the time (ns) of each frame shown to its number on timeline ``frame``. A
    video stream needs every packet from a keyframe on: those of frames not shown are logged
    on timeline ``time`` alone. MJPEG packets are logged for the frames shown only.
    """
    if not shown:
        return
    last = max(shown)
    if mode == "stream":
        codec = getattr(rr.VideoCodec, _VIDEO_CODECS[recording.color_codec.video_format])
        rec.log(entity, rr.VideoStream(codec=codec), static=True)
    for packet in recording.packets():
        if packet.pts > last:
            break
        number = shown.get(packet.pts)
        if number is None and mode != "stream":
            continue
        if number is None:
            rec.disable_timeline("frame")
        else:
            rec.set_time("frame", sequence=number)
        rec.set_time("time", timestamp=np.datetime64(packet.pts, "ns"))
        if mode == "stream":
            rec.log(entity, rr.VideoStream.from_fields(sample=packet.data))
        else:
            rec.log(entity, rr.EncodedImage(contents=packet.data, media_type="image/jpeg"))


def _log_frame(
    rr: Any,
    rec: Any,
    frame: Any,
    opts: _Options,
    mode: str,
    base: str = "world/camera",
    place: bool = True,
    blob: Any = False,
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any] | None] | None:
    """Log one frame under ``base`` (placed by the frame's pose when ``place``): its depth
    (``blob``: its :func:`_depth_blob`, when encoded already), its color when ``mode`` is
    ``"images"``, and with ``opts.points`` its thinned points, which are returned with their
    colors (camera frame); ``None`` without."""
    projector = frame.projector
    if place and frame.pose is not None:
        pose = np.asarray(frame.pose, dtype=np.float64)
        rec.log(base, rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
    if mode == "images" and frame.color is not None:
        image = rr.Image(frame.color)
        quality = opts.jpeg_quality
        rec.log(f"{base}/image/rgb", image.compress(jpeg_quality=quality) if quality else image)
    # Depth units per metre, float32 depth too: as the projector (and format.md) divide it.
    meter = projector.depth_scale
    rec.log(
        f"{base}/image/depth",
        _depth_image(rr, frame.depth, meter, opts.depth_format, opts.png_level, blob),
    )
    if not opts.points:
        return None
    stride = opts.stride
    points, colors = _subsampled_points(projector, frame.depth, frame.color, stride)
    rec.log(f"{base}/points", rr.Points3D(points, colors=colors, radii=0.004 * stride))
    return points, colors


def _log_camera(rr: Any, rec: Any, base: str, cam: Any, pose: Any = None) -> None:
    """The pinhole of camera ``cam`` at ``base`` (and where it sits, if ``pose`` is given)."""
    if pose is not None:
        pose = np.asarray(pose, dtype=np.float64)
        rec.log(base, rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]), static=True)
    rec.log(
        base,
        rr.Pinhole(
            image_from_camera=cam.K,
            resolution=[cam.width, cam.height],
            camera_xyz=rr.ViewCoordinates.RDF,
            image_plane_distance=0.3,
        ),
        static=True,
    )


def _log_rig(
    rr: Any, rec: Any, rig: Any, every: int, max_frames: int | None, opts: _Options
) -> None:
    """Every camera of ``rig`` in its place, each frame set, its fused cloud with
    ``opts.points``, and each camera's color stream."""
    modes = {}
    for name, cam in rig.cameras.items():
        _log_camera(rr, rec, f"world/{name}", cam.intrinsics, cam.rig_pose)
        modes[name] = _color_mode(rr, rig.frames(name), opts.video)
    shown: dict[str, dict[int, int]] = {name: {} for name in modes}
    sets = rig.framesets()
    for i in range(0, len(sets), every)[:max_frames]:
        frameset = sets[i]
        rec.set_time("frame", sequence=i)
        points: list[np.ndarray[Any, Any]] = []
        colors: list[np.ndarray[Any, Any]] = []
        for name, frame in frameset.frames.items():
            if frame is None:
                continue
            shown[name][frame.timestamp_ns] = i
            rec.set_time("time", timestamp=np.datetime64(frame.timestamp_ns, "ns"))
            logged = _log_frame(rr, rec, frame, opts, modes[name], f"world/{name}", place=False)
            if logged is None:
                continue
            own, own_colors = logged
            pose = rig.rig_poses[name]
            points.append(own.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3])
            colors.append(
                own_colors if own_colors is not None else np.zeros((len(own), 3), np.uint8)
            )
        if not opts.points:
            continue
        rec.set_time("time", timestamp=np.datetime64(frameset.timestamp_ns, "ns"))
        fused = np.concatenate(points) if points else np.zeros((0, 3))
        rec.log(
            "world/fused",
            rr.Points3D(
                fused, colors=np.concatenate(colors) if colors else None, radii=0.004 * opts.stride
            ),
        )
    for name, mode in modes.items():
        if mode in ("stream", "jpeg"):
            entity = f"world/{name}/image/rgb"
            _log_packets(rr, rec, rig.frames(name), entity, mode, shown[name])


def _subsampled_points(
    projector: Any, depth: Any, color: Any, stride: int
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any] | None]:
    """Points of every ``stride``-th pixel in each direction, in metres in the camera frame,
    as the projector makes them (its color camera, distortion and ``depth_trunc`` included)."""
    if stride > 1:
        thinned = np.zeros_like(depth)  # 0: no depth, in uint16 and float32 alike
        thinned[::stride, ::stride] = depth[::stride, ::stride]
        depth = thinned
    return projector.to_points(depth, color)  # type: ignore[no-any-return]


def view(
    path: str | os.PathLike[str],
    *,
    save: str | os.PathLike[str] | None = None,
    every: int = 1,
    max_frames: int | None = None,
    stride: int = 2,
    jpeg_quality: int | None = 90,
    threads: int | None = None,
    points: bool = False,
    depth_format: str = "png",
    video: bool = True,
) -> Path | None:
    """Show the recording at ``path`` in the Rerun viewer, or write it to the ``.rrd`` file
    ``save`` (written beside its target and moved into place when complete; returned).

    ``every`` logs every n-th frame, ``max_frames`` stops after that many logged frames.
    ``depth_format`` is how depth is logged (:data:`DEPTH_FORMATS`: ``"png"``, the smallest,
    ``"rvl"``, the fastest to write, both lossless, or ``"raw"``). ``video`` passes H.264,
    H.265 and AV1 packets through as they are (``False``: every codec's color decoded and
    logged as images); ``jpeg_quality`` compresses the color logged as images (``None``: raw).
    ``points`` logs the point cloud as well (Rerun draws one from the depth image itself), of
    every ``stride``-th pixel in each direction (1 keeps all). ``threads`` is how many cores
    reading may use (:func:`pcdcodec.open`): with ``every`` 1 the frames are read in order,
    ahead on that many threads, when their color is decoded (images or ``points``; a color
    stream passed through leaves only depth to decode, read frame by frame). Raises
    :class:`~pcdcodec.InputError` for bad options and :class:`~pcdcodec.PcdcodecError` when
    rerun-sdk is not installed.
    """
    from .recording import open as open_recording
    from .recording.rig_reader import RigRecording

    for name, value in (("every", every), ("stride", stride)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(f"{name} must be a positive int, got {value!r}")
    if max_frames is not None and (
        isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 1
    ):
        raise InputError(f"max_frames must be None or a positive int, got {max_frames!r}")
    if jpeg_quality is not None and (
        isinstance(jpeg_quality, bool)
        or not isinstance(jpeg_quality, int)
        or not 1 <= jpeg_quality <= 100
    ):
        raise InputError(
            f"jpeg_quality must be an int in 1..100, or None for raw images, got {jpeg_quality!r}"
        )
    if depth_format not in DEPTH_FORMATS:
        raise InputError(f"depth_format must be one of {DEPTH_FORMATS}, got {depth_format!r}")
    opts = _Options(stride, jpeg_quality, points, depth_format, video=video)
    rr = _rerun()
    target = Path(save) if save is not None else None
    if target is not None and target.is_dir():
        raise InputError(f"{str(target)!r} is a folder; --save takes an .rrd file name")
    if target is not None and not target.parent.is_dir():
        raise InputError(f"cannot save {str(target)!r}: no folder {str(target.parent)!r}")
    with open_recording(path, threads=threads) as recording:
        stream = rr.RecordingStream("pcdcodec", recording_id=str(recording.path.resolve()))
        # Written beside the target and moved onto it when complete; removed if logging fails.
        output = atomic_output(target) if target is not None else contextlib.nullcontext()
        with output as partial, _file_errors(partial):
            if partial is not None:
                stream.save(str(partial))
            else:
                stream.spawn()
            try:
                stream.log("world", rr.ViewCoordinates.RDF, static=True)
                if isinstance(recording, RigRecording):
                    _log_rig(rr, stream, recording, every, max_frames, opts)
                else:
                    _log_recording(rr, stream, recording, every, max_frames, opts)
                stream.flush()
            finally:
                stream.disconnect()
    return target


@contextlib.contextmanager
def _file_errors(partial: Path | None) -> Iterator[None]:
    """Rerun's errors writing the file ``partial`` (a ``RuntimeError`` whose text ends in the
    system's ``(os error N)``) raised as the ``OSError`` they are, so that the output's
    handler names the user's path and says what to do (a folder not writable, a full disk)."""
    try:
        yield
    except RuntimeError as exc:
        found = re.search(r"\(os error (\d+)\)", str(exc))
        if partial is None or found is None:
            raise
        code = int(found.group(1))
        raise OSError(code, os.strerror(code), str(partial)) from exc


def _log_recording(
    rr: Any, rec: Any, recording: Any, every: int, max_frames: int | None, opts: _Options
) -> None:
    """The camera of a one-camera recording, each frame, its color and the trajectory."""
    _log_camera(rr, rec, "world/camera", recording.intrinsics)
    mode = _color_mode(rr, recording, opts.video)
    trajectory: list[np.ndarray[Any, Any]] = []
    shown: dict[int, int] = {}
    if opts.points or mode == "images":
        frames: Iterator[tuple[int, Any, Any]] = (
            (i, frame, False) for i, frame in _frames(recording, every, max_frames)
        )
    else:
        frames = _depth_frames(recording, every, max_frames, rr, opts)
    for i, frame, blob in frames:
        shown[frame.timestamp_ns] = i
        rec.set_time("frame", sequence=i)
        rec.set_time("time", timestamp=np.datetime64(frame.timestamp_ns, "ns"))
        _log_frame(rr, rec, frame, opts, mode, blob=blob)
        if frame.pose is not None:
            trajectory.append(np.asarray(frame.pose, dtype=np.float64)[:3, 3])
    if trajectory:  # once, whole: a growing line logged every frame grows the file as n²
        rec.log("world/trajectory", rr.LineStrips3D([np.array(trajectory)]), static=True)
    if mode in ("stream", "jpeg"):
        _log_packets(rr, rec, recording, "world/camera/image/rgb", mode, shown)


def _frames(recording: Any, every: int, max_frames: int | None) -> Iterator[tuple[int, Any]]:
    """``(i, frame)`` of every ``every``-th frame, at most ``max_frames``: all of them read in
    order (ahead on the recording's threads), others one by one."""
    if every == 1:
        return enumerate(itertools.islice(recording, max_frames))
    return ((i, recording[i]) for i in range(0, len(recording), every)[:max_frames])


def _depth_frames(
    recording: Any, every: int, max_frames: int | None, rr: Any, opts: _Options
) -> Iterator[tuple[int, Any, Any]]:
    """``(i, frame, blob)`` as :func:`_frames` gives frames, without their color (not
    decoded): depth and pose, and the depth encoded (:func:`_depth_blob`). With the
    recording's ``threads`` at 2 or more, frames decode and encode ahead on that many threads,
    a few per thread at most, and come out in order."""
    from concurrent.futures import Future, ThreadPoolExecutor

    from .frame import Frame

    times = recording.timestamps
    poses = recording.poses() if recording.has_poses else None
    projector = recording.projector

    def load(i: int) -> tuple[int, Any, Any]:
        depth = recording.depth(i)
        pose = poses[i] if poses is not None else None
        frame = Frame(None, depth, int(times[i]), index=i, pose=pose, projector=projector)
        return i, frame, _depth_blob(rr, depth, opts.depth_format, opts.png_level)

    indices = iter(range(0, len(recording), every)[:max_frames])
    workers = recording.threads or 1
    if workers < 2:
        yield from map(load, indices)
        return
    with ThreadPoolExecutor(workers) as pool:
        ahead: list[Future[tuple[int, Any, Any]]] = [
            pool.submit(load, i) for i in itertools.islice(indices, 4 * workers)
        ]
        while ahead:
            done = ahead.pop(0).result()
            ahead.extend(pool.submit(load, i) for i in itertools.islice(indices, 1))
            yield done


def view_open3d(
    path: str | os.PathLike[str],
    *,
    every: int = 1,
    fps: float | None = None,
    threads: int | None = None,
) -> None:
    """Play the recording's point clouds in Open3D's window (needs a display); ``threads`` as
    for :func:`view`. Of a recording of several cameras, each frame set's fused cloud. Raises
    :class:`~pcdcodec.InputError` for bad options and a recording that cannot be read before
    any window opens."""
    import time

    import open3d as o3d

    from .recording import open as open_recording
    from .recording.rig_reader import RigRecording

    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise InputError(f"every must be a positive int, got {every!r}")
    if fps is not None and not fps > 0:
        raise InputError(f"fps must be positive, got {fps!r}")
    with open_recording(path, threads=threads) as recording:
        vis: Any = o3d.visualization.Visualizer()
        if not vis.create_window(window_name=f"pcdcodec {Path(path).name}"):
            raise PcdcodecError("Open3D could not open a window (no display?); use --save out.rrd")
        try:
            if isinstance(recording, RigRecording):  # each frame set's fused cloud
                sets = recording.framesets()
                rate = recording.cameras[sets.reference].fps
                shown: Iterator[Any] = (sets[i] for i in range(0, len(sets), every))
            else:
                rate = recording.fps
                shown = (frame for _, frame in _frames(recording, every, None))
            delay = 1.0 / (fps or rate)
            cloud = None
            for item in shown:
                new = item.to_point_cloud()
                if cloud is None:
                    cloud = new
                    vis.add_geometry(cloud)
                else:
                    cloud.points, cloud.colors = new.points, new.colors
                    vis.update_geometry(cloud)
                if not vis.poll_events():
                    break
                vis.update_renderer()
                time.sleep(delay)
        finally:
            vis.destroy_window()


class LiveView:
    """Frames streamed to a Rerun viewer while they are recorded, at most ``max_fps`` a camera.

    ``cameras`` is one ``(name, projector)`` per camera (a
    :class:`~pcdcodec.geometry.projector.Projector` with the camera's intrinsics, depth scale and
    color camera). :meth:`log` shows the color image (JPEG), the depth image (a lossless PNG
    written at zlib level 1, fast; the raw image where Rerun lacks encoded depth) and, with
    ``points``, every ``stride``-th point of the cloud under ``world/<name>``; frames coming
    faster than ``max_fps`` are skipped, so the viewer never slows the recording much.
    ``save`` writes a ``.rrd`` file instead of opening a window. Raises
    :class:`~pcdcodec.PcdcodecError` naming ``pip install "pcdcodec[view]"`` when rerun-sdk is
    not installed.
    """

    def __init__(
        self,
        cameras: list[tuple[str, Any]],
        *,
        max_fps: float = 5.0,
        stride: int = 4,
        save: str | os.PathLike[str] | None = None,
        points: bool = False,
    ) -> None:
        import time

        rr = _rerun()
        self._rr, self._time = rr, time.monotonic
        self.cameras, self.stride, self.period = cameras, stride, 1.0 / max_fps
        self.points = points
        self._last = [float("-inf")] * len(cameras)
        self.stream = rr.RecordingStream("pcdcodec-record")
        if save is not None:
            self.stream.save(str(save))
        else:
            self.stream.spawn()
        self.stream.log("world", rr.ViewCoordinates.RDF, static=True)
        for name, projector in cameras:
            _log_camera(rr, self.stream, f"world/{name}", projector.intrinsics)

    def log(self, index: int, frame: Any) -> bool:
        """Show ``frame`` of camera ``index``, unless one was shown less than a period ago."""
        now = self._time()
        if now - self._last[index] < self.period:
            return False
        self._last[index] = now
        rr, stream = self._rr, self.stream
        name, projector = self.cameras[index]
        stream.set_time("time", timestamp=np.datetime64(frame.timestamp_ns, "ns"))
        if frame.color is not None:
            stream.log(f"world/{name}/color", rr.Image(frame.color).compress(jpeg_quality=80))
        meter = projector.depth_scale  # depth units per metre, as for view()
        stream.log(f"world/{name}/depth", _depth_image(rr, frame.depth, meter, "png", 1))
        if not self.points:
            return True
        points, colors = projector.to_points(frame.depth, frame.color)
        step = self.stride * self.stride
        stream.log(
            f"world/{name}/points",
            rr.Points3D(points[::step], colors=None if colors is None else colors[::step]),
        )
        return True

    def close(self) -> None:
        """Send what is left and let the viewer go."""
        self.stream.flush()
        self.stream.disconnect()
