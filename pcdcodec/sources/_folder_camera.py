"""What an RGB-D folder says of its camera: its ``camera.json``, and the depth scale of the
datasets whose folders say nothing (TUM RGB-D, 7-Scenes); cameras and transforms given as values
or files.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ._folder_layouts import Pair

if TYPE_CHECKING:
    pass

__all__ = [
    "CAMERA_JSON_KEYS",
    "TUM_DEPTH_SCALE",
    "as_transform",
    "dataset_camera",
    "folder_depth_scale",
    "read_camera_json",
]

#: Depth units per metre of the TUM RGB-D benchmark's 16-bit depth PNGs.
TUM_DEPTH_SCALE = 5000.0


#: Keys a folder's ``camera.json`` may hold.
CAMERA_JSON_KEYS = (
    "width",
    "height",
    "fx",
    "fy",
    "cx",
    "cy",
    "distortion_model",
    "distortion",
    "depth_scale",
    "color",
    "depth_to_color",
)


def read_camera_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What a folder's ``camera.json`` says: any of these, each optional.

    * the depth camera: ``fx``, ``fy``, ``cx``, ``cy`` (all four, pixels), ``width`` and
      ``height`` (default: the depth images' size), ``distortion_model`` and ``distortion``;
    * ``depth_scale``: depth units per metre of uint16 depth;
    * ``color``: the color camera, where color images are not registered to depth (another
      size or lens): a dict with the same keys as the depth camera, ``width`` and ``height``
      required;
    * ``depth_to_color``: the rigid 4 × 4 transform (row-major, metres) from the depth camera
      frame to the color camera frame; default identity.

    A ``camera.json`` holding only ``depth_scale`` beside another intrinsics file is fine: the
    camera then comes from that file. Returns a dict: ``"camera"`` (the depth camera's keys
    given, as a dict; empty when none), ``"depth_scale"`` (float or ``None``), ``"color"`` (as
    given, or ``None``) and ``"depth_to_color"`` (a 4 × 4 float64 array, or ``None``).
    Raises :class:`~pcdcodec.InputError` for a file that is not a JSON object, unknown keys,
    an incomplete camera, a color camera without its size, a depth_to_color that is not 16
    numbers or a bad depth scale, naming the file.
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"cannot read {str(p)!r} as JSON: {exc}") from None
    if not isinstance(data, dict):
        raise InputError(f"{str(p)!r} must hold a JSON object, got {type(data).__name__}")
    unknown = sorted(k for k in data if k not in CAMERA_JSON_KEYS)
    if unknown:
        raise InputError(
            f"{str(p)!r} has unknown key(s) {unknown}; a camera.json may hold "
            f"{', '.join(CAMERA_JSON_KEYS)}"
        )
    pin = [k for k in ("fx", "fy", "cx", "cy") if k in data]
    if pin and len(pin) != 4:
        missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
        raise InputError(f"{str(p)!r} gives {', '.join(pin)} but not {', '.join(missing)}")
    if not pin and any(k in data for k in ("distortion_model", "distortion")):
        raise InputError(f"{str(p)!r} gives a distortion without fx, fy, cx, cy")
    if data.get("depth_to_color") is not None and data.get("color") is None:
        raise InputError(
            f"{str(p)!r} gives depth_to_color without color: the transform needs the color "
            "camera it leads to"
        )
    if data.get("color") is not None and not isinstance(data["color"], dict):
        raise InputError(
            f"{str(p)!r}: color must be a dict of the color camera's keys (width, height, fx, "
            f"fy, cx, cy), got {data['color']!r}"
        )
    color = data.get("color")
    if color is not None:
        unsized = [k for k in ("width", "height") if k not in color]
        if unsized:
            raise InputError(
                f"{str(p)!r}: color gives no {' or '.join(unsized)}; the color camera needs "
                "its image size (width and height, pixels)"
            )
    d2c = data.get("depth_to_color")
    if d2c is not None:
        if isinstance(d2c, str):  # in camera.json the matrix itself, not a file name
            raise InputError(
                f"{str(p)!r}: depth_to_color must be a 4x4 matrix (16 numbers, row-major), "
                f"got {d2c!r}"
            )
        d2c = as_transform(d2c, f"{str(p)!r}: depth_to_color")
    scale = data.get("depth_scale")
    if scale is not None:
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
            raise InputError(
                f"{str(p)!r}: depth_scale must be a positive number of depth units per metre, "
                f"got {scale!r}"
            )
        scale = float(scale)
    return {
        "camera": {k: data[k] for k in data if k not in ("depth_scale", "color", "depth_to_color")},
        "depth_scale": scale,
        "color": color,
        "depth_to_color": d2c,
    }


def as_transform(value: Any, what: str) -> npt.NDArray[np.float64]:
    """A 4 × 4 matrix given as numbers or as a text file of 16 numbers."""
    if isinstance(value, (str, os.PathLike)):
        p = Path(value)
        try:
            value = [float(v) for v in p.read_text().replace(",", " ").split()]
        except (OSError, ValueError) as exc:
            raise InputError(f"{what} {str(p)!r} is not a text file of 16 numbers: {exc}") from None
    try:
        m = np.asarray(value, dtype=np.float64).reshape(4, 4)
    except (TypeError, ValueError):
        raise InputError(
            f"{what} must be a 4x4 matrix (16 numbers, row-major), got {value!r}"
        ) from None
    return m


def _is_tum_dataset(root: Path) -> bool:
    """Whether ``depth.txt`` is one of the TUM RGB-D benchmark's own lists.

    TUM writes ``# file: 'rgbd_dataset_freiburg…bag'`` in its header. Other recordings use the
    same list layout with other units (RealSense millimetres), so the layout alone says nothing.
    """
    try:
        with open(root / "depth.txt", encoding="utf-8", errors="replace") as fh:
            head = [fh.readline() for _ in range(3)]
    except OSError:
        return False
    return any(line.startswith("# file:") and "rgbd_dataset_" in line for line in head)


_SEVEN_SCENES_DEPTH = re.compile(r"frame-\d{6}\.depth\.png\Z")


def _is_seven_scenes(root: Path, pairs: list[Pair]) -> bool:
    """Whether the folder is laid out as Microsoft 7-Scenes ships it (millimetre depth):
    ``frame-NNNNNN.depth.png`` files and ``camera-intrinsics.txt``."""
    return (root / "camera-intrinsics.txt").is_file() and all(
        _SEVEN_SCENES_DEPTH.match(d.name) for _, _, d in pairs
    )


#: The camera of TUM RGB-D folders, whose lists name no camera: TUM's depth is registered to
#: color, and TUM's own tools make clouds with the ROS default camera (the ``tum-ros`` preset).
TUM_CAMERA = "tum-ros"


def dataset_camera(root: Path) -> tuple[Any, str] | None:
    """The camera a dataset's convention gives a folder that ships no intrinsics file (a TUM
    RGB-D folder), and where it came from; ``None`` for other folders."""
    if not _is_tum_dataset(root):
        return None
    from ..geometry.camera import camera_preset

    return (
        camera_preset(TUM_CAMERA).intrinsics,
        f"TUM RGB-D dataset: the ROS default camera TUM's tools use, {TUM_CAMERA}",
    )


def folder_depth_scale(
    root: Path, given: float | None, meta: dict[str, Any], pairs: list[Pair]
) -> tuple[float, str]:
    """The folder's depth scale and where it came from."""
    if given is not None:
        return float(given), "given"
    if meta.get("depth_scale") is not None:
        return float(meta["depth_scale"]), "camera.json"
    if _is_tum_dataset(root):
        return TUM_DEPTH_SCALE, "TUM RGB-D dataset"
    if _is_seven_scenes(root, pairs):
        return 1000.0, "7-Scenes dataset"
    raise InputError(
        f"no depth scale for {str(root)!r}: nothing in the folder says how many depth units make "
        "a metre; pass depth_scale=UNITS_PER_METRE (1000 for millimetres), or put depth_scale "
        "in a camera.json in the folder"
    )
