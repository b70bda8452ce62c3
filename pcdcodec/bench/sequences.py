"""The sequences the repository's tests and benchmarks run on: the bundled sample, and the real
sequences in ``../shared/data`` beside the checkout when they are present.

Each sequence says where it lives, how its files are named and its camera; the loaders read
frames spread over a sequence (cached), and skip the calling test or benchmark when its data is
absent. Tests, benchmarks and scripts all import this one module, so they read the same frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from ..datasets import sample_dir
from ..geometry.camera import CameraIntrinsics
from .sparse import sparsify_depth

__all__ = [
    "ALL_DEPTH_SETS",
    "AZURE_KINECT_MKV",
    "DEPTH_SETS",
    "PRESENT",
    "REPO",
    "SAMPLE",
    "SEQUENCES",
    "SHARED_DATA",
    "SPOT_BAG",
    "SPOT_TOPIC",
    "Sequence",
    "load_azure_kinect_depth",
    "load_colors",
    "load_depths",
    "load_frames",
    "load_spot_depth",
    "read_image",
    "set_present",
    "upsample_720p",
]

#: The checkout pcdcodec is imported from; the shared data sits beside it.
REPO = Path(__file__).resolve().parents[2]
SHARED_DATA = REPO.parent / "shared" / "data"
SAMPLE = sample_dir()


@dataclass(frozen=True)
class Sequence:
    """A real RGB-D sequence: where it lives, how its files are named, its camera."""

    name: str
    root: Path
    depth_glob: str
    depth_scale: float
    camera: CameraIntrinsics
    color_glob: str = "rgb/*.png"
    layout: str = "auto"

    @property
    def present(self) -> bool:
        return self.root.is_dir() and any(self.root.glob(self.depth_glob))

    def depth_paths(self) -> list[Path]:
        return sorted(self.root.glob(self.depth_glob))

    def reader_options(self) -> dict[str, Any]:
        """Options for :func:`pcdcodec.open_source` / ``load_folder``."""
        return {"depth_scale": self.depth_scale, "intrinsics": self.camera, "layout": self.layout}


_TUM = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
SEQUENCES = {
    "sample": Sequence("sample", SAMPLE, "depth/*.png", 5000.0, _TUM),
    "tum_fr1_rpy": Sequence(
        "tum_fr1_rpy", SHARED_DATA / "tum_fr1_rpy", "depth/*.png", 5000.0, _TUM
    ),
    # Its rgb.txt/depth.txt hold time deltas, not times: read it as plain folders.
    "realsense_d435": Sequence(
        "realsense_d435",
        SHARED_DATA / "realsense_d435_office",
        "depth/*.png",
        1000.0,
        CameraIntrinsics(640, 480, 615.0, 615.0, 320.0, 240.0),
        layout="folders",
    ),
    "7scenes_redkitchen": Sequence(
        "7scenes_redkitchen",
        SHARED_DATA / "7scenes_redkitchen",
        "depth/*.depth.png",
        1000.0,
        CameraIntrinsics(640, 480, 585.0, 585.0, 320.0, 240.0),
        "rgb/*.color.jpg",
    ),
}
PRESENT = [name for name, seq in SEQUENCES.items() if seq.present]


def _skip(what: Path) -> NoReturn:
    import pytest

    pytest.skip(f"{what} is not present")


def _present(name: str) -> Sequence:
    """Sequence ``name``; skips the calling test when its data is absent."""
    seq = SEQUENCES[name]
    if not seq.present:
        _skip(seq.root)
    return seq


def read_image(path: Path) -> np.ndarray[Any, Any]:
    """An image file as an array (imagecodecs: PNG, JPEG, ...)."""
    import imagecodecs

    return np.asarray(imagecodecs.imread(str(path)))


_cache: dict[tuple[str, str, int], list[np.ndarray[Any, Any]]] = {}


def load_depths(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """``count`` depth frames spread evenly over sequence ``name``; skips when it is absent."""
    seq = _present(name)
    key = ("depth", name, count)
    if key not in _cache:
        paths = seq.depth_paths()
        picks = np.linspace(0, len(paths) - 1, min(count, len(paths))).round().astype(int)
        _cache[key] = [read_image(paths[i]) for i in sorted(set(picks))]
    return _cache[key]


def load_colors(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """The first ``count`` consecutive RGB frames of sequence ``name``; skips when absent."""
    seq = _present(name)
    key = ("color", name, count)
    if key not in _cache:
        paths = sorted(seq.root.glob(seq.color_glob))[:count]
        _cache[key] = [read_image(p)[..., :3] for p in paths]
    return _cache[key]


SPOT_BAG = SHARED_DATA / "bags" / "spot" / "raw.bag"
SPOT_TOPIC = "/spot/depth/frontleft/image"
_spot: list[np.ndarray[Any, Any]] = []


def load_spot_depth() -> np.ndarray[Any, Any]:
    """The one Spot front-left depth frame (424×240 16UC1, mm, 36 % holes); skips when absent."""
    if not SPOT_BAG.is_file():
        _skip(SPOT_BAG)
    if not _spot:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        typestore = get_typestore(Stores.ROS1_NOETIC)
        with AnyReader([SPOT_BAG], default_typestore=typestore) as reader:
            conns = [c for c in reader.connections if c.topic == SPOT_TOPIC]
            _, _, raw = next(iter(reader.messages(connections=conns)))
            msg: Any = reader.deserialize(raw, conns[0].msgtype)
        order = ">u2" if msg.is_bigendian else "<u2"
        image = np.frombuffer(bytes(msg.data), order).reshape(msg.height, msg.width)
        _spot.append(np.ascontiguousarray(image, dtype=np.uint16))
    return _spot[0]


AZURE_KINECT_MKV = SHARED_DATA / "bags" / "pyk4a_recording.mkv"
_azure: list[np.ndarray[Any, Any]] = []


def load_azure_kinect_depth() -> np.ndarray[Any, Any]:
    """The one Azure Kinect depth frame (640×576 NFOV unbinned ToF, mm, 23.5 % holes), read by
    pcdcodec's own ``.mkv`` reader; skips when absent."""
    if not AZURE_KINECT_MKV.is_file():
        _skip(AZURE_KINECT_MKV)
    if not _azure:
        from ..sources import open_source

        with open_source(AZURE_KINECT_MKV) as source:
            frame = next(iter(source))
        _azure.append(np.ascontiguousarray(frame.depth, dtype=np.uint16))
    return _azure[0]


def upsample_720p(depth: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """A 1280×720 frame from a 640×480 one: its centre 640×360 rows, each pixel repeated as a
    2×2 block (nearest neighbour, so every value and hole is the sensor's own).

    No real 1280×720 depth is at hand; a real one has more detail per pixel than this, so it
    stands in for the pixel count (the per-pixel cost of a coder), not for the ratio.
    """
    h, w = depth.shape
    if (h, w) != (480, 640):
        raise ValueError(f"upsample_720p takes a 640x480 frame, got {w}x{h}")
    crop = depth[60:420]
    return np.ascontiguousarray(np.repeat(np.repeat(crop, 2, axis=0), 2, axis=1))


#: The 1280×720 set: the RealSense D435 frames, upsampled (:func:`upsample_720p`).
_UPSAMPLED = {"realsense_d435-1280x720": "realsense_d435"}


def load_frames(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """Depth frames of a sequence, of its ``-sparse`` variant, the Spot frame (``spot``), the
    Azure Kinect frame (``azure_kinect``) or the 1280×720 set (``realsense_d435-1280x720``)."""
    if name == "spot":
        return [load_spot_depth()]
    if name == "azure_kinect":
        return [load_azure_kinect_depth()]
    if name in _UPSAMPLED:
        return [upsample_720p(d) for d in load_depths(_UPSAMPLED[name], count)]
    if name.endswith("-sparse"):
        return [
            sparsify_depth(d, seed=i)
            for i, d in enumerate(load_depths(name.removesuffix("-sparse"), count))
        ]
    return load_depths(name, count)


#: Every depth test set: the sequences, their sparse variants and the Spot frame.
DEPTH_SETS = [*SEQUENCES, *(f"{n}-sparse" for n in SEQUENCES), "spot"]

#: :data:`DEPTH_SETS` and two more sensors' frame sizes: the Azure Kinect ToF frame
#: (640×576) and D435 frames upsampled to 1280×720.
ALL_DEPTH_SETS = [*DEPTH_SETS, "azure_kinect", *_UPSAMPLED]


def set_present(name: str) -> bool:
    """Whether the data of depth set ``name`` (one of :data:`ALL_DEPTH_SETS`) is present."""
    if name == "spot":
        return SPOT_BAG.is_file()
    if name == "azure_kinect":
        return AZURE_KINECT_MKV.is_file()
    base = _UPSAMPLED.get(name, name.removesuffix("-sparse"))
    return SEQUENCES[base].present
