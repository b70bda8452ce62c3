"""RGB-D image folders as a :class:`Source`: :func:`open_folder` and :class:`FolderSource`.

Folder layouts understood (``layout="auto"`` tries them in this order):

* **TUM RGB-D**: ``rgb.txt`` and ``depth.txt`` (``timestamp path`` lines, ``#`` comments), and
  optionally ``associations.txt`` (``rgb_ts rgb_path depth_ts depth_path`` lines). Without
  associations, each color frame is paired with the depth frame nearest in time. A folder
  with ``depth.txt`` alone is depth only.
* **Subfolders**: ``rgb/`` (or ``color/``) and ``depth/`` holding images that pair up in
  sorted file-name order; ``depth/`` alone is depth only.
* **Flat**: one folder whose file names say what they hold: ``frame_000001_depth.tiff`` beside
  ``frame_000001_rgb.tiff`` (as PCL writes), ``0001_depth.png`` beside ``0001_color.png``,
  ``frame-000000.depth.png`` beside ``frame-000000.color.png`` (7-Scenes as Microsoft ships
  it, with its ``frame-000000.pose.txt`` poses)... Depth and color files pair up by the rest of
  their names.
* **Patterns**: ``depth_pattern`` and ``color_pattern``, glob patterns relative to the
  folder (``"depth_*.npy"``, ``"cam0/*.png"``), pair up by the text their wildcards match.

Depth files are 16-bit PNG or TIFF, float32 TIFF (metres), or NumPy ``.npy`` arrays (uint16
depth units or float32 metres); color files are 8-bit PNG, JPEG or TIFF.

Without time lists, timestamps come from the file names when they carry them: seconds with a
fraction (``1305031102.175304.png``, as TUM names its files) or nanosecond integers
(``1614787200123456789.png``); otherwise the frame numbers in the names (``frame-000012``) or
the file order, at ``fps``. The source's ``metadata["timestamps"]`` says which.

Intrinsics and depth scale come from the arguments or, when not given, from the folder: a
``camera.json`` (see :func:`read_camera_json`), or an intrinsics file it ships with
(:data:`~pcdcodec.geometry.camera.INTRINSICS_FILE_NAMES`). Without a depth scale there, a TUM RGB-D
dataset folder (its ``depth.txt`` names the dataset's ``rgbd_dataset_…`` bag) gets TUM's 5000
units per metre (and, without an intrinsics file, the ROS default camera TUM's own tools use,
the ``tum-ros`` preset, for its 640 x 480 images) and a 7-Scenes folder
(``frame-NNNNNN.depth.png`` with ``camera-intrinsics.txt``) 1000; for any other folder the
scale cannot be known, and opening it raises :class:`~pcdcodec.InputError` asking for
``depth_scale``.

Every PNG and JPEG is checked whole before it is decoded (decoders fill a cut image with grey):
a cut or damaged image raises :class:`~pcdcodec.DecodeError` naming the file, when its frame
is read.

The layouts' file pairing and timing live in ``_folder_layouts``, the camera.json and the
datasets' depth scales in ``_folder_camera``; this module opens the folder and reads its images.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..frame import Frame
from ..geometry.camera import as_intrinsics
from ._folder_camera import (
    CAMERA_JSON_KEYS,
    TUM_DEPTH_SCALE,
    as_transform,
    dataset_camera,
    folder_depth_scale,
    read_camera_json,
)
from ._folder_layouts import (
    DEPTH_SUFFIXES,
    FLAT_DEPTH,
    IMAGE_SUFFIXES,
    LOOKED_FOR,
    Pair,
    folder_pairs,
)
from .base import InputStream, Source, detect_kind, register_source

if TYPE_CHECKING:
    from ..geometry.camera import CameraIntrinsics

__all__ = [
    "CAMERA_JSON_KEYS",
    "DEPTH_SUFFIXES",
    "FLAT_DEPTH",
    "IMAGE_SUFFIXES",
    "TUM_DEPTH_SCALE",
    "FolderSource",
    "Pair",
    "as_transform",
    "open_folder",
    "read_camera_json",
]


def _read_image(path: Path) -> npt.NDArray[Any]:
    """An image file's pixels. A PNG or JPEG is checked whole first (decoders fill a cut image
    with grey instead of failing): a cut or damaged one raises :class:`~pcdcodec.DecodeError`
    naming the file and what is wrong; other formats (TIFF) are left to the decoder."""
    import imagecodecs

    from ..color.images import check_compressed

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"image file {str(path)!r} does not exist") from None
    except OSError as exc:
        raise InputError(f"cannot read image {str(path)!r}: {exc.strerror or exc}") from None
    codec: str | None = None
    if data.startswith((b"\x89PNG", b"\xff\xd8")):
        codec = check_compressed(data, repr(str(path))).format  # "png" or "jpeg"
    try:
        return np.asarray(imagecodecs.imread(data, codec=codec) if codec else _imread(path))
    except Exception as exc:
        # One line: without a format, imagecodecs lists every decoder it tried.
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        what = f"a {codec.upper()} image" if codec else "a PNG, JPEG or TIFF image"
        raise InputError(f"cannot read image {str(path)!r} as {what}: {first}") from None


def _imread(path: Path) -> Any:
    import imagecodecs

    return imagecodecs.imread(str(path))


def _read_color(path: Path) -> npt.NDArray[np.uint8]:
    img = _read_image(path)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise InputError(
            f"color image {str(path)!r} is {img.dtype} {img.shape}, expected 8-bit RGB"
        )
    return np.ascontiguousarray(img[..., :3])


def _read_npy(path: Path) -> npt.NDArray[Any]:
    """A depth array from a ``.npy`` file, mapped first so that a header declaring more than
    the file holds is refused before anything is allocated."""
    try:
        mapped = np.load(path, mmap_mode="r", allow_pickle=False)
    except FileNotFoundError:
        raise InputError(f"depth file {str(path)!r} does not exist") from None
    except Exception as exc:
        raise InputError(f"cannot read depth array {str(path)!r}: {exc}") from None
    if not isinstance(mapped, np.ndarray) or mapped.dtype.kind not in "uf" or mapped.ndim != 2:
        what = f"{mapped.dtype} {mapped.shape}" if isinstance(mapped, np.ndarray) else "not one"
        raise InputError(
            f"depth array {str(path)!r} is {what}, expected a 2-D uint16 (depth units) or "
            "float32 (metres) array"
        )
    native = mapped.dtype.newbyteorder("=")
    if native not in (np.dtype(np.uint16), np.dtype(np.float32)):
        raise InputError(
            f"depth array {str(path)!r} is {mapped.dtype}; expected uint16 (depth units) or "
            "float32 (metres): convert it without losing values first"
        )
    return np.array(mapped, dtype=native)


def _read_depth(path: Path) -> npt.NDArray[Any]:
    img = _read_npy(path) if path.suffix.lower() == ".npy" else _read_image(path)
    if img.ndim != 2 or img.dtype not in (np.uint16, np.float32):
        raise InputError(
            f"depth image {str(path)!r} is {img.dtype} {img.shape}, "
            "expected single-channel uint16 or float32"
        )
    return img


@dataclass
class FolderSource(Source):
    """An RGB-D folder opened without reading its images: they load one frame at a time."""

    root: Path
    pairs: list[Pair]
    intrinsics: CameraIntrinsics | None
    depth_scale: float
    metadata: dict[str, str] = field(default_factory=dict)
    #: Camera-to-world pose per pair (TUM groundtruth.txt, 7-Scenes pose/ or pose files beside
    #: the depth images), or None.
    poses: list[npt.NDArray[np.float64] | None] | None = None
    #: Where :attr:`depth_scale` came from: ``"given"``, ``"camera.json"``,
    #: ``"TUM RGB-D dataset"`` or ``"7-Scenes dataset"``.
    depth_scale_origin: str = "given"
    #: Where :attr:`intrinsics` came from: ``"given"``, ``"camera.json"`` or the name of the
    #: intrinsics file in the folder.
    intrinsics_origin: str = "given"
    #: The color camera where color is not registered to depth (another size), else None.
    color_intrinsics: CameraIntrinsics | None = None
    depth_to_color: Any = None
    has_color: bool = True
    camera_notes: tuple[str, ...] = ()
    #: The folder's own entries a recording of it holds: the image folders (or files), the
    #: time lists, the camera and pose files it read.
    read_entries: frozenset[str] = frozenset()
    #: Images of TUM lists left without a partner when pairing them by time, by stream.
    dropped: dict[str, int] = field(default_factory=lambda: {"color": 0, "depth": 0})
    #: Each pair's depth image's own time (ns) where the folder stamps depth apart from color
    #: (TUM lists), else None: the pair's time is both images'.
    depth_times: list[int] | None = None

    @property
    def path(self) -> Path:  # type: ignore[override]
        return self.root

    def input_streams(self) -> list[InputStream]:
        """The folder's own files and subfolders (not its images: those are the frames), from
        its listing."""
        try:
            entries = sorted(os.scandir(self.root), key=lambda e: e.name)
        except OSError:
            return []
        images = DEPTH_SUFFIXES + IMAGE_SUFFIXES
        return [
            InputStream(e.name, "folder" if e.is_dir() else "file")
            for e in entries
            if not e.name.startswith(".")
            and (e.is_dir() or os.path.splitext(e.name)[1].lower() not in images)
        ]

    def recorded_streams(self) -> set[str]:
        """The image folders, the time lists, and the camera and pose files read (a TUM
        folder's ``accelerometer.txt``, say, is left out)."""
        return set(self.read_entries)

    def __len__(self) -> int:
        return len(self.pairs)

    def describe(self) -> dict[str, Any]:
        """As :meth:`Source.describe`, with the image sizes (from the first pair) and how the
        timestamps were made."""
        out = super().describe()
        _, c, d = self.pairs[0]
        h, w = _read_depth(d).shape
        size = f"{w}x{h} depth"
        if c is not None:
            ch, cw = _read_color(c).shape[:2]
            size += f", {cw}x{ch} color"
        else:
            size += ", no color"
        out["size"] = size
        out["timestamps"] = self.metadata.get("timestamps")
        out["dropped"] = dict(self.dropped)
        return out

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Frame]:
        """Frames ``start`` to ``stop`` (exclusive); only their images are read."""
        shape: tuple[int, ...] | None = None
        projector = None
        if self.intrinsics is not None:
            from ..geometry.projector import Projector

            projector = Projector(
                self.intrinsics,
                self.depth_scale,
                color_intrinsics=self.color_intrinsics,
                depth_to_color=self.depth_to_color,
            )
        for i, (t, c, d) in enumerate(self.pairs[start:stop], start):
            pose = None if self.poses is None else self.poses[i]
            depth_t = None if self.depth_times is None else self.depth_times[i]
            color = _read_color(c) if c is not None else None
            depth = _read_depth(d)
            if c is not None and color is not None:
                expected = (
                    self.color_intrinsics.shape
                    if self.color_intrinsics is not None
                    else depth.shape
                )
                if color.shape[:2] != expected:
                    raise InputError(
                        _size_problem(c, color.shape, d, depth.shape, self.color_intrinsics)
                    )
            if shape is not None and depth.shape != shape:
                raise InputError(
                    f"frames in {str(self.root)!r} have different sizes: {str(d)!r} is "
                    f"{depth.shape[1]}x{depth.shape[0]}, earlier frames "
                    f"{shape[1]}x{shape[0]}"
                )
            shape = depth.shape
            yield Frame(
                color, depth, t, index=i, pose=pose, projector=projector, depth_timestamp_ns=depth_t
            )


def _size_problem(
    c: Path, color: tuple[int, ...], d: Path, depth: tuple[int, ...], camera: Any
) -> str:
    if camera is not None:
        return (
            f"{str(c)!r} is {color[1]}x{color[0]}, but the color camera is "
            f"{camera.width}x{camera.height}"
        )
    return (
        f"{str(c)!r} is {color[1]}x{color[0]} but {str(d)!r} is {depth[1]}x{depth[0]}: color "
        "not registered to depth needs its own camera: pass color_intrinsics= (and "
        'depth_to_color=, the 4x4 depth-to-color transform in metres), or put "color" and '
        '"depth_to_color" in the folder\'s camera.json; or read depth only (color=False)'
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
    color_intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_to_color: Any = None,
    depth_pattern: str | None = None,
    color_pattern: str | None = None,
    color: bool = True,
    max_difference: int | None = None,
) -> FolderSource:
    """Find the color/depth pairs of an RGB-D folder without reading the images.

    Arguments as :func:`~pcdcodec.datasets.load_folder`; iterate the result to read the frames
    one at a time. ``max_difference`` (int ns, the name every reader takes) replaces
    ``max_dt`` (seconds) where given. The TUM list images left without a partner are the
    source's :attr:`~FolderSource.dropped`.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError(f"RGB-D folder {str(root)!r} does not exist or is not a folder")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    from ..sync import as_max_difference

    tolerance = round(max_dt * 1_000_000_000) if max_difference is None else max_difference
    dropped = {"color": 0, "depth": 0}
    pairs, note, depth_times = folder_pairs(
        root, layout, fps, as_max_difference(tolerance), depth_pattern, color_pattern, dropped
    )
    if max_frames is not None:
        pairs = pairs[:max_frames]
        depth_times = None if depth_times is None else depth_times[:max_frames]
    if not pairs:
        raise InputError(
            f"RGB-D folder {str(root)!r} holds no color/depth pairs; looked for {LOOKED_FOR}"
        )
    if not color:
        pairs = [(t, None, d) for t, _, d in pairs]

    camera_file = root / "camera.json"
    meta = read_camera_json(camera_file) if camera_file.is_file() else {}
    scale, scale_from = folder_depth_scale(root, depth_scale, meta, pairs)
    shape: tuple[int, int] | None = None

    def depth_size() -> tuple[int, int]:
        nonlocal shape
        if shape is None:
            h, w = _read_depth(pairs[0][2]).shape
            shape = (w, h)
        return shape

    camera: CameraIntrinsics | None = None
    camera_from = ""
    own = meta.get("camera") or {}
    if intrinsics is not None:
        camera, camera_from = as_intrinsics(intrinsics, "intrinsics", *depth_size()), "given"
    elif "fx" in own:
        camera = as_intrinsics(own, str(camera_file), *depth_size())
        camera_from = "camera.json"
    else:
        from ..geometry.camera import find_intrinsics_file

        found = find_intrinsics_file(root)
        if found is not None:
            from ..geometry.camera import read_intrinsics

            camera, camera_from = read_intrinsics(found, *depth_size()), found.name
        # Only for images of the dataset's size: a cropped copy has another camera.
        elif (by_dataset := dataset_camera(root)) is not None and (
            by_dataset[0].width,
            by_dataset[0].height,
        ) == depth_size():
            camera, camera_from = by_dataset

    has_color = any(c is not None for _, c, _ in pairs)

    def color_size() -> tuple[int, int]:
        first = pairs[0][1]
        assert first is not None
        h, w = _read_color(first).shape[:2]
        return w, h

    color_camera = None
    d2c = depth_to_color
    if color_intrinsics is not None and has_color:
        color_camera = as_intrinsics(color_intrinsics, "color_intrinsics", *color_size())
    elif meta.get("color") is not None and has_color:
        color_camera = as_intrinsics(meta["color"], f"{str(camera_file)!r} color", *color_size())
        if d2c is None:
            d2c = meta.get("depth_to_color")
    if d2c is not None:
        d2c = as_transform(d2c, "depth_to_color")
    if color_camera is not None and has_color:
        from ..geometry.projector import check_color_camera

        color_camera, d2c = check_color_camera(color_camera, d2c)
    elif color_intrinsics is None and d2c is not None and has_color:
        raise InputError("depth_to_color was given without color_intrinsics")
    else:
        color_camera, d2c = None, None

    from .poses import POSE_LAYOUT_KEY, folder_poses

    poses, pose_layout = folder_poses(root, pairs, depth_times=depth_times)
    source = FolderSource(
        root,
        pairs,
        camera,
        scale,
        poses=poses,
        depth_scale_origin=scale_from,
        intrinsics_origin=camera_from or "given",
        color_intrinsics=color_camera,
        depth_to_color=d2c,
        has_color=has_color,
        depth_times=depth_times,
    )
    source.metadata["timestamps"] = note
    source.dropped = dropped
    if pose_layout is not None:
        source.metadata[POSE_LAYOUT_KEY] = pose_layout
    if camera_from not in ("", "given", "camera.json"):
        source.metadata["intrinsics_file"] = camera_from
    is_tum_pairs = depth_times is not None
    source.read_entries = _read_entries(root, pairs, is_tum_pairs, poses is not None, camera_from)
    return source


def _read_entries(
    root: Path, pairs: list[Pair], tum: bool, posed: bool, camera_from: str
) -> frozenset[str]:
    """The names of the folder's own entries that opening it read or its frames come from."""
    read: set[str] = set()
    for _, c, d in pairs:
        for f in (c, d):
            parts = f.relative_to(root).parts if f is not None and f.is_relative_to(root) else ()
            if parts:
                read.add(parts[0])
    if tum:
        read |= {n for n in ("rgb.txt", "depth.txt", "associations.txt") if (root / n).is_file()}
    if (root / "camera.json").is_file():
        read.add("camera.json")
    if camera_from not in ("", "given", "camera.json"):
        read.add(camera_from)
    if posed:
        if tum and (root / "groundtruth.txt").is_file():
            read.add("groundtruth.txt")
        elif (root / "pose").is_dir():
            read.add("pose")
        else:  # 7-Scenes as shipped: a pose file beside each depth image
            from .poses import flat_pose_files

            read.update(flat_pose_files(root))
    return frozenset(read)


def _flat_depth_and_others(path: Path) -> tuple[bool, list[str]]:
    """Whether the folder holds a depth file of the flat layout (``*depth*.png``, ...), and its
    other files that are not images (which may be bags or camera recordings)."""
    flat = False
    others: list[str] = []
    try:
        with os.scandir(path) as entries:
            for e in entries:
                stem, ext = os.path.splitext(e.name)
                ext = ext.lower()
                if ext in DEPTH_SUFFIXES + IMAGE_SUFFIXES:
                    flat = flat or (
                        ext in DEPTH_SUFFIXES and bool(FLAT_DEPTH.match(stem)) and e.is_file()
                    )
                elif e.is_file():
                    others.append(e.path)
    except OSError:
        return False, []
    return flat, others


def _is_folder(path: Path) -> bool:
    if not path.is_dir():
        return False
    if ((path / "rgb.txt").is_file() and (path / "depth.txt").is_file()) or (
        (path / "depth").is_dir() and any((path / n).is_dir() for n in ("rgb", "color"))
    ):
        return True  # color and depth: an RGB-D folder whatever else it holds
    # Depth alone (depth.txt, depth/, or files named *depth*) is an RGB-D folder only beside no
    # other input: a folder of bags with a depth/ of previews or a depth_preview.png is a
    # folder of bags, to be searched, not frames of depth. A recording beside depth is what
    # was made of it, as before recordings were inputs.
    flat, others = _flat_depth_and_others(path)
    if not (flat or (path / "depth.txt").is_file() or (path / "depth").is_dir()):
        return False
    return not any(detect_kind(f) not in (None, "recording") for f in others)


_DEPTH_FILES = "16-bit PNG/TIFF, float32 TIFF or .npy"


def _missing(path: Path) -> str | None:
    """What a folder of color images lacks to be an RGB-D folder (its depth), or ``None``."""
    if not path.is_dir():
        return None
    if (path / "rgb.txt").is_file() and not (path / "depth.txt").is_file():
        return (
            "holds rgb.txt but no depth.txt: a TUM RGB-D folder lists its depth images "
            "(timestamp and file per line) in depth.txt beside rgb.txt"
        )
    color_dir = next((n for n in ("rgb", "color") if (path / n).is_dir()), None)
    if color_dir is not None and not (path / "depth").is_dir():
        return (
            f"holds {color_dir}/ but no depth/ found: an RGB-D folder of this layout keeps its "
            f"depth images ({_DEPTH_FILES}) in depth/ beside {color_dir}/; files of other "
            "names need depth_pattern= and color_pattern="
        )
    try:
        names = [e.name for e in os.scandir(path) if e.is_file()]
    except OSError:
        return None
    colors = [
        n
        for n in names
        if os.path.splitext(n)[1].lower() in IMAGE_SUFFIXES
        and re.search("rgb|colou?r", n, re.IGNORECASE)
    ]
    if colors and not _flat_depth_and_others(path)[0]:
        return (
            f"holds color images ({sorted(colors)[0]}, ...) but no depth image: depth files "
            f"({_DEPTH_FILES}) named *depth* beside them pair up by the rest of their names "
            "(frame_000001_depth.png with frame_000001_rgb.png); other names need "
            "depth_pattern= and color_pattern="
        )
    return None


register_source(
    "folder",
    _is_folder,
    open_folder,
    "a TUM RGB-D folder, rgb/ (or color/) and depth/ image folders, or one folder of "
    "*depth* and *rgb* files; other names need depth_pattern= and color_pattern=",
    missing=_missing,
)
