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

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .errors import InputError
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
]

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
#: Depth units per metre of the TUM RGB-D benchmark's 16-bit depth PNGs.
TUM_DEPTH_SCALE = 5000.0
_NS_PER_S = 1_000_000_000


@dataclass
class RGBDFrame:
    """One color/depth pair: RGB uint8 H×W×3, depth H×W (uint16 units or float32 metres)."""

    color: npt.NDArray[np.uint8]
    depth: npt.NDArray[Any]
    timestamp_ns: int


@dataclass
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
        return [f.color for f in self.frames]


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
    return [(round(i * step), c, d) for i, (c, d) in enumerate(zip(colors, depths, strict=True))]


@dataclass
class FolderSource(Source):
    """An RGB-D folder opened without reading its images: they load one frame at a time."""

    root: Path
    pairs: list[tuple[int, Path, Path]]
    intrinsics: CameraIntrinsics | None
    depth_scale: float
    metadata: dict[str, str] = field(default_factory=dict)
    #: Where :attr:`depth_scale` came from: ``"given"``, ``"camera.json"`` or
    #: ``"TUM RGB-D dataset"``.
    depth_scale_origin: str = "given"

    @property
    def path(self) -> Path:  # type: ignore[override]
        return self.root

    def __len__(self) -> int:
        return len(self.pairs)

    def __iter__(self) -> Iterator[RGBDFrame]:
        shape: tuple[int, ...] | None = None
        for t, c, d in self.pairs:
            frame = RGBDFrame(_read_color(c), _read_depth(d), t)
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
        "a metre; pass depth_scale= (--depth-scale on the command line), e.g. 1000 for "
        "millimetres, or put depth_scale in a camera.json in the folder"
    )


def open_folder(
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: CameraIntrinsics | None = None,
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
    return FolderSource(root, pairs, intrinsics, scale, depth_scale_origin=origin)


def load_folder(
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: CameraIntrinsics | None = None,
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
    :class:`~pcdcodec.InputError` asking for ``depth_scale``. Raises
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
