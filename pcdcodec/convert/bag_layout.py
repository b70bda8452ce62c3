"""Where a camera's messages go in a bag the export writes: the frames they are in (their
``frame_id``), the static transforms of a color camera apart from its depth camera and of a
rig's cameras, a rig's frames in time order, and the finished bag moved into place.
"""

from __future__ import annotations

import heapq
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..recording.rig_reader import RigRecording

__all__ = [
    "COLOR_FRAME",
    "DEPTH_FRAME",
    "color_transform",
    "frame_ids",
    "in_time_order",
    "rig_transforms",
    "swap_in",
]

#: A camera's frames, by the names realsense-ros gives them, where none is given.
DEPTH_FRAME, COLOR_FRAME = "camera_depth_optical_frame", "camera_color_optical_frame"


def frame_ids(frame_id: str | None, *, apart: bool) -> tuple[str, str]:
    """The ``frame_id`` of a camera's depth and color messages: both ``frame_id`` where color is
    registered to depth; else the depth's ``frame_id`` and the color's ``<frame_id>_color``,
    and without ``frame_id`` realsense-ros's names (:data:`DEPTH_FRAME`,
    :data:`COLOR_FRAME`; the one frame of registered color is :data:`COLOR_FRAME`)."""
    if not apart:
        fid = frame_id or COLOR_FRAME
        return fid, fid
    if frame_id:
        return frame_id, f"{frame_id}_color"
    return DEPTH_FRAME, COLOR_FRAME


def color_transform(frame_id: str, color_frame: str, depth_to_color: Any) -> tuple[str, str, Any]:
    """The ``/tf_static`` edge ``(parent, child, child-to-parent pose)`` placing the frame of a
    color camera apart from its depth camera in the depth camera's frame: the inverse of
    ``depth_to_color``."""
    return frame_id, color_frame, np.linalg.inv(np.asarray(depth_to_color, np.float64))


def in_time_order(rig: RigRecording) -> Iterator[tuple[int, str, Any]]:
    """``(timestamp, camera, frame)`` of every camera's frames, merged in time order (ties in
    the rig's camera order); one decoded frame per camera is held at a time."""

    def stamped(k: int, name: str) -> Iterator[tuple[int, int, str, Any]]:
        for frame in rig.frames(name):
            yield int(frame.timestamp_ns), k, name, frame

    streams = [stamped(k, name) for k, name in enumerate(rig.camera_names)]
    for ts, _, name, frame in heapq.merge(*streams, key=lambda e: (e[0], e[1])):
        yield ts, name, frame


def rig_transforms(rig: RigRecording) -> list[tuple[str, str, Any]]:
    """The static transforms of a rig, as ``(parent, child, child-to-parent pose)``: each
    camera frame in the rig frame, and each color camera apart from its depth camera
    (``<frame_id>_color``) in its camera frame."""
    edges: list[tuple[str, str, Any]] = []
    for cam in rig.cameras.values():
        edges.append((rig.rig_frame_id, cam.frame_id, cam.rig_pose))
        if cam.color_intrinsics is not None and cam.depth_to_color is not None:
            fid, color_fid = frame_ids(cam.frame_id, apart=True)
            edges.append(color_transform(fid, color_fid, cam.depth_to_color))
    return edges


def swap_in(staging: Path, target: Path) -> None:
    """Move the bag written as ``staging/NAME`` onto ``target``, replacing a bag there (a file
    or a folder)."""
    tmp_out = staging / target.name
    if target.exists():
        trash = target.parent / f".{target.name}.old-{os.getpid()}"
        os.replace(target, trash)
        os.replace(tmp_out, target)
        if trash.is_dir():
            shutil.rmtree(trash)
        else:
            trash.unlink()
    else:
        os.replace(tmp_out, target)
