"""Looking at a recording: color, depth, the point cloud, the camera and its trajectory, over time.

:func:`view` sends a ``.pcdc`` recording to the Rerun viewer (``pip install "pcdcodec[view]"``),
or writes a ``.rrd`` file that the viewer opens later (``rerun out.rrd``). Each frame is logged
at its recorded time (timeline ``time``) and by number (timeline ``frame``):

* ``world/camera``: the pinhole camera (intrinsics, image size; x right, y down, z forward),
  placed by the frame's pose where the recording has poses;
* ``world/camera/image/rgb``: the color image (JPEG-compressed in the viewer's store unless
  ``jpeg_quality`` is ``None``), ``world/camera/image/depth``: the depth image with its scale;
* ``world/camera/points``: the colored point cloud (every ``stride``-th pixel in each direction);
* ``world/trajectory``: the camera positions as a line, where poses exist.

A recording of several cameras is shown by frame sets (``RigRecording.framesets()``: one frame
per camera, matched by time; timeline ``frame`` is the set's number, and each camera's frame is
logged at its own time): ``world`` is the rig frame, and each camera is ``world/<name>``, placed
by its rig pose, with its pinhole, ``image/rgb``, ``image/depth`` and ``points`` as above;
``world/fused`` is the set's fused cloud in the rig frame (each camera's thinned points moved by
its rig pose). Frames that no set took are not shown.

:func:`view_open3d` plays the point clouds in Open3D's own window, for machines with a display
and without Rerun. :class:`LiveView` streams frames to a Rerun viewer as they are recorded
(``pcdcodec record --view``), one entity tree per camera (``world/<name>/...``). rerun and open3d
are imported only here, when called.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ._atomic import partial_path
from .errors import InputError, PcdcodecError

__all__ = ["LiveView", "view", "view_open3d"]

_INSTALL = 'pip install "pcdcodec[view]"'


def _rerun() -> Any:
    try:
        import rerun as rr
    except ImportError:
        raise PcdcodecError(f"the viewer needs rerun-sdk: {_INSTALL}") from None
    return rr


def _log_frame(
    rr: Any,
    rec: Any,
    frame: Any,
    stride: int,
    jpeg_quality: int | None,
    base: str = "world/camera",
    place: bool = True,
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any] | None]:
    """Log one frame's images and thinned points under ``base`` (placed by the frame's pose
    when ``place``); returns the points and their colors, in the camera frame."""
    projector = frame.projector
    if place and frame.pose is not None:
        pose = np.asarray(frame.pose, dtype=np.float64)
        rec.log(base, rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
    if frame.color is not None:
        image = rr.Image(frame.color)
        rec.log(
            f"{base}/image/rgb",
            image.compress(jpeg_quality=jpeg_quality) if jpeg_quality is not None else image,
        )
    meter = 1.0 if frame.depth.dtype == np.float32 else projector.depth_scale
    rec.log(f"{base}/image/depth", rr.DepthImage(frame.depth, meter=meter))
    depth = frame.depth[::stride, ::stride]
    color = frame.color[::stride, ::stride] if frame.color is not None else None
    points, colors = _subsampled_points(projector, depth, color, stride)
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
    rr: Any, rec: Any, rig: Any, every: int, max_frames: int | None, stride: int, jpeg: int | None
) -> None:
    """Every camera of ``rig`` in its place, and each frame set with its fused cloud."""
    for name, cam in rig.cameras.items():
        _log_camera(rr, rec, f"world/{name}", cam.intrinsics, cam.rig_pose)
    sets = rig.framesets()
    for i in range(0, len(sets), every)[:max_frames]:
        frameset = sets[i]
        rec.set_time("frame", sequence=i)
        points: list[np.ndarray[Any, Any]] = []
        colors: list[np.ndarray[Any, Any]] = []
        for name, frame in frameset.frames.items():
            if frame is None:
                continue
            rec.set_time("time", timestamp=np.datetime64(frame.timestamp_ns, "ns"))
            own, own_colors = _log_frame(
                rr, rec, frame, stride, jpeg, base=f"world/{name}", place=False
            )
            pose = rig.rig_poses[name]
            points.append(own.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3])
            colors.append(
                own_colors if own_colors is not None else np.zeros((len(own), 3), np.uint8)
            )
        rec.set_time("time", timestamp=np.datetime64(frameset.timestamp_ns, "ns"))
        fused = np.concatenate(points) if points else np.zeros((0, 3))
        rec.log(
            "world/fused",
            rr.Points3D(
                fused, colors=np.concatenate(colors) if colors else None, radii=0.004 * stride
            ),
        )


def _subsampled_points(
    projector: Any, depth: Any, color: Any, stride: int
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any] | None]:
    """Points of every ``stride``-th pixel, in metres in the camera frame."""
    if stride == 1:
        return projector.to_points(depth, color)  # type: ignore[no-any-return]
    cam = projector.intrinsics
    v, u = np.nonzero(np.isfinite(depth) & (depth > 0))
    z = depth[v, u].astype(np.float64)
    if depth.dtype != np.float32:
        z = z / projector.depth_scale
    x = (u * stride - cam.cx) * z / cam.fx
    y = (v * stride - cam.cy) * z / cam.fy
    points = np.stack([x, y, z], axis=1).astype(np.float32)
    return points, (color[v, u] if color is not None else None)


def view(
    path: str | os.PathLike[str],
    *,
    save: str | os.PathLike[str] | None = None,
    every: int = 1,
    max_frames: int | None = None,
    stride: int = 2,
    jpeg_quality: int | None = 90,
    threads: int | None = None,
) -> Path | None:
    """Show the recording at ``path`` in the Rerun viewer, or write it to the ``.rrd`` file
    ``save`` (written beside its target and moved into place when complete; returned).

    ``every`` logs every n-th frame, ``max_frames`` stops after that many logged frames,
    ``stride`` thins the point cloud (every ``stride``-th pixel in each direction; 1 keeps all)
    and ``jpeg_quality`` compresses the color images (``None``: raw). ``threads`` is how many
    cores reading may use (:func:`pcdcodec.open`): with ``every`` 1 the frames are read in
    order, ahead on that many threads. Raises
    :class:`~pcdcodec.InputError` for bad options and :class:`~pcdcodec.PcdcodecError` when
    rerun-sdk is not installed.
    """
    from .recording import open as open_recording
    from .recording.rig_reader import RigRecording

    for name, value in (("every", every), ("stride", stride)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(f"{name} must be a positive int, got {value!r}")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    rr = _rerun()
    target = Path(save) if save is not None else None
    if target is not None and target.is_dir():
        raise InputError(f"{str(target)!r} is a folder; --save takes an .rrd file name")
    with open_recording(path, threads=threads) as recording:
        stream = rr.RecordingStream("pcdcodec", recording_id=str(recording.path.resolve()))
        partial = None
        if target is not None:
            partial = partial_path(target)
            stream.save(str(partial))
        else:
            stream.spawn()
        try:
            stream.log("world", rr.ViewCoordinates.RDF, static=True)
            if isinstance(recording, RigRecording):
                _log_rig(rr, stream, recording, every, max_frames, stride, jpeg_quality)
            else:
                _log_recording(rr, stream, recording, every, max_frames, stride, jpeg_quality)
            stream.flush()
        finally:
            stream.disconnect()
        if partial is not None and target is not None:
            os.replace(partial, target)
    return target


def _log_recording(
    rr: Any, rec: Any, recording: Any, every: int, max_frames: int | None, stride: int,
    jpeg: int | None,
) -> None:  # fmt: skip
    """The camera of a one-camera recording, each frame, and the trajectory."""
    _log_camera(rr, rec, "world/camera", recording.intrinsics)
    trajectory: list[np.ndarray[Any, Any]] = []
    for i, frame in _frames(recording, every, max_frames):
        rec.set_time("frame", sequence=i)
        rec.set_time("time", timestamp=np.datetime64(frame.timestamp_ns, "ns"))
        _log_frame(rr, rec, frame, stride, jpeg)
        if frame.pose is not None:
            trajectory.append(np.asarray(frame.pose, dtype=np.float64)[:3, 3])
            rec.log("world/trajectory", rr.LineStrips3D([np.array(trajectory)]))


def _frames(recording: Any, every: int, max_frames: int | None) -> Iterator[tuple[int, Any]]:
    """``(i, frame)`` of every ``every``-th frame, at most ``max_frames``: all of them read in
    order (ahead on the recording's threads), others one by one."""
    if every == 1:
        return enumerate(itertools.islice(recording, max_frames))
    return ((i, recording[i]) for i in range(0, len(recording), every)[:max_frames])


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
    color camera). :meth:`log` shows the color image, the depth image and every ``stride``-th
    point of the cloud under ``world/<name>``; frames coming faster than ``max_fps`` are
    skipped, so the viewer never slows the recording much. ``spawn=False`` with ``save`` writes
    a ``.rrd`` file instead of opening a window. Raises :class:`~pcdcodec.PcdcodecError`
    naming ``pip install "pcdcodec[view]"`` when rerun-sdk is not installed.
    """

    def __init__(
        self,
        cameras: list[tuple[str, Any]],
        *,
        max_fps: float = 5.0,
        stride: int = 4,
        save: str | os.PathLike[str] | None = None,
    ) -> None:
        import time

        rr = _rerun()
        self._rr, self._time = rr, time.monotonic
        self.cameras, self.stride, self.period = cameras, stride, 1.0 / max_fps
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
        meter = 1.0 if frame.depth.dtype == np.float32 else projector.depth_scale
        stream.log(f"world/{name}/depth", rr.DepthImage(frame.depth, meter=meter))
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
