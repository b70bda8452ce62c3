"""The archive's tasks for an input of several cameras (a bag whose depth topics lie in several
namespaces): probe it, encode a segment of it, check a segment, verify the output, each keeping
every camera.

A rig input is cut into segments by time: the cameras' frames are put in one timestamp order
(:class:`RigIndex`), the segment plan cuts that order as it cuts a one-camera input's frames,
and each segment holds every camera's frames from its first stamp to the next segment's. Each
segment is a recording of the whole rig, and the segments are joined as one-camera segments
are (by :func:`pcdcodec.recording.join.join`).
"""

from __future__ import annotations

import operator
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, PcdcodecError, VerificationError
from .checks import check_frames, depth_bound, digest

__all__ = ["RigIndex", "is_rig_input"]

#: Options that pick one camera of a bag: with any of them the bag is read as one camera.
_ONE_CAMERA = ("depth_topic", "color_topic", "info_topic", "cloud_topic")


def is_rig_input(src: str | Path, options: dict[str, Any]) -> bool:
    """Whether ``src`` is a bag of several cameras, read as a rig (not when ``options`` pick
    one camera's topics)."""
    from ..sources.base import detect_kind
    from ..sources.rig import bag_cameras

    if any(options.get(k) is not None for k in _ONE_CAMERA):
        return False
    if detect_kind(src) != "rosbag":
        return False
    try:
        return len(bag_cameras(src)) > 1
    except PcdcodecError:
        return False  # read as one camera, whose reader says what is wrong


@dataclass(frozen=True, eq=False)
class RigIndex:
    """The frames of every camera of a rig input, in one timestamp order: per camera its
    :class:`~pcdcodec.sources.FrameIndex` (``None`` for a camera read without one), and the
    sorted stamps of all frames. :meth:`slice` takes positions in that order and gives each
    camera's frames in the same stretch of time."""

    cameras: dict[str, Any]
    stamps: Any

    def __len__(self) -> int:
        return int(self.stamps.shape[0])

    def slice(self, start: int = 0, stop: int | None = None) -> RigIndex:
        """The frames from the stamp at ``start`` up to (not including) the stamp at ``stop``,
        of every camera."""
        n = len(self)
        lo = int(self.stamps[start]) if start < n else None
        hi = int(self.stamps[stop]) if stop is not None and stop < n else None
        out = {}
        for name, index in self.cameras.items():
            ts = index.timestamps
            i0 = len(ts) if lo is None else int(np.searchsorted(ts, lo, side="left"))
            i1 = len(ts) if hi is None else int(np.searchsorted(ts, hi, side="left"))
            out[name] = index.slice(i0, i1)
        stamps = self.stamps[start:stop]
        return RigIndex(out, stamps.copy())


def _open(src: str, options: dict[str, Any]) -> tuple[list[Any], str]:
    from ..sources.rig import open_inputs

    cams, root = open_inputs([src], **options)
    return cams, root or "rig"


def probe_rig(src: str, options: dict[str, Any], plan: Any) -> dict[str, Any]:
    """Frame count, cameras and, where the plan cuts the input, the :class:`RigIndex` of a rig
    input (its size and hash are the caller's). ``plan(frames)`` says whether that many frames
    would be cut."""
    from ..sources.rig import close_inputs

    cams, _ = _open(src, options)
    try:
        cameras = {}
        for cam in cams:
            source = cam.source
            if source.intrinsics is None:
                raise InputError(
                    f"{src!r}: camera {cam.name} does not say its camera intrinsics (no "
                    "CameraInfo topic)"
                )
            cameras[cam.name] = {
                "camera": source.intrinsics.to_dict(),
                "camera_from": source.intrinsics_origin,
                "depth_scale": float(source.depth_scale),
                "depth_scale_from": source.depth_scale_origin,
                "notes": list(source.camera_notes),
                "rig_pose_from": cam.pose_from,
            }
        most = sum(operator.length_hint(cam.source, 0) for cam in cams)
        frames: int | None = None
        index = None
        if plan(most):
            parts = {cam.name: cam.source.frame_index() for cam in cams}
            if all(p is not None for p in parts.values()):
                stamps = np.sort(np.concatenate([p.timestamps for p in parts.values()]))
                index = RigIndex(parts, stamps)
                frames = len(index)
        first = next(iter(cameras.values()))
        camera = {
            **first,
            "camera_from": f"{first['camera_from']}; {len(cameras)} cameras: " + ", ".join(cameras),
            "cameras": cameras,
        }
        return {"frames": frames, "index": index, "camera": camera}
    finally:
        close_inputs(cams)


def encode_rig_segment(
    src: str,
    options: dict[str, Any],
    tmp: Path,
    writer_options: dict[str, Any],
    index: RigIndex | None,
) -> int:
    """Write the frames ``index`` lists (all without one) of every camera of ``src`` into a
    new rig recording at ``tmp``; returns the frames written."""
    from ..recording.encode_rig import rig_specs, write_rig
    from ..sources.rig import close_inputs

    cams, rig_frame = _open(src, options)
    try:
        specs, _ = rig_specs(
            cams,
            rig_frame,
            color=writer_options["color"],
            depth=writer_options["depth"],
            fps=writer_options["fps"],
        )
        frames = None
        if index is not None:
            frames = [cam.source.frames_at(index.cameras[cam.name]) for cam in cams]
        meta = {f"{c.name}.{k}": v for c in cams for k, v in c.source.metadata.items()}
        done = write_rig(tmp, cams, specs, rig_frame, metadata=meta, frames=frames)
    finally:
        close_inputs(cams)
    return sum(s.frames for s in done)


def rig_colors(path: Path) -> list[str]:
    """A digest of each decoded color image of a rig recording, camera by camera, each as
    ``camera:digest``, so that segments' lists joined give each camera's frames in order."""
    from ..recording import open as open_recording

    out: list[str] = []
    with open_recording(path) as rec:
        for name in rec.camera_names:
            out += [f"{name}:{digest(f.color)}" for f in rec.frames(camera=name)]
    return out


def count_frames(path: Path) -> int:
    """Frames of every camera of the recording at ``path``."""
    from ..recording import open as open_recording

    with open_recording(path) as rec:
        return sum(len(rec.frames(camera=name)) for name in rec.camera_names)


def verify_rig(
    src: str, options: dict[str, Any], output: str, colors: list[str] | None
) -> dict[str, Any]:
    """Decode every camera of ``output`` and compare it with that camera of ``src`` read
    again; raise :class:`~pcdcodec.VerificationError` on any difference."""
    from ..recording import open as open_recording
    from ..sources.rig import close_inputs

    name = Path(output).name
    cams, _ = _open(src, options)
    total = 0
    try:
        with open_recording(output) as rec:
            names = list(getattr(rec, "camera_names", []))
            if names != [c.name for c in cams]:
                raise VerificationError(
                    f"{name}: cameras {names}, the source's {[c.name for c in cams]}"
                )
            for cam in cams:
                frames = rec.frames(camera=cam.name)
                if not frames.indexed:
                    raise VerificationError(f"{name}: camera {cam.name} has no index")
                bound = depth_bound(frames.codecs.get("depth") or {})
                mine = None
                if colors is not None:
                    prefix = cam.name + ":"
                    mine = [c[len(prefix) :] for c in colors if c.startswith(prefix)]
                decoded: Iterator[Any] = iter(frames)
                where = f"{name}, camera {cam.name}"
                total += check_frames(where, decoded, cam.source, bound, mine)
    finally:
        close_inputs(cams)
    return {"frames": total}
