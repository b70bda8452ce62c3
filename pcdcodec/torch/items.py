"""What one item of a dataset holds: the fields a training loop asks for, built from a frame.

:data:`FIELDS` names every field and what it gives. An item is a ``dict`` of the fields asked
for, in their order; :func:`build_item` makes it from a decoded frame (or, when no field needs
color, from the frame's depth alone, so that color is never decoded).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, InputTypeError
from ..geometry.projector import Projector

__all__ = ["COLOR_FIELDS", "DEFAULT_FIELDS", "FIELDS", "Decoded", "build_item", "check_fields"]

#: Every field an item can hold, and what it is.
FIELDS: dict[str, str] = {
    "color": "H × W × 3 uint8 RGB (the color camera's size)",
    "depth": "H × W depth as stored: uint16 depth units (or float32 metres, if so recorded)",
    "depth_metres": "H × W float32 metres, 0 where there is no depth",
    "points": "N × 3 float32 points in metres (camera frame) of the pixels with depth",
    "point_colors": "N × 3 uint8 RGB of those points",
    "organized": "H × W × 3 float32 organized cloud in metres, NaN where there is no depth",
    "intrinsics": "3 × 3 float64 camera matrix K of the depth camera",
    "pose": "4 × 4 float64 camera-to-world pose, NaN where the frame has none",
    "rig_pose": "4 × 4 float64 camera-to-rig transform (the identity for a one-camera file)",
    "timestamp": "int, nanoseconds",
    "camera": "str, the camera's name",
    "source": "str, the recording's path",
    "index": "int, the frame's index among its camera's frames in its recording",
}

#: The fields an item holds unless told otherwise.
DEFAULT_FIELDS = ("color", "depth")

#: The fields that need the frame's color decoded.
COLOR_FIELDS = frozenset({"color", "point_colors"})

_NO_POSE = np.full((4, 4), np.nan)
_NO_POSE.flags.writeable = False


def check_fields(fields: Any) -> tuple[str, ...]:
    """``fields`` as a tuple of known field names, in the order given, each once."""
    if isinstance(fields, str):
        fields = (fields,)
    try:
        names = tuple(fields)
    except TypeError:
        raise InputTypeError(
            f"fields must be a field name or a sequence of them, got {type(fields).__name__}"
        ) from None
    if not names:
        raise InputError(f"fields is empty; choose from {sorted(FIELDS)}")
    for name in names:
        if not isinstance(name, str):
            raise InputTypeError(f"each field must be a field name, got {name!r}")
        if name not in FIELDS:
            raise InputError(f"unknown field {name!r}; the fields are {sorted(FIELDS)}")
    if len(set(names)) != len(names):
        raise InputError(f"fields names a field twice: {list(names)}")
    return names


@dataclass
class Decoded:
    """A decoded frame and where it came from: what :func:`build_item` needs."""

    color: npt.NDArray[np.uint8] | None
    depth: npt.NDArray[Any]
    timestamp: int
    pose: npt.NDArray[np.float64] | None
    projector: Projector
    rig_pose: npt.NDArray[np.float64]
    camera: str
    source: str
    index: int


def _metres(depth: npt.NDArray[Any], scale: float) -> npt.NDArray[np.float32]:
    out = depth.astype(np.float32)
    out /= np.float32(scale)
    # float32 depth keeps NaN for "no depth"; training code wants one marker: 0, as uint16 has.
    np.nan_to_num(out, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    return out


def build_item(frame: Decoded, fields: tuple[str, ...]) -> dict[str, Any]:
    """The item of ``frame``: one entry per field, in the order of ``fields``."""
    item: dict[str, Any] = {}
    points: tuple[Any, Any] | None = None
    for name in fields:
        if name == "color":
            item[name] = frame.color
        elif name == "depth":
            item[name] = frame.depth
        elif name == "depth_metres":
            item[name] = _metres(frame.depth, frame.projector.depth_scale)
        elif name in ("points", "point_colors"):
            if points is None:
                color = frame.color if "point_colors" in fields else None
                points = frame.projector.to_points(frame.depth, color)
            item[name] = points[0] if name == "points" else points[1]
        elif name == "organized":
            item[name] = frame.projector.to_organized(frame.depth)
        elif name == "intrinsics":
            item[name] = frame.projector.intrinsics.K
        elif name == "pose":
            item[name] = _NO_POSE.copy() if frame.pose is None else frame.pose
        elif name == "rig_pose":
            item[name] = frame.rig_pose.copy()
        elif name == "timestamp":
            item[name] = frame.timestamp
        elif name == "camera":
            item[name] = frame.camera
        elif name == "source":
            item[name] = frame.source
        else:  # "index"
            item[name] = frame.index
    return item
