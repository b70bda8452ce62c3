"""Reading RGB-D sequences from folders, and the bundled sample.

Two folder layouts are understood:

* **TUM RGB-D**: ``rgb.txt`` and ``depth.txt`` (``timestamp path`` lines, ``#`` comments), and
  optionally ``associations.txt`` (``rgb_ts rgb_path depth_ts depth_path`` lines). Without
  associations, each color frame is paired with the depth frame nearest in time.
* **Plain folders**: ``rgb/`` (or ``color/``) and ``depth/`` holding images that pair up in
  sorted file-name order; timestamps are then the frame index at ``fps``.

Intrinsics and depth scale come from the arguments or, when not given, from a ``camera.json``
in the folder (``width``, ``height``, ``fx``, ``fy``, ``cx``, ``cy``, ``depth_scale``). Without
either, the depth scale of a TUM RGB-D dataset folder (its ``depth.txt`` names the dataset's
``rgbd_dataset_…`` bag) is TUM's 5000 units per metre; for any other folder the scale cannot
be known, and opening it raises :class:`~pcdcodec.InputError` asking for ``depth_scale``.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .errors import InputError
from .frame import Frame
from .sources.base import Source

if TYPE_CHECKING:
    from .camera import CameraIntrinsics

__all__ = [
    "FolderSource",
    "RGBDFrame",
    "RGBDSequence",
    "load_folder",
    "load_sample",
    "open_folder",
    "sample_dir",
    "write_folder",
]

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
#: Depth units per metre of the TUM RGB-D benchmark's 16-bit depth PNGs.
TUM_DEPTH_SCALE = 5000.0
_NS_PER_S = 1_000_000_000


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
    paths: list[tuple[Path, Path]] = field(default_factory=list)

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


def _read_image(path: Path) -> npt.NDArray[Any]:
    import imagecodecs

    try:
        return np.asarray(imagecodecs.imread(str(path)))
    except FileNotFoundError:
        raise InputError(f"image file {str(path)!r} does not exist") from None
    except Exception as exc:
        raise InputError(f"cannot read image {str(path)!r}: {exc}") from exc


def _read_color(path: Path) -> npt.NDArray[np.uint8]:
    img = _read_image(path)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise InputError(
            f"color image {str(path)!r} is {img.dtype} {img.shape}, expected 8-bit RGB"
        )
    return np.ascontiguousarray(img[..., :3])


def _read_depth(path: Path) -> npt.NDArray[Any]:
    img = _read_image(path)
    if img.ndim != 2 or img.dtype not in (np.uint16, np.float32):
        raise InputError(
            f"depth image {str(path)!r} is {img.dtype} {img.shape}, "
            "expected single-channel uint16 or float32"
        )
    return img


def _read_list(path: Path, columns: int) -> list[list[str]]:
    rows = []
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < columns:
            raise InputError(f"{path}:{lineno}: expected {columns} columns, got {line!r}")
        rows.append(parts[:columns])
    return rows


def _seconds_to_ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * _NS_PER_S + int((frac + "000000000")[:9])


def _tum_pairs(root: Path, max_dt_ns: int) -> list[tuple[int, Path, Path]]:
    assoc = root / "associations.txt"
    if assoc.exists():
        return [(_seconds_to_ns(r[0]), root / r[1], root / r[3]) for r in _read_list(assoc, 4)]
    from .sync import associate

    rgb = [(_seconds_to_ns(t), root / p) for t, p in _read_list(root / "rgb.txt", 2)]
    depth = [(_seconds_to_ns(t), root / p) for t, p in _read_list(root / "depth.txt", 2)]
    pairs = associate([t for t, _ in rgb], [t for t, _ in depth], max_difference=max_dt_ns)
    return [(rgb[i][0], rgb[i][1], depth[j][1]) for i, j in pairs]


def _folder_pairs(root: Path, fps: float) -> list[tuple[int, Path, Path]]:
    color_dir = next((root / n for n in ("rgb", "color") if (root / n).is_dir()), None)
    if color_dir is None or not (root / "depth").is_dir():
        raise InputError(
            f"{str(root)!r} is not an RGB-D folder: expected rgb.txt and depth.txt (TUM layout) "
            "or rgb/ and depth/ subfolders"
        )

    def images(d: Path) -> list[Path]:
        return sorted(p for p in d.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)

    colors, depths = images(color_dir), images(root / "depth")
    if len(colors) != len(depths):
        raise InputError(
            f"{str(root)!r} holds {len(colors)} color and {len(depths)} depth images; "
            "plain folders must pair up one to one"
        )
    step = _NS_PER_S / fps
    # Frame numbers in the names (frame-000012.png) keep the gaps of dropped frames.
    numbers = _frame_numbers(colors) or range(len(colors))
    return [
        (round((n - numbers[0]) * step), c, d)
        for n, c, d in zip(numbers, colors, depths, strict=True)
    ]


def _frame_numbers(paths: list[Path]) -> list[int] | None:
    """The last number in each file name, when every name has one and they increase."""
    import re

    numbers = []
    for p in paths:
        found = re.findall(r"\d+", p.stem)
        if not found:
            return None
        numbers.append(int(found[-1]))
    if any(b <= a for a, b in itertools.pairwise(numbers)):
        return None
    return numbers


def _timestamp_note(root: Path, tum: bool, pairs: list[tuple[int, Path, Path]], fps: float) -> str:
    """How a folder's timestamps were made, kept in the recording's metadata."""
    if tum:
        return "recorded (TUM lists)"
    if _frame_numbers([c for _, c, _ in pairs]) is not None:
        return f"not recorded: frame numbers in the file names at {fps:g} fps, from 0"
    return f"not recorded: file order at {fps:g} fps, from 0"


def _folder_camera(
    root: Path,
    intrinsics: Any,
    pairs: list[tuple[int, Path, Path]],
) -> tuple[CameraIntrinsics | None, str]:
    """The intrinsics given (a CameraIntrinsics or a file), or found in the folder
    (:data:`~pcdcodec.camera.INTRINSICS_FILE_NAMES`); and where they came from."""
    from .camera import CameraIntrinsics, find_intrinsics_file, read_intrinsics

    if isinstance(intrinsics, CameraIntrinsics):
        return intrinsics, "given"
    path = Path(intrinsics) if intrinsics is not None else find_intrinsics_file(root)
    if path is None:
        return None, ""
    h, w = _read_depth(pairs[0][2]).shape
    return read_intrinsics(path, w, h), str(path)


@dataclass
class FolderSource(Source):
    """An RGB-D folder opened without reading its images: they load one frame at a time."""

    root: Path
    pairs: list[tuple[int, Path, Path]]
    intrinsics: CameraIntrinsics | None
    depth_scale: float
    metadata: dict[str, str] = field(default_factory=dict)
    #: Camera-to-world pose per pair (TUM groundtruth.txt, 7-Scenes pose/), or None.
    poses: list[npt.NDArray[np.float64] | None] | None = None
    #: Where :attr:`depth_scale` came from: ``"given"``, ``"camera.json"`` or
    #: ``"TUM RGB-D dataset"``.
    depth_scale_origin: str = "given"

    @property
    def path(self) -> Path:  # type: ignore[override]
        return self.root

    def __len__(self) -> int:
        return len(self.pairs)

    def __iter__(self) -> Iterator[RGBDFrame]:
        return self.frames()

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[RGBDFrame]:
        """Frames ``start`` to ``stop`` (exclusive); only their images are read."""
        shape: tuple[int, ...] | None = None
        projector = None
        if self.intrinsics is not None:
            from .projector import Projector

            projector = Projector(self.intrinsics, self.depth_scale)
        for i, (t, c, d) in enumerate(self.pairs[start:stop], start):
            pose = None if self.poses is None else self.poses[i]
            frame = RGBDFrame(
                _read_color(c), _read_depth(d), t, index=i, pose=pose, projector=projector
            )
            assert frame.color is not None
            if frame.color.shape[:2] != frame.depth.shape:
                raise InputError(
                    f"{str(c)!r} is {frame.color.shape[1]}x{frame.color.shape[0]} but "
                    f"{str(d)!r} is {frame.depth.shape[1]}x{frame.depth.shape[0]}"
                )
            if shape is not None and frame.depth.shape != shape:
                raise InputError(
                    f"frames in {str(self.root)!r} have different sizes: {str(d)!r} is "
                    f"{frame.depth.shape[1]}x{frame.depth.shape[0]}, earlier frames "
                    f"{shape[1]}x{shape[0]}"
                )
            shape = frame.depth.shape
            yield frame


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


def _depth_scale(root: Path, given: float | None, meta: dict[str, Any]) -> tuple[float, str]:
    """The folder's depth scale and where it came from."""
    if given is not None:
        return float(given), "given"
    if "depth_scale" in meta:
        return float(meta["depth_scale"]), "camera.json"
    if _is_tum_dataset(root):
        return TUM_DEPTH_SCALE, "TUM RGB-D dataset"
    raise InputError(
        f"no depth scale for {str(root)!r}: nothing in the folder says how many depth units make "
        "a metre; pass depth_scale=UNITS_PER_METRE (1000 for millimetres), or put depth_scale "
        "in a camera.json in the folder"
    )


def open_folder(
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_scale: float | None = None,
    layout: str = "auto",
    fps: float = 30.0,
    max_dt: float = 0.02,
) -> FolderSource:
    """Find the color/depth pairs of an RGB-D folder without reading the images.

    Arguments as :func:`load_folder`; iterate the result to read the frames one at a time.
    """
    from .camera import CameraIntrinsics

    root = Path(path)
    if not root.is_dir():
        raise InputError(f"RGB-D folder {str(root)!r} does not exist or is not a folder")
    if layout not in ("auto", "tum", "folders"):
        raise InputError(f"layout must be 'auto', 'tum' or 'folders', got {layout!r}")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    is_tum = (root / "rgb.txt").exists() and (root / "depth.txt").exists()
    if layout == "tum" or (layout == "auto" and is_tum):
        pairs = _tum_pairs(root, round(max_dt * _NS_PER_S))
    else:
        pairs = _folder_pairs(root, fps)
    if max_frames is not None:
        pairs = pairs[:max_frames]
    if not pairs:
        raise InputError(f"RGB-D folder {str(root)!r} holds no color/depth pairs")

    camera_file = root / "camera.json"
    meta: dict[str, Any] = json.loads(camera_file.read_text()) if camera_file.exists() else {}
    if intrinsics is None and {"fx", "fy", "cx", "cy"} <= meta.keys():
        keys = ("width", "height", "fx", "fy", "cx", "cy")
        intrinsics = CameraIntrinsics.from_dict({k: meta[k] for k in keys if k in meta})
    scale, origin = _depth_scale(root, depth_scale, meta)
    intrinsics, camera_from = _folder_camera(root, intrinsics, pairs)
    is_tum_pairs = layout == "tum" or (layout == "auto" and is_tum)
    from .sources.poses import folder_poses

    poses = folder_poses(root, pairs, tum=is_tum_pairs)
    source = FolderSource(root, pairs, intrinsics, scale, poses=poses, depth_scale_origin=origin)
    source.metadata["timestamps"] = _timestamp_note(root, is_tum_pairs, pairs, fps)
    if camera_from and camera_from != "given":
        source.metadata["intrinsics_file"] = Path(camera_from).name
    return source


def load_folder(
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_scale: float | None = None,
    layout: str = "auto",
    fps: float = 30.0,
    max_dt: float = 0.02,
) -> RGBDSequence:
    """Load an RGB-D sequence from a folder (see the module docstring for the layouts).

    ``layout`` is ``"auto"``, ``"tum"`` or ``"folders"``; ``max_dt`` is the largest color/depth
    time difference in seconds accepted when pairing TUM lists without ``associations.txt``.
    Intrinsics and depth scale default to the folder's ``camera.json``; without a depth scale
    there, a TUM RGB-D dataset folder gets TUM's 5000 and any other folder raises
    :class:`~pcdcodec.InputError` asking for ``depth_scale``. ``intrinsics`` may also be an
    intrinsics file
    (:func:`~pcdcodec.camera.read_intrinsics`), and without either, a file the folder ships
    with (``intrinsics.K.txt``, ``camera-intrinsics.txt``, a CameraInfo YAML, an Open3D
    intrinsic JSON) is read. Plain folders without time lists are timed at ``fps`` from the
    frame numbers in their file names, so dropped frames keep their gap; the source's
    ``metadata["timestamps"]`` says how the times were made. Raises
    :class:`~pcdcodec.InputError` for a missing folder, an unknown layout, an empty sequence,
    an unknown depth scale, unreadable images or frames of different sizes.
    """
    source = open_folder(
        path,
        max_frames=max_frames,
        intrinsics=intrinsics,
        depth_scale=depth_scale,
        layout=layout,
        fps=fps,
        max_dt=max_dt,
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
) -> int:
    """Write frames as a TUM RGB-D folder that :func:`load_folder` reads back.

    ``rgb/NNNNNN.png`` (8-bit RGB), ``depth/NNNNNN.png`` (16-bit depth units; float32 depth as
    ``.tiff`` metres), ``rgb.txt`` and ``depth.txt`` with the timestamps in seconds, and
    ``camera.json`` (intrinsics and depth scale) when ``intrinsics`` is given. ``clouds`` names
    point-cloud formats to write per frame into ``clouds/`` (``"ply"``, ``"pcd"``; the frames
    need a projector, as frames of a recording have). The folder is written beside its target
    and moved into place when complete; an existing non-empty folder needs ``overwrite``.
    ``progress`` is called with the number of frames written. Returns that number.
    """
    import shutil

    import imagecodecs

    out = Path(path)
    for fmt_name in clouds:
        if fmt_name not in ("ply", "pcd"):
            raise InputError(f"point cloud format must be 'ply' or 'pcd', got {fmt_name!r}")
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(f"{str(out)!r} is not empty; pass overwrite=True to write into it")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        (tmp / "rgb").mkdir(parents=True)
        (tmp / "depth").mkdir()
        if clouds:
            (tmp / "clouds").mkdir()
        rgb_list = ["# color images", "# timestamp filename"]
        depth_list = ["# depth maps", "# timestamp filename"]
        count = 0
        for i, frame in enumerate(frames):
            t = int(frame.timestamp_ns)
            stamp = f"{t // _NS_PER_S}.{t % _NS_PER_S:09d}"
            name = f"{i:06d}"
            if frame.color is not None:
                (tmp / "rgb" / f"{name}.png").write_bytes(imagecodecs.png_encode(frame.color))
                rgb_list.append(f"{stamp} rgb/{name}.png")
            if frame.depth.dtype == np.uint16:
                depth_file = f"depth/{name}.png"
                data = imagecodecs.png_encode(frame.depth)
            else:
                depth_file = f"depth/{name}.tiff"
                data = imagecodecs.tiff_encode(frame.depth)
            (tmp / depth_file).write_bytes(data)
            depth_list.append(f"{stamp} {depth_file}")
            if clouds:
                import open3d as o3d

                cloud = frame.to_point_cloud()
                for ext in clouds:
                    o3d.io.write_point_cloud(tmp / "clouds" / f"{name}.{ext}", cloud)
            count = i + 1
            if progress is not None:
                progress(count)
        (tmp / "rgb.txt").write_text("\n".join(rgb_list) + "\n")
        (tmp / "depth.txt").write_text("\n".join(depth_list) + "\n")
        if intrinsics is not None:
            camera = {**intrinsics.to_dict(), "depth_scale": depth_scale}
            (tmp / "camera.json").write_text(json.dumps(camera, indent=2) + "\n")
        if not out.exists():
            os.replace(tmp, out)
        elif not any(out.iterdir()):
            out.rmdir()
            os.replace(tmp, out)
        else:  # overwrite: replace the files written, leave others alone
            for item in sorted(tmp.rglob("*")):
                target = out / item.relative_to(tmp)
                if item.is_dir():
                    target.mkdir(exist_ok=True)
                else:
                    os.replace(item, target)
            shutil.rmtree(tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return count
