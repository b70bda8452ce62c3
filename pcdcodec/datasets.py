"""RGB-D sequences held in memory, the bundled sample, and folders read whole or written.

:class:`RGBDSequence` holds frames with their camera; :func:`load_sample` gives the bundled
sample, :func:`load_folder` reads a folder into a sequence and :func:`write_folder` writes frames
as a TUM RGB-D folder that it reads back (:func:`write_rig_folder`: one per camera of a rig).
The folder reader itself (its layouts, ``camera.json``, :func:`open_folder` and
:class:`FolderSource`) is :mod:`pcdcodec.sources.folder`; its names still import from here, and
load on first use so that ``import pcdcodec`` does not load the reader.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .errors import InputError
from .frame import Frame

if TYPE_CHECKING:
    from .geometry.camera import CameraIntrinsics
    from .sources.folder import CAMERA_JSON_KEYS as CAMERA_JSON_KEYS
    from .sources.folder import DEPTH_SUFFIXES as DEPTH_SUFFIXES
    from .sources.folder import FLAT_DEPTH as FLAT_DEPTH
    from .sources.folder import IMAGE_SUFFIXES as IMAGE_SUFFIXES
    from .sources.folder import TUM_DEPTH_SCALE as TUM_DEPTH_SCALE
    from .sources.folder import FolderSource, open_folder, read_camera_json
    from .sources.folder import Pair as Pair

__all__ = [
    "FolderSource",
    "RGBDFrame",
    "RGBDSequence",
    "load_folder",
    "load_sample",
    "open_folder",
    "read_camera_json",
    "sample_dir",
    "write_folder",
    "write_kept_images",
    "write_rig_folder",
]

#: Names of the folder reader (:mod:`pcdcodec.sources.folder`) that import from here too.
_FOLDER_NAMES = frozenset(
    {
        "CAMERA_JSON_KEYS",
        "DEPTH_SUFFIXES",
        "FLAT_DEPTH",
        "IMAGE_SUFFIXES",
        "TUM_DEPTH_SCALE",
        "FolderSource",
        "Pair",
        "open_folder",
        "read_camera_json",
    }
)


def __getattr__(name: str) -> Any:
    """The folder reader's names, loaded on first use."""
    if name in _FOLDER_NAMES:
        from .sources import folder

        value = getattr(folder, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_FOLDER_NAMES})


#: The frame type of sources, recordings and evaluation (see :class:`pcdcodec.Frame`);
#: ``RGBDFrame(color=..., depth=..., timestamp_ns=...)``.
RGBDFrame = Frame


@dataclass(repr=False)
class RGBDSequence:
    """Frames in time order, with the camera that took them."""

    frames: list[RGBDFrame]
    intrinsics: CameraIntrinsics | None = None
    depth_scale: float = 1000.0
    name: str = ""
    #: (color file or None for depth only, depth file) per frame
    paths: list[tuple[Path | None, Path]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[RGBDFrame]:
        return iter(self.frames)

    def __getitem__(self, index: int) -> RGBDFrame:
        return self.frames[index]

    @property
    def depths(self) -> list[npt.NDArray[Any]]:
        return [f.depth for f in self.frames]

    @property
    def colors(self) -> list[npt.NDArray[np.uint8]]:
        return [f.color for f in self.frames if f.color is not None]

    def __repr__(self) -> str:
        size = ""
        if self.frames:
            h, w = self.frames[0].depth.shape[:2]
            size = f", {w}x{h} {self.frames[0].depth.dtype}"
        name = f" {self.name!r}" if self.name else ""
        span = ""
        if len(self.frames) > 1:
            span = f", {(self.frames[-1].timestamp_ns - self.frames[0].timestamp_ns) / 1e9:.2f} s"
        return (
            f"<pcdcodec.RGBDSequence{name}: {len(self.frames)} frames{size}{span}, "
            f"depth_scale={self.depth_scale:g}, intrinsics={self.intrinsics!r}>"
        )


def sample_dir() -> Path:
    """The folder of the bundled sample: 15 frames of TUM RGB-D ``freiburg1_rpy`` (CC BY 4.0)."""
    return Path(__file__).resolve().parent / "data" / "tum_fr1_rpy"


def load_sample(max_frames: int | None = None) -> RGBDSequence:
    """Load the bundled sample (640×480, depth scale 5000 per metre, fx = fy = 525)."""
    return load_folder(sample_dir(), max_frames=max_frames)


def load_folder(
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_scale: float | None = None,
    layout: str = "auto",
    fps: float = 30.0,
    max_dt: float = 0.02,
    color_intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_to_color: Any = None,
    depth_pattern: str | None = None,
    color_pattern: str | None = None,
    color: bool = True,
) -> RGBDSequence:
    """Load an RGB-D sequence from a folder (see :mod:`pcdcodec.sources.folder` for the layouts).

    ``layout`` is ``"auto"``, ``"tum"``, ``"folders"`` or ``"flat"``; ``depth_pattern`` and
    ``color_pattern`` (glob patterns relative to the folder) pick the files instead, paired by
    the text their wildcards match (no ``color_pattern``: depth only). ``max_dt`` is the
    largest color/depth time difference in seconds accepted when pairing TUM lists without
    ``associations.txt``. Intrinsics and depth scale default to the folder's ``camera.json``
    (:func:`read_camera_json`); without a depth scale there, a TUM RGB-D or 7-Scenes dataset
    folder gets its dataset's and any other folder raises :class:`~pcdcodec.InputError` asking
    for ``depth_scale``. ``intrinsics`` may also be an intrinsics file
    (:func:`~pcdcodec.geometry.camera.read_intrinsics`), and without either, a file the folder ships
    with (``intrinsics.K.txt``, ``camera-intrinsics.txt``, a CameraInfo YAML, an Open3D
    intrinsic JSON) is read. ``color_intrinsics`` (a camera or a file) and ``depth_to_color``
    (a 4 × 4 rigid transform in metres, or a text file of its 16 numbers; default identity)
    describe a color camera apart from the depth camera, for color images of another size
    than the depth images; ``color=False`` reads depth only. Folders without time lists are
    timed from the times in their file names, else at ``fps`` from the frame numbers in
    their names, so dropped frames keep their gap; the source's ``metadata["timestamps"]``
    says how the times were made. Raises :class:`~pcdcodec.InputError` for a missing
    folder, an unknown layout, an empty sequence, an unknown depth scale, unreadable images
    or frames of different sizes.
    """
    from .sources.folder import open_folder

    source = open_folder(
        path,
        max_frames=max_frames,
        intrinsics=intrinsics,
        depth_scale=depth_scale,
        layout=layout,
        fps=fps,
        max_dt=max_dt,
        color_intrinsics=color_intrinsics,
        depth_to_color=depth_to_color,
        depth_pattern=depth_pattern,
        color_pattern=color_pattern,
        color=color,
    )
    return RGBDSequence(
        list(source),
        intrinsics=source.intrinsics,
        depth_scale=source.depth_scale,
        name=source.root.name,
        paths=[(c, d) for _, c, d in source.pairs],
    )


def write_folder(
    frames: Any,
    path: str | os.PathLike[str],
    *,
    intrinsics: CameraIntrinsics | None = None,
    depth_scale: float = 1000.0,
    clouds: tuple[str, ...] = (),
    overwrite: bool = False,
    progress: Any = None,
    color_intrinsics: CameraIntrinsics | None = None,
    depth_to_color: Any = None,
    pose_layout: str | None = None,
) -> int:
    """Write frames as a TUM RGB-D folder that :func:`load_folder` reads back.

    ``rgb/NNNNNN.png`` (8-bit RGB), ``depth/NNNNNN.png`` (16-bit depth units; float32 depth as
    ``.tiff`` metres), ``rgb.txt`` and ``depth.txt`` with each image's own time in seconds
    (``frame.color_timestamp_ns`` and ``frame.depth_timestamp_ns``, as TUM writes times), and
    ``associations.txt`` pairing them as the frames do (no ``rgb/``, ``rgb.txt`` and
    ``associations.txt`` when no frame has color: a depth-only folder), and ``camera.json``
    (intrinsics and depth scale) when ``intrinsics`` is given, with the color camera of color
    not registered to depth (``color_intrinsics``, and ``depth_to_color``, the 4 × 4
    transform in metres) as ``color`` and ``depth_to_color``.

    Frames with a pose have it written in ``pose_layout`` (see
    :data:`pcdcodec.sources.poses.POSE_LAYOUTS`; default ``"tum"``): ``"tum"`` writes
    ``groundtruth.txt``, a line ``timestamp tx ty tz qx qy qz qw`` per pose at its frame's
    depth time; ``"7scenes"`` names the files as 7-Scenes does (``rgb/frame-NNNNNN.color.png``,
    ``depth/frame-NNNNNN.depth.png``) and writes ``pose/frame-NNNNNN.pose.txt``, the 4 × 4
    matrix. Either reads back as the same poses.

    ``clouds`` names point-cloud formats to write per frame into ``clouds/`` (``"ply"``,
    ``"pcd"``: binary, with the cloud's float32 points and 8-bit colors; the frames need a
    projector, as frames of a recording have). The folder is written beside its target and
    moved into place when complete; an existing non-empty folder needs ``overwrite``.
    ``progress`` is called with the number of frames written. Returns that number.
    """
    import imagecodecs

    from ._atomic import atomic_output  # not loaded by `import pcdcodec`
    from .sources.folder import as_transform
    from .sources.poses import DEFAULT_POSE_LAYOUT, POSE_LAYOUTS, seconds_text

    out = Path(path)
    if hasattr(frames, "rig_frame_id"):  # a RigRecording: its frames are per camera
        raise InputError(
            "write_folder writes one camera's frames; for a recording of several cameras use "
            "write_rig_folder (a folder per camera) or pass rec.frames(camera)"
        )
    for fmt_name in clouds:
        if fmt_name not in ("ply", "pcd"):
            raise InputError(f"point cloud format must be 'ply' or 'pcd', got {fmt_name!r}")
    layout = DEFAULT_POSE_LAYOUT if pose_layout is None else pose_layout
    if layout not in POSE_LAYOUTS:
        raise InputError(
            f"pose_layout must be one of {', '.join(map(repr, POSE_LAYOUTS))}, got {layout!r}"
        )
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(f"{str(out)!r} is not empty; pass overwrite=True to write into it")
    out.parent.mkdir(parents=True, exist_ok=True)
    # 7-Scenes names its files frame-NNNNNN.<kind>.<ext>, the pose file's name from them.
    seven = layout == "7scenes"
    with atomic_output(out, place=_place_folder) as tmp:
        (tmp / "rgb").mkdir(parents=True)
        (tmp / "depth").mkdir()
        if clouds:
            (tmp / "clouds").mkdir()
        rgb_list = ["# color images", "# timestamp filename"]
        depth_list = ["# depth maps", "# timestamp filename"]
        pairs = ["# color timestamp, file, depth timestamp, file"]
        poses: list[tuple[str, int, Any]] = []
        count = 0
        for i, frame in enumerate(frames):
            name = f"frame-{i:06d}" if seven else f"{i:06d}"
            rgb_file = f"rgb/{name}.color.png" if seven else f"rgb/{name}.png"
            depth_stamp = seconds_text(frame.depth_timestamp_ns)
            if frame.color is not None:
                (tmp / rgb_file).write_bytes(imagecodecs.png_encode(frame.color))
                rgb_list.append(f"{seconds_text(frame.color_timestamp_ns)} {rgb_file}")
            depth_file = f"depth/{name}.depth" if seven else f"depth/{name}"
            if frame.depth.dtype == np.uint16:
                depth_file += ".png"
                data = imagecodecs.png_encode(frame.depth)
            else:
                depth_file += ".tiff"
                data = imagecodecs.tiff_encode(frame.depth)
            (tmp / depth_file).write_bytes(data)
            depth_list.append(f"{depth_stamp} {depth_file}")
            if frame.color is not None:
                pairs.append(f"{rgb_list[-1]} {depth_list[-1]}")
            if frame.pose is not None:
                poses.append((name, int(frame.depth_timestamp_ns), frame.pose))
            if clouds:
                _write_clouds(frame, tmp / "clouds" / f"{i:06d}", clouds)
            count = i + 1
            if progress is not None:
                progress(count)
        if len(rgb_list) > 2:
            (tmp / "rgb.txt").write_text("\n".join(rgb_list) + "\n")
            (tmp / "associations.txt").write_text("\n".join(pairs) + "\n")
        else:  # no color: depth.txt alone reads back as a depth-only folder
            (tmp / "rgb").rmdir()
        (tmp / "depth.txt").write_text("\n".join(depth_list) + "\n")
        if poses:
            _write_poses(tmp, layout, poses)
        if intrinsics is not None:
            camera: dict[str, Any] = {**intrinsics.to_dict(), "depth_scale": depth_scale}
            if color_intrinsics is not None:
                camera["color"] = color_intrinsics.to_dict()
                if depth_to_color is not None:
                    camera["depth_to_color"] = as_transform(
                        depth_to_color, "depth_to_color"
                    ).tolist()
            (tmp / "camera.json").write_text(json.dumps(camera, indent=2) + "\n")
    return count


def write_kept_images(rec: Any, path: str | os.PathLike[str]) -> dict[str, int]:
    """Write the images a recording keeps beside its frames (its kept topics of encoded depth
    frames, message encoding ``pcdcodec.depth``: an Azure Kinect's IR on ``/k4a/ir``) under the
    folder ``path``, bit-exact: each topic's images as 16-bit PNG files named by topic
    (``/k4a/ir`` -> ``k4a/ir/000000.png``, ...) and ``k4a/ir.txt`` listing each image's log
    time in seconds and its file, as TUM lists images. Written beside and moved into place
    when complete (the folder may hold a decoded recording already; files of the same name
    are replaced). Returns the images written per topic; nothing is written without such
    topics. Raises :class:`~pcdcodec.DecodeError` when an image does not decode."""
    import imagecodecs

    from ._atomic import atomic_output
    from .ros.kept import IMAGE_ENCODING
    from .sources.poses import seconds_text

    topics = [t.topic for t in rec.kept_topics if t.message_encoding == IMAGE_ENCODING]
    if not topics:
        return {}
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    out.parent.mkdir(parents=True, exist_ok=True)
    counts: dict[str, int] = {}
    with atomic_output(out, place=_place_folder) as tmp:
        tmp.mkdir()
        for topic in dict.fromkeys(topics):
            # The topic's names as folders: only plain names (a topic is the file's word).
            parts = [re.sub(r"[^A-Za-z0-9_.-]", "_", p) for p in topic.split("/") if p]
            parts = [p if p.strip(".") else "_" for p in parts] or ["kept"]
            folder = tmp.joinpath(*parts)
            folder.mkdir(parents=True, exist_ok=True)
            lines = [f"# {topic} images", "# timestamp filename"]
            for i, (log_time, image) in enumerate(rec.kept_images(topic)):
                name = "/".join([*parts, f"{i:06d}.png"])
                (tmp / name).write_bytes(imagecodecs.png_encode(image))
                lines.append(f"{seconds_text(log_time)} {name}")
            folder.with_name(parts[-1] + ".txt").write_text("\n".join(lines) + "\n")
            counts[topic] = len(lines) - 2
    return counts


def _write_poses(folder: Path, layout: str, poses: list[tuple[str, int, Any]]) -> None:
    """The frames' ``(name, depth time, pose)`` written in ``layout``: TUM's
    ``groundtruth.txt`` or 7-Scenes' ``pose/<name>.pose.txt``."""
    from .sources.poses import write_pose_file, write_tum_trajectory

    if layout == "7scenes":
        (folder / "pose").mkdir()
        for name, _, pose in poses:
            write_pose_file(folder / "pose" / f"{name}.pose.txt", pose)
    else:
        write_tum_trajectory(
            folder / "groundtruth.txt", [t for _, t, _ in poses], [p for _, _, p in poses]
        )


def _write_clouds(frame: Any, stem: Path, formats: tuple[str, ...]) -> None:
    """The frame's point cloud as ``stem.ply`` (float32 points, :func:`write_ply`) and/or
    ``stem.pcd`` (Open3D's writer, which stores float32 points too)."""
    from .geometry.ply import write_ply

    points, colors = frame.to_points()
    if "ply" in formats:
        write_ply(stem.with_suffix(".ply"), points, colors)
    if "pcd" in formats:
        import open3d as o3d

        o3d.io.write_point_cloud(stem.with_suffix(".pcd"), frame.to_point_cloud())


def write_rig_folder(
    rig: Any,
    path: str | os.PathLike[str],
    *,
    clouds: tuple[str, ...] = (),
    overwrite: bool = False,
    progress: Any = None,
) -> dict[str, int]:
    """Write each camera of a recording of several cameras (:class:`~pcdcodec.RigRecording`)
    as :func:`write_folder` writes one, into ``path/<name>/`` (with its ``camera.json``), and
    ``path/rig.json``: the rig frame and, per camera, its folder, frame id, frames and rig
    pose (the 4 × 4 transform from the camera's depth frame to the rig frame, metres).

    ``progress`` is called with the number of frames written, all cameras. An existing
    non-empty ``path`` needs ``overwrite``. Returns the frames written per camera.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(f"{str(out)!r} is not empty; pass overwrite=True to write into it")
    counts: dict[str, int] = {}
    for name, cam in rig.cameras.items():
        done = sum(counts.values())
        counts[name] = write_folder(
            rig.frames(name),
            out / name,
            intrinsics=cam.intrinsics,
            depth_scale=cam.depth_scale,
            color_intrinsics=cam.color_intrinsics,
            depth_to_color=cam.depth_to_color,
            clouds=clouds,
            overwrite=overwrite,
            progress=None if progress is None else (lambda n, done=done: progress(done + n)),
        )
    layout = {
        "rig_frame_id": rig.rig_frame_id,
        "cameras": [
            {
                "name": name,
                "folder": name,
                "frame_id": cam.frame_id,
                "frames": counts[name],
                "rig_pose": np.asarray(cam.rig_pose, np.float64).tolist(),
            }
            for name, cam in rig.cameras.items()
        ],
    }
    (out / "rig.json").write_text(json.dumps(layout, indent=2) + "\n")
    return counts


def _place_folder(tmp: Path, out: Path) -> None:
    """Put the folder written at ``tmp`` in place as ``out``: moved there when ``out`` is absent
    or empty; otherwise (overwrite) the files written replace theirs and others are left."""
    if not out.exists():
        os.replace(tmp, out)
    elif not any(out.iterdir()):
        out.rmdir()
        os.replace(tmp, out)
    else:
        for item in sorted(tmp.rglob("*")):
            target = out / item.relative_to(tmp)
            if item.is_dir():
                target.mkdir(exist_ok=True)
            else:
                os.replace(item, target)
