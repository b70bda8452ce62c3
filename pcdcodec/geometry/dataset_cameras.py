"""Cameras as RGB-D datasets publish them: the intrinsics files they ship, and the published
values of well-known dataset cameras.

An intrinsics file is read by its content, not its name: a 3 × 3 camera matrix ``K`` as text
(``intrinsics.K.txt``, ``camera-intrinsics.txt``), a ROS ``camera_calibration`` YAML
(``image_width``, ``camera_matrix``, ...), a ``sensor_msgs/CameraInfo`` dump (``K``), an Open3D
``PinholeCameraIntrinsic`` JSON (``intrinsic_matrix``, column-major) or pcdcodec's
``camera.json`` (``fx``, ``fy``, ``cx``, ``cy``).

This module holds plain data, not the camera model: :func:`describe_intrinsics_file` says which
:class:`~pcdcodec.CameraIntrinsics` constructor builds the camera a file holds, and with what,
and :data:`PUBLISHED_CAMERAS` lists the presets' numbers. :mod:`pcdcodec.geometry.camera` builds
the cameras (:func:`~pcdcodec.geometry.camera.read_intrinsics`,
:data:`~pcdcodec.geometry.camera.CAMERA_PRESETS`) and loads this module on first use, so that
``import pcdcodec`` does not.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..errors import InputError

__all__ = [
    "INTRINSICS_FILE_NAMES",
    "PUBLISHED_CAMERAS",
    "describe_intrinsics_file",
    "find_intrinsics_file",
]

#: The presets (``--camera NAME``): name, ``(fx, fy, cx, cy)`` of a 640 × 480 image, the depth
#: scale the dataset fixes (depth units per metre) and where the values come from.
PUBLISHED_CAMERAS: tuple[tuple[str, tuple[float, float, float, float], float, str], ...] = (
    (
        "tum-fr1",
        (517.3, 516.5, 318.6, 255.3),
        5000.0,
        "TUM RGB-D, freiburg1 color camera (distortion not modelled)",
    ),
    (
        "tum-fr2",
        (520.9, 521.0, 325.1, 249.7),
        5000.0,
        "TUM RGB-D, freiburg2 color camera (distortion not modelled)",
    ),
    (
        "tum-fr3",
        (535.4, 539.2, 320.1, 247.6),
        5000.0,
        "TUM RGB-D, freiburg3 color camera (undistorted images)",
    ),
    (
        "tum-ros",
        (525.0, 525.0, 319.5, 239.5),
        5000.0,
        "TUM RGB-D, the ROS defaults TUM recommends for its registered depth",
    ),
    (
        "kinect-v1",
        (525.0, 525.0, 319.5, 239.5),
        1000.0,
        "Microsoft Kinect v1 / PrimeSense, OpenNI and Open3D defaults (millimetres)",
    ),
    (
        "7scenes",
        (585.0, 585.0, 320.0, 240.0),
        1000.0,
        "Microsoft 7-Scenes (Kinect v1), the dataset's published approximation",
    ),
)

#: File names looked for in RGB-D folders, in this order.
INTRINSICS_FILE_NAMES = (
    "camera.json",
    "intrinsics.K.txt",
    "camera-intrinsics.txt",
    "intrinsics.txt",
    "K.txt",
    "camera_info.yaml",
    "camera_info.yml",
    "camera.yaml",
    "intrinsic.json",
    "camera_intrinsic.json",
)

#: The keys of :meth:`CameraIntrinsics.from_dict` that a ``camera.json`` gives or the size fills.
_DICT_KEYS = ("width", "height", "fx", "fy", "cx", "cy")

#: A :class:`~pcdcodec.CameraIntrinsics` class method and the arguments it is called with.
Recipe = tuple[Literal["from_K", "from_camera_info", "from_dict"], tuple[Any, ...]]


def _names_a_camera(path: Path) -> bool:
    """Whether a ``camera.json`` gives a camera; one holding only ``depth_scale`` does not."""
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return True  # let read_intrinsics say what is wrong with it
    return not isinstance(data, dict) or bool({"fx", "fy", "cx", "cy"} & set(data))


def find_intrinsics_file(folder: str | os.PathLike[str]) -> Path | None:
    """The first intrinsics file of :data:`INTRINSICS_FILE_NAMES` in ``folder``, or ``None``.

    A ``camera.json`` that gives no camera (only a ``depth_scale``) is passed over for the
    next file."""
    root = Path(folder)
    for name in INTRINSICS_FILE_NAMES:
        p = root / name
        if p.is_file() and (name != "camera.json" or _names_a_camera(p)):
            return p
    return None


def _k_text(path: Path, width: int | None, height: int | None) -> Recipe:
    try:
        values = [float(v) for v in path.read_text().replace(",", " ").split()]
    except ValueError:
        raise InputError(f"{str(path)!r} is not a 3x3 camera matrix of numbers") from None
    if len(values) != 9:
        raise InputError(
            f"{str(path)!r} holds {len(values)} numbers; a camera matrix K has 9 (3 rows of 3)"
        )
    if width is None or height is None:
        raise InputError(
            f"{str(path)!r} is a camera matrix without the image size; give width and height"
        )
    return "from_K", (np.reshape(values, (3, 3)), width, height)


def _yaml(path: Path) -> Any:
    try:
        import yaml
    except ImportError:
        raise InputError(f"reading {str(path)!r} needs PyYAML: pip install pyyaml") from None
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise InputError(f"{str(path)!r} is not valid YAML: {exc}") from None


def _from_mapping(data: Any, path: Path, width: int | None, height: int | None) -> Recipe:
    if not isinstance(data, Mapping):
        raise InputError(f"{str(path)!r} holds no camera description (expected a mapping)")
    if "camera_matrix" in data:  # ROS camera_calibration_parsers YAML
        matrix = data["camera_matrix"]
        k = matrix.get("data") if isinstance(matrix, Mapping) else matrix
        info = {
            "width": data.get("image_width", width),
            "height": data.get("image_height", height),
            "K": k,
            "D": (data.get("distortion_coefficients") or {}).get("data"),
            "distortion_model": data.get("distortion_model") or "plumb_bob",
        }
        return "from_camera_info", (info,)
    if "intrinsic_matrix" in data:  # Open3D PinholeCameraIntrinsic JSON, column-major
        m = np.asarray(data["intrinsic_matrix"], dtype=np.float64)
        if m.size != 9:
            raise InputError(f"{str(path)!r}: intrinsic_matrix must have 9 numbers")
        return "from_K", (m.reshape(3, 3).T, data.get("width", width), data.get("height", height))
    if any(k in data for k in ("K", "k")):  # a sensor_msgs/CameraInfo dump
        return "from_camera_info", ({"width": width, "height": height, **dict(data)},)
    if {"fx", "fy", "cx", "cy"} <= set(data):  # pcdcodec's camera.json
        size = {"width": width, "height": height}
        return "from_dict", ({k: data.get(k, size.get(k)) for k in _DICT_KEYS},)
    raise InputError(
        f"{str(path)!r} is not an intrinsics file pcdcodec reads: expected a ROS CameraInfo "
        "YAML (camera_matrix), an Open3D intrinsic JSON (intrinsic_matrix), a CameraInfo dump "
        "(K) or fx/fy/cx/cy keys"
    )


def describe_intrinsics_file(
    path: str | os.PathLike[str], width: int | None = None, height: int | None = None
) -> Recipe:
    """How to build the camera an intrinsics file holds: ``(method, arguments)``, the
    :class:`~pcdcodec.CameraIntrinsics` class method (``"from_K"``, ``"from_camera_info"`` or
    ``"from_dict"``) and what to call it with.

    ``width`` and ``height`` fill in a size the file does not give. Raises
    :class:`~pcdcodec.InputError` for a missing or unreadable file, naming it and what was
    expected; the values themselves are checked by the constructor.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"intrinsics file {str(p)!r} does not exist")
    text = p.read_text(errors="replace").lstrip()
    if text.startswith("{"):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"{str(p)!r} is not valid JSON: {exc}") from None
        return _from_mapping(data, p, width, height)
    first = text.split(None, 1)[0] if text else ""
    try:
        float(first.rstrip(","))
    except ValueError:
        return _from_mapping(_yaml(p), p, width, height)
    return _k_text(p, width, height)
