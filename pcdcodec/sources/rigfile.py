"""Rig files: a small YAML file naming a rig's cameras, where each one's frames come from and
where it sits on the rig (``docs/rig.md``).

::

    frame: base_link            # the rig frame (default: rig)
    cameras:
      - name: head
        source: head.bag        # relative to this file; omitted: the next input given
        namespace: /cam_head    # the camera's namespace in a bag of several cameras
        extrinsic:              # depth optical frame -> rig frame, metres
          translation: [0.1, 0.0, 0.5]
          rotation: [0.0, 0.0, 0.0, 1.0]   # quaternion x y z w
      - name: wrist
        source: wrist/          # an RGB-D folder, a RealSense .bag, ...
        extrinsic: [[1, 0, 0, 0.2], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
        intrinsics: wrist/camera.json   # or {width: ..., height: ..., fx: ..., ...}
        depth_scale: 1000
        color: h264:crf=20      # codecs as encode takes them; color: none for depth only
        depth: depthac
        fps: 15

:func:`read_rig` parses and checks a file (every error names the file, the camera and the
key); :func:`open_rig` opens each camera's source.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, PcdcodecError
from .base import Source, detect_kind, open_source
from .rig import CameraInput, bag_cameras, close_inputs, open_bag_cameras

#: A camera's name: as a rig's file and API take it (recording/rig.py checks it again).
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")

__all__ = ["RigCameraEntry", "RigFile", "open_rig", "read_rig"]

_TOP_KEYS = ("frame", "cameras")
_CAMERA_KEYS = (
    "name",
    "source",
    "namespace",
    "extrinsic",
    "frame_id",
    "intrinsics",
    "depth_scale",
    "color",
    "depth",
    "fps",
    "options",
)
#: Options a camera sets with keys of its own, not through ``options``.
_OWN_KEYS = ("intrinsics", "depth_scale")


@dataclass
class RigCameraEntry:
    """One camera of a rig file, checked: ``source`` resolved against the file's folder
    (``None``: the next input given), ``extrinsic`` as a 4 × 4 matrix (``None``: from the bag's
    ``/tf_static``), ``overrides`` the codecs and rate it replaces, ``source_options`` what the
    source is opened with (``intrinsics``, ``depth_scale``)."""

    name: str
    source: Path | None = None
    namespace: str | None = None
    extrinsic: npt.NDArray[np.float64] | None = None
    frame_id: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    source_options: dict[str, Any] = field(default_factory=dict)


@dataclass
class RigFile:
    """A rig file, checked: its path, the rig frame's name and its cameras."""

    path: Path
    frame: str
    cameras: list[RigCameraEntry]


class _Where:
    """Builds errors naming the file, the camera and the key."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, what: str, camera: str | None = None, key: str | None = None) -> InputError:
        parts = [f"rig file {str(self.path)!r}"]
        if camera is not None:
            parts.append(f"camera {camera}")
        if key is not None:
            parts.append(f"key {key!r}")
        return InputError(", ".join(parts) + ": " + what)


def read_rig(path: str | os.PathLike[str]) -> RigFile:
    """Parse and check the rig file at ``path`` (see the module). Raises
    :class:`~pcdcodec.InputError` naming the file, the camera and the key for anything
    missing, unknown or wrong."""
    import yaml

    rig = Path(path)
    where = _Where(rig)
    try:
        text = rig.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise where.error(f"cannot be read ({exc})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise where.error(f"is not YAML: {' '.join(str(exc).split())}") from None
    if not isinstance(data, Mapping):
        raise where.error(f"expected a mapping with keys {list(_TOP_KEYS)}, got {_kind(data)}")
    unknown = sorted(str(k) for k in data if k not in _TOP_KEYS)
    if unknown:
        raise where.error(f"unknown keys {unknown}; expected {list(_TOP_KEYS)}")
    frame = data.get("frame", "rig")
    if not isinstance(frame, str) or not frame.strip():
        raise where.error(f"expected a frame name, got {frame!r}", key="frame")
    cameras = data.get("cameras")
    if not isinstance(cameras, list) or not cameras:
        raise where.error(
            f"expected a non-empty list of cameras, got {_kind(cameras)}", None, "cameras"
        )
    entries = [_entry(where, k, item) for k, item in enumerate(cameras)]
    names = [e.name for e in entries]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise where.error(f"camera names must differ; given more than once: {twice}", None, "name")
    return RigFile(rig, frame.strip(), entries)


def _kind(value: Any) -> str:
    return "nothing" if value is None else f"{type(value).__name__} {value!r}"[:80]


def _entry(where: _Where, k: int, item: Any) -> RigCameraEntry:
    label = f"#{k + 1}"
    if not isinstance(item, Mapping):
        raise where.error(f"expected a mapping, got {_kind(item)}", label)
    unknown = sorted(str(key) for key in item if key not in _CAMERA_KEYS)
    name = item.get("name")
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise where.error(
            f"expected a name (a letter, then up to 63 letters, digits or '_'), got {_kind(name)}",
            label,
            "name",
        )
    if unknown:
        raise where.error(f"unknown keys {unknown}; expected {list(_CAMERA_KEYS)}", name)
    entry = RigCameraEntry(name)
    folder = where.path.parent
    for key in ("source", "namespace", "frame_id"):
        value = item.get(key)
        if value is not None and (not isinstance(value, str) or not value.strip()):
            raise where.error(f"expected a non-empty string, got {_kind(value)}", name, key)
    if item.get("source") is not None:
        entry.source = folder / Path(os.path.expanduser(item["source"]))
    if item.get("namespace") is not None:
        entry.namespace = "/" + item["namespace"].strip().strip("/")
    entry.frame_id = item.get("frame_id")
    if "extrinsic" in item:
        entry.extrinsic = _extrinsic(where, name, item["extrinsic"])
    if item.get("options") is not None:
        value = item["options"]
        if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
            raise where.error(
                "expected a mapping of the reader's options (layout, depth_topic, color_topic, "
                f"depth_pattern, ...), got {_kind(value)}",
                name,
                "options",
            )
        own = sorted(k for k in value if k in _OWN_KEYS)
        if own:
            raise where.error(f"give {own} as the camera's own keys", name, "options")
        entry.source_options.update(value)
    if item.get("intrinsics") is not None:
        value = item["intrinsics"]
        if isinstance(value, str):
            value = str(folder / Path(os.path.expanduser(value)))
        elif not isinstance(value, Mapping):
            raise where.error(
                f"expected a camera mapping (width, height, fx, fy, cx, cy) or a file, got "
                f"{_kind(value)}",
                name,
                "intrinsics",
            )
        entry.source_options["intrinsics"] = dict(value) if isinstance(value, Mapping) else value
    if item.get("depth_scale") is not None:
        entry.source_options["depth_scale"] = _positive(where, name, "depth_scale", item)
    if "fps" in item:
        entry.overrides["fps"] = _positive(where, name, "fps", item)
    for key in ("color", "depth"):
        if key in item:
            entry.overrides[key] = _codec(where, name, key, item[key])
    return entry


def _finite(value: Any) -> float | None:
    """``value`` as a finite float, or ``None`` (not a number, or none a float holds)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if np.isfinite(number) else None


def _positive(where: _Where, name: str, key: str, item: Mapping[str, Any]) -> float:
    value = item[key]
    number = _finite(value)
    if number is None or number <= 0:
        raise where.error(f"expected a positive number, got {_kind(value)}", name, key)
    return number


def _codec(where: _Where, name: str, key: str, value: Any) -> Any:
    """A codec spec, checked now so that a bad one is named before anything is read."""
    from ..registry import as_codec

    if key == "color" and (value is None or (isinstance(value, str) and value.lower() == "none")):
        return None
    if not isinstance(value, (str, Mapping)):
        raise where.error(
            f"expected a codec name or a config mapping, got {_kind(value)}", name, key
        )
    spec = dict(value) if isinstance(value, Mapping) else value
    try:
        as_codec(spec, key)
    except PcdcodecError as exc:
        raise where.error(str(exc), name, key) from None
    return spec


def _extrinsic(where: _Where, name: str, value: Any) -> npt.NDArray[np.float64]:
    """A 4 × 4 rigid transform from a matrix (4 × 4, or 3 × 4) or a mapping of
    ``translation`` (x y z) and ``rotation`` (quaternion x y z w)."""
    from ..geometry.transform import as_rigid, rigid_from_quaternion

    key = "extrinsic"
    if isinstance(value, Mapping):
        unknown = sorted(str(k) for k in value if k not in ("translation", "rotation"))
        if unknown:
            raise where.error(
                f"unknown keys {unknown}; expected translation and rotation", name, key
            )
        t = _numbers(where, name, f"{key}.translation", value.get("translation"), 3)
        q = _numbers(where, name, f"{key}.rotation", value.get("rotation"), 4)
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-3:
            raise where.error(
                f"expected a unit quaternion x y z w, got {q.tolist()} (norm {norm:.6g})",
                name,
                f"{key}.rotation",
            )
        return rigid_from_quaternion(t, q / norm)
    rows = value if isinstance(value, Sequence) and not isinstance(value, str) else None
    try:
        matrix = np.asarray(rows, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        matrix = np.empty(0)
    if rows is None or matrix.shape not in ((4, 4), (3, 4)):
        raise where.error(
            "expected a 4 x 4 matrix (a list of 4 rows of 4 numbers) or a mapping of "
            f"translation and rotation, got {_kind(value)}",
            name,
            key,
        )
    if matrix.shape == (3, 4):
        matrix = np.vstack([matrix, [0.0, 0.0, 0.0, 1.0]])
    try:
        return as_rigid(matrix, key)
    except PcdcodecError as exc:
        raise where.error(str(exc), name, key) from None


def _numbers(where: _Where, name: str, key: str, value: Any, n: int) -> npt.NDArray[np.float64]:
    ok = isinstance(value, Sequence) and not isinstance(value, str) and len(value) == n
    numbers = [_finite(v) for v in value] if ok else []
    if not ok or any(v is None for v in numbers):
        raise where.error(f"expected {n} finite numbers, got {_kind(value)}", name, key)
    return np.asarray(numbers, dtype=np.float64)


# -- opening the cameras --------------------------------------------------------------------


def _assign(rig: RigFile, inputs: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Each camera's input: its own ``source``, else the next input given that no camera
    names. Every input given must feed a camera."""
    where = _Where(rig.path)
    given = [Path(p) for p in inputs]
    named = {e.source.resolve() for e in rig.cameras if e.source is not None}
    free = [p for p in given if p.resolve() not in named]
    out: list[Path] = []
    for entry in rig.cameras:
        if entry.source is not None:
            out.append(entry.source)
        elif free:
            out.append(free.pop(0))
        else:
            raise where.error(
                "no source: give one in the file, or one more input on the command line",
                entry.name,
                "source",
            )
    if free:
        raise InputError(
            f"inputs {[str(p) for p in free]} feed no camera of rig file {str(rig.path)!r} "
            "(each camera takes its source, or the next input no camera names)"
        )
    return out


def open_rig(
    rig: RigFile | str | os.PathLike[str],
    inputs: Sequence[str | os.PathLike[str]] = (),
    **options: Any,
) -> list[CameraInput]:
    """Open the source of every camera of ``rig`` (a :class:`RigFile` or its path), with
    ``inputs`` feeding the cameras that name no source; ``options`` go to every source
    (the camera's own ``intrinsics`` and ``depth_scale`` win). A camera in a bag of several
    cameras is its ``namespace``'s; a camera without ``extrinsic`` takes the pose the bag's
    ``/tf_static`` gives its frame, which must hang from the rig's frame.

    Raises :class:`~pcdcodec.InputError` naming the file and the camera for a source that does
    not exist or cannot be read, a bag of several cameras without ``namespace``, and a camera
    that nothing places on the rig."""
    rig = rig if isinstance(rig, RigFile) else read_rig(rig)
    where = _Where(rig.path)
    paths = _assign(rig, inputs)
    found: dict[Path, Any] = {}
    cams: list[CameraInput] = []
    try:
        for entry, path in zip(rig.cameras, paths, strict=True):
            try:
                cam = _open_entry(rig, entry, path, found, options)
            except PcdcodecError as exc:
                if str(rig.path) not in str(exc):
                    exc.args = (str(where.error(str(exc), entry.name)), *exc.args[1:])
                raise
            cams.append(cam)
    except BaseException:
        close_inputs(cams)
        raise
    return cams


def _open_entry(
    rig: RigFile,
    entry: RigCameraEntry,
    path: Path,
    found: dict[Path, Any],
    options: dict[str, Any],
) -> CameraInput:
    where = _Where(rig.path)
    opts = {**options, **entry.source_options}
    if not path.exists():
        raise where.error(f"source {str(path)!r} does not exist", entry.name, "source")
    if detect_kind(path) == "rosbag":
        if path not in found:
            found[path] = bag_cameras(path)
        bag = found[path]
        if entry.namespace is None and len(bag) > 1:
            raise where.error(
                f"bag {str(path)!r} holds cameras in namespaces {bag.namespaces}; say which",
                entry.name,
                "namespace",
            )
        (cam,) = open_bag_cameras(bag, [entry.namespace or bag.namespaces[0]], **opts)
        if entry.extrinsic is None and cam.rig_pose is not None and bag.root != rig.frame:
            cam.source.close()
            raise where.error(
                f"no extrinsic, and /tf_static of {str(path)!r} places the camera in "
                f"{bag.root!r}, not in the rig's frame {rig.frame!r}",
                entry.name,
                "extrinsic",
            )
    else:
        if entry.namespace is not None:
            raise where.error(
                f"{str(path)!r} is not a ROS bag; only bags have namespaces",
                entry.name,
                "namespace",
            )
        source: Source = open_source(path, **opts)
        cam = CameraInput(entry.name, source)
    cam.name = entry.name
    cam.overrides = dict(entry.overrides)
    if entry.frame_id is not None:
        cam.frame_id = entry.frame_id
    if entry.extrinsic is not None:
        cam.rig_pose, cam.pose_from = entry.extrinsic, f"rig file {rig.path.name}"
    elif cam.rig_pose is None:
        cam.source.close()
        raise where.error(
            "no extrinsic, and no /tf_static in the source places the camera",
            entry.name,
            "extrinsic",
        )
    return cam
