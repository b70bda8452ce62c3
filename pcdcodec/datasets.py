"""Reading RGB-D sequences from folders, and the bundled sample.

Folder layouts understood (``layout="auto"`` tries them in this order):

* **TUM RGB-D**: ``rgb.txt`` and ``depth.txt`` (``timestamp path`` lines, ``#`` comments), and
  optionally ``associations.txt`` (``rgb_ts rgb_path depth_ts depth_path`` lines). Without
  associations, each color frame is paired with the depth frame nearest in time. A folder
  with ``depth.txt`` alone is depth only.
* **Subfolders**: ``rgb/`` (or ``color/``) and ``depth/`` holding images that pair up in
  sorted file-name order; ``depth/`` alone is depth only.
* **Flat**: one folder whose file names say what they hold: ``frame_000001_depth.tiff`` beside
  ``frame_000001_rgb.tiff`` (as PCL writes), ``0001_depth.png`` beside ``0001_color.png``...
  Depth and color files pair up by the rest of their names.
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
units per metre and a 7-Scenes folder (``frame-NNNNNN.depth.png`` with
``camera-intrinsics.txt``) 1000; for any other folder the scale cannot be known, and opening it
raises :class:`~pcdcodec.InputError` asking for ``depth_scale``.
"""

from __future__ import annotations

import fnmatch
import itertools
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
from .sources.base import Source

if TYPE_CHECKING:
    from .geometry.camera import CameraIntrinsics

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
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
DEPTH_SUFFIXES = (".png", ".tif", ".tiff", ".npy")
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


_DECIMAL_SECONDS = re.compile(r"\d+(?:\.\d*)?")


def _read_list(path: Path, columns: int) -> list[tuple[int, list[str]]]:
    """A TUM list's rows, ``timestamp`` first, each with its time in int ns.

    Raises :class:`~pcdcodec.InputError` naming the file and line for a row of too few
    columns, a time that is not decimal seconds, or a time not after the row before's (the
    rows are frames in time order; equal or earlier times are not times).
    """
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) < columns:
            raise InputError(f"{path}:{lineno}: expected {columns} columns, got {line!r}")
        if not _DECIMAL_SECONDS.fullmatch(parts[0]):
            raise InputError(
                f"{path}:{lineno}: timestamp {parts[0]!r} is not seconds (a decimal number "
                "such as 1305031229.528748)"
            )
        t = _seconds_to_ns(parts[0])
        if rows and t <= rows[-1][0]:
            raise InputError(
                f"{path}:{lineno}: timestamp {parts[0]} is not after the line before's; the "
                "listed times must increase (files whose listed times are not times need "
                "depth_pattern= and color_pattern=, to pair them by name)"
            )
        rows.append((t, parts[:columns]))
    return rows


def _seconds_to_ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * _NS_PER_S + int((frac + "000000000")[:9])


#: (timestamp ns, color file or None for depth only, depth file)
Pair = tuple[int, Path | None, Path]


def _tum_pairs(root: Path, max_dt_ns: int) -> list[Pair]:
    assoc = root / "associations.txt"
    if assoc.exists():
        return [(t, root / r[1], root / r[3]) for t, r in _read_list(assoc, 4)]
    depth = [(t, root / r[1]) for t, r in _read_list(root / "depth.txt", 2)]
    if not (root / "rgb.txt").exists():
        return [(t, None, d) for t, d in depth]  # depth only
    from .sync import associate

    rgb = [(t, root / r[1]) for t, r in _read_list(root / "rgb.txt", 2)]
    pairs = associate([t for t, _ in rgb], [t for t, _ in depth], max_difference=max_dt_ns)
    return [(rgb[i][0], rgb[i][1], depth[j][1]) for i, j in pairs]


#: What the layouts look for, for the error of a folder that matches none.
_LOOKED_FOR = (
    "rgb.txt/depth.txt (TUM layout); rgb/ (or color/) and depth/ subfolders; or one folder of "
    "files named *depth* and *rgb*/*color* (frame_000001_depth.tiff, frame_000001_rgb.tiff); "
    "depth as 16-bit PNG/TIFF, float32 TIFF or .npy, color as PNG/JPEG/TIFF; other names "
    "need depth_pattern= and color_pattern="
)


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    return sorted(
        p for p in folder.iterdir() if p.suffix.lower() in suffixes and not p.name.startswith(".")
    )


def _color_dir(root: Path) -> Path | None:
    return next((root / n for n in ("rgb", "color") if (root / n).is_dir()), None)


def _subfolder_files(root: Path) -> tuple[list[Path] | None, list[Path]]:
    color_dir = _color_dir(root)
    depths = _files(root / "depth", DEPTH_SUFFIXES)
    if color_dir is None:
        return None, depths  # depth only
    colors = _files(color_dir, IMAGE_SUFFIXES)
    if len(colors) != len(depths):
        raise InputError(
            f"{str(root)!r} holds {len(colors)} color and {len(depths)} depth images; "
            "plain folders must pair up one to one"
        )
    return colors, depths


# The word that says what a file holds, and the rest of the name that pairs it up.
FLAT_DEPTH = re.compile(r"^(.*?)[-_.]?depth(.*)$", re.IGNORECASE)
_FLAT_COLOR = re.compile(r"^(.*?)[-_.]?(?:rgb|color|colour)(.*)$", re.IGNORECASE)


def _flat_key(regex: re.Pattern[str], path: Path) -> str | None:
    m = regex.match(path.stem)
    return None if m is None else f"{m.group(1)}|{m.group(2) or ''}"


def _pair_by_key(
    root: Path,
    colors: dict[str, Path] | None,
    depths: dict[str, Path],
    what: str,
    rule: str = "a color file of the same name but for its kind (or give a depth-only folder)",
) -> tuple[list[Path] | None, list[Path]]:
    """Depth files and their color files, matched by key and sorted by depth file name;
    ``rule`` says, in the error for a file without its partner, what a partner is."""
    keys = sorted(depths, key=lambda k: depths[k].name)
    if colors is None:
        return None, [depths[k] for k in keys]
    alone = [depths[k].name for k in keys if k not in colors]
    alone += [colors[k].name for k in sorted(colors) if k not in depths]
    if alone:
        raise InputError(
            f"{str(root)!r}: {len(alone)} file(s) have no partner among the {what}, such as "
            f"{alone[0]!r}; every depth file needs {rule}"
        )
    return [colors[k] for k in keys], [depths[k] for k in keys]


def _flat_files(root: Path) -> tuple[list[Path] | None, list[Path]] | None:
    """The flat layout's files (files named *depth* and *rgb*/*color*), or None if none."""
    depths: dict[str, Path] = {}
    colors: dict[str, Path] = {}

    def add(found: dict[str, Path], key: str, p: Path) -> None:
        if key in found:  # frame_1_depth.png and frame_1_depth.tiff: which one is the frame?
            raise InputError(
                f"{str(root)!r}: {found[key].name!r} and {p.name!r} are the same frame's "
                "files; keep one, or pick files with depth_pattern= and color_pattern="
            )
        found[key] = p

    for p in _files(root, DEPTH_SUFFIXES + IMAGE_SUFFIXES):
        key = _flat_key(FLAT_DEPTH, p)
        if key is not None and p.suffix.lower() in DEPTH_SUFFIXES:
            add(depths, key, p)
        elif p.suffix.lower() in IMAGE_SUFFIXES and (key := _flat_key(_FLAT_COLOR, p)):
            add(colors, key, p)
    if not depths:
        return None
    return _pair_by_key(root, colors or None, depths, "*depth* and *rgb*/*color* files")


def _glob_key(pattern: str) -> re.Pattern[str]:
    """A regex whose groups are what the wildcards of a glob pattern match (``*``, ``?`` and
    ``[...]`` classes, ``[!...]`` negated; a ``[`` without its ``]`` is itself)."""
    parts = []
    i = 0
    while i < len(pattern):
        ch = pattern[i]
        if ch == "*":
            parts.append("(.*)")
        elif ch == "?":
            parts.append("(.)")
        elif ch == "[":
            start = i + 2 if pattern[i + 1 : i + 2] == "!" else i + 1
            end = pattern.find("]", start + 1)  # a "]" first in the class is one of its chars
            if end < 0:
                parts.append(re.escape(ch))
            else:
                # fnmatch's own regex for the class, "(?s:[...])\\Z", as a group
                regex = fnmatch.translate(pattern[i : end + 1])
                parts.append("(" + regex.removeprefix("(?s:").removesuffix(")\\Z") + ")")
                i = end
        else:
            parts.append(re.escape(ch))
        i += 1
    return re.compile("".join(parts) + r"\Z")


def _pattern_files(
    root: Path, depth_pattern: str, color_pattern: str | None
) -> tuple[list[Path] | None, list[Path]]:
    def matched(pattern: str) -> dict[str, Path]:
        if not isinstance(pattern, str) or not pattern or Path(pattern).is_absolute():
            raise InputError(
                f"a name pattern must be a glob relative to the folder, got {pattern!r}"
            )
        regex = _glob_key(pattern)
        out: dict[str, Path] = {}
        for p in sorted(root.glob(pattern)):
            rel = p.relative_to(root).as_posix()
            m = regex.match(rel)
            if p.is_file() and m is not None:
                out["|".join(m.groups())] = p
        return out

    depths = matched(depth_pattern)
    if not depths:
        raise InputError(f"{str(root)!r} holds no file matching depth_pattern {depth_pattern!r}")
    colors = None if color_pattern is None else matched(color_pattern)
    if colors is not None and not colors:
        raise InputError(f"{str(root)!r} holds no file matching color_pattern {color_pattern!r}")
    return _pair_by_key(
        root,
        colors,
        depths,
        f"files matching {depth_pattern!r} and {color_pattern!r}",
        "a color file whose wildcards match the same text (with 'depth/d*.png' and "
        "'rgb/c*.png', depth/d001.png pairs with rgb/c001.png), or no color_pattern for "
        "depth only",
    )


_SECONDS = re.compile(r"(?<![\d.])(\d{9,10})\.(\d{1,9})(?!\d|\.\d)")
_NANOSECONDS = re.compile(r"(?<!\d)(\d{18,19})(?!\d)")


def _name_times(paths: list[Path]) -> tuple[list[int], str] | None:
    """Timestamps (ns) the file names carry, and what they were read as; or None."""
    for regex, what in ((_SECONDS, "seconds"), (_NANOSECONDS, "nanoseconds")):
        times = []
        for p in paths:
            found = regex.findall(p.name)
            if len(found) != 1:
                break
            m = found[0]
            times.append(_seconds_to_ns(".".join(m)) if what == "seconds" else int(m))
        else:
            if all(b > a for a, b in itertools.pairwise(times)):
                return times, what
    return None


def _named_pairs(
    colors: list[Path] | None, depths: list[Path], fps: float
) -> tuple[list[Pair], str]:
    """Timestamped pairs of files paired up already, and how the times were made."""
    stamped = _name_times(depths)
    if stamped is not None:
        times, what = stamped
        note = f"recorded: {what} in the depth file names"
    else:
        step = _NS_PER_S / fps
        # Frame numbers in the names (frame-000012.png) keep the gaps of dropped frames.
        numbers = _frame_numbers(colors if colors is not None else depths)
        if numbers is not None:
            note = f"not recorded: frame numbers in the file names at {fps:g} fps, from 0"
        else:
            note = f"not recorded: file order at {fps:g} fps, from 0"
        numbers = numbers or list(range(len(depths)))
        times = [round((n - numbers[0]) * step) for n in numbers]
    cs: list[Path | None] = list(colors) if colors is not None else [None] * len(depths)
    return list(zip(times, cs, depths, strict=True)), note


def _frame_numbers(paths: list[Path]) -> list[int] | None:
    """The last number in each file name, when every name has one and they increase."""
    numbers = []
    for p in paths:
        found = re.findall(r"\d+", p.stem)
        if not found:
            return None
        numbers.append(int(found[-1]))
    if any(b <= a for a, b in itertools.pairwise(numbers)):
        return None
    return numbers


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
        d2c = _as_transform(d2c, f"{str(p)!r}: depth_to_color")
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


def _as_camera(value: Any, what: str, width: int | None, height: int | None) -> CameraIntrinsics:
    """A camera given as CameraIntrinsics, a dict (camera.json keys) or an intrinsics file."""
    from .geometry.camera import CameraIntrinsics, read_intrinsics

    if isinstance(value, CameraIntrinsics):
        return value
    if isinstance(value, dict):
        size = {"width": width, "height": height}
        data = {**{k: v for k, v in size.items() if v is not None}, **value}
        try:
            return CameraIntrinsics.from_dict(data)
        except InputError as exc:
            raise InputError(f"{what}: {exc}") from None
    if isinstance(value, (str, os.PathLike)):
        return read_intrinsics(value, width, height)
    raise InputError(
        f"{what} must be a CameraIntrinsics, a dict or an intrinsics file, got "
        f"{type(value).__name__}"
    )


def _as_transform(value: Any, what: str) -> npt.NDArray[np.float64]:
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


@dataclass
class FolderSource(Source):
    """An RGB-D folder opened without reading its images: they load one frame at a time."""

    root: Path
    pairs: list[Pair]
    intrinsics: CameraIntrinsics | None
    depth_scale: float
    metadata: dict[str, str] = field(default_factory=dict)
    #: Camera-to-world pose per pair (TUM groundtruth.txt, 7-Scenes pose/), or None.
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

    @property
    def path(self) -> Path:  # type: ignore[override]
        return self.root

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
        return out

    def __iter__(self) -> Iterator[RGBDFrame]:
        return self.frames()

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[RGBDFrame]:
        """Frames ``start`` to ``stop`` (exclusive); only their images are read."""
        shape: tuple[int, ...] | None = None
        projector = None
        if self.intrinsics is not None:
            from .geometry.projector import Projector

            projector = Projector(
                self.intrinsics,
                self.depth_scale,
                color_intrinsics=self.color_intrinsics,
                depth_to_color=self.depth_to_color,
            )
        for i, (t, c, d) in enumerate(self.pairs[start:stop], start):
            pose = None if self.poses is None else self.poses[i]
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
            yield RGBDFrame(color, depth, t, index=i, pose=pose, projector=projector)


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


def _depth_scale(
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


def _folder_pairs(
    root: Path,
    layout: str,
    fps: float,
    max_dt: float,
    depth_pattern: str | None,
    color_pattern: str | None,
) -> tuple[list[Pair], str, bool]:
    """The folder's pairs, how their times were made, and whether they are TUM lists."""
    if layout not in ("auto", "tum", "folders", "flat"):
        raise InputError(f"layout must be 'auto', 'tum', 'folders' or 'flat', got {layout!r}")
    if depth_pattern is not None:
        colors, depths = _pattern_files(root, depth_pattern, color_pattern)
        return (*_named_pairs(colors, depths, fps), False)
    if color_pattern is not None:
        raise InputError("color_pattern needs depth_pattern too")
    if layout == "tum" or (layout == "auto" and (root / "depth.txt").is_file()):
        return _tum_pairs(root, round(max_dt * _NS_PER_S)), "recorded (TUM lists)", True
    if layout in ("auto", "folders") and (root / "depth").is_dir():
        return (*_named_pairs(*_subfolder_files(root), fps), False)
    flat = _flat_files(root) if layout in ("auto", "flat") else None
    if flat is None:
        raise InputError(f"{str(root)!r} is not an RGB-D folder: expected {_LOOKED_FOR}")
    return (*_named_pairs(*flat, fps), False)


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
) -> FolderSource:
    """Find the color/depth pairs of an RGB-D folder without reading the images.

    Arguments as :func:`load_folder`; iterate the result to read the frames one at a time.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError(f"RGB-D folder {str(root)!r} does not exist or is not a folder")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, got {max_frames}")
    pairs, note, is_tum_pairs = _folder_pairs(
        root, layout, fps, max_dt, depth_pattern, color_pattern
    )
    if max_frames is not None:
        pairs = pairs[:max_frames]
    if not pairs:
        raise InputError(
            f"RGB-D folder {str(root)!r} holds no color/depth pairs; looked for {_LOOKED_FOR}"
        )
    if not color:
        pairs = [(t, None, d) for t, _, d in pairs]

    camera_file = root / "camera.json"
    meta = read_camera_json(camera_file) if camera_file.is_file() else {}
    scale, scale_from = _depth_scale(root, depth_scale, meta, pairs)
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
        camera, camera_from = _as_camera(intrinsics, "intrinsics", *depth_size()), "given"
    elif "fx" in own:
        camera = _as_camera(own, str(camera_file), *depth_size())
        camera_from = "camera.json"
    else:
        from .geometry.camera import find_intrinsics_file

        found = find_intrinsics_file(root)
        if found is not None:
            from .geometry.camera import read_intrinsics

            camera, camera_from = read_intrinsics(found, *depth_size()), found.name

    has_color = any(c is not None for _, c, _ in pairs)

    def color_size() -> tuple[int, int]:
        first = pairs[0][1]
        assert first is not None
        h, w = _read_color(first).shape[:2]
        return w, h

    color_camera = None
    d2c = depth_to_color
    if color_intrinsics is not None and has_color:
        color_camera = _as_camera(color_intrinsics, "color_intrinsics", *color_size())
    elif meta.get("color") is not None and has_color:
        color_camera = _as_camera(meta["color"], f"{str(camera_file)!r} color", *color_size())
        if d2c is None:
            d2c = meta.get("depth_to_color")
    if d2c is not None:
        d2c = _as_transform(d2c, "depth_to_color")
    if color_camera is not None and has_color:
        from .geometry.projector import check_color_camera

        color_camera, d2c = check_color_camera(color_camera, d2c)
    elif color_intrinsics is None and d2c is not None and has_color:
        raise InputError("depth_to_color was given without color_intrinsics")
    else:
        color_camera, d2c = None, None

    from .sources.poses import folder_poses

    poses = folder_poses(root, pairs, tum=is_tum_pairs)
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
    )
    source.metadata["timestamps"] = note
    if camera_from not in ("", "given", "camera.json"):
        source.metadata["intrinsics_file"] = camera_from
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
    color_intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None,
    depth_to_color: Any = None,
    depth_pattern: str | None = None,
    color_pattern: str | None = None,
    color: bool = True,
) -> RGBDSequence:
    """Load an RGB-D sequence from a folder (see the module docstring for the layouts).

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
) -> int:
    """Write frames as a TUM RGB-D folder that :func:`load_folder` reads back.

    ``rgb/NNNNNN.png`` (8-bit RGB), ``depth/NNNNNN.png`` (16-bit depth units; float32 depth as
    ``.tiff`` metres), ``rgb.txt`` and ``depth.txt`` with the timestamps in seconds (no
    ``rgb/`` and ``rgb.txt`` when no frame has color: a depth-only folder), and
    ``camera.json`` (intrinsics and depth scale) when ``intrinsics`` is given, with the color
    camera of color not registered to depth (``color_intrinsics``, and ``depth_to_color``,
    the 4 × 4 transform in metres) as ``color`` and ``depth_to_color``. ``clouds`` names
    point-cloud formats to write per frame into ``clouds/`` (``"ply"``, ``"pcd"``; the frames
    need a projector, as frames of a recording have). The folder is written beside its target
    and moved into place when complete; an existing non-empty folder needs ``overwrite``.
    ``progress`` is called with the number of frames written. Returns that number.
    """
    import imagecodecs

    from ._atomic import atomic_output  # not loaded by `import pcdcodec`

    out = Path(path)
    for fmt_name in clouds:
        if fmt_name not in ("ply", "pcd"):
            raise InputError(f"point cloud format must be 'ply' or 'pcd', got {fmt_name!r}")
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(f"{str(out)!r} is not empty; pass overwrite=True to write into it")
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(out, place=_place_folder) as tmp:
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
        if len(rgb_list) > 2:
            (tmp / "rgb.txt").write_text("\n".join(rgb_list) + "\n")
        else:  # no color: depth.txt alone reads back as a depth-only folder
            (tmp / "rgb").rmdir()
        (tmp / "depth.txt").write_text("\n".join(depth_list) + "\n")
        if intrinsics is not None:
            camera: dict[str, Any] = {**intrinsics.to_dict(), "depth_scale": depth_scale}
            if color_intrinsics is not None:
                camera["color"] = color_intrinsics.to_dict()
                if depth_to_color is not None:
                    camera["depth_to_color"] = _as_transform(
                        depth_to_color, "depth_to_color"
                    ).tolist()
            (tmp / "camera.json").write_text(json.dumps(camera, indent=2) + "\n")
    return count


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
