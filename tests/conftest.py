"""Shared fixtures: the bundled sample and, when present, the real sequences in ../shared/data."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"
SAMPLE = REPO / "pcdcodec" / "data" / "tum_fr1_rpy"


@dataclass(frozen=True)
class Sequence:
    """A real RGB-D sequence: where its depth lives and how to read it."""

    name: str
    root: Path
    depth_glob: str
    depth_scale: float
    color_glob: str = "rgb/*.png"

    @property
    def present(self) -> bool:
        return self.root.is_dir() and any(self.root.glob(self.depth_glob))

    def depth_paths(self) -> list[Path]:
        return sorted(self.root.glob(self.depth_glob))


SEQUENCES = {
    "sample": Sequence("sample", SAMPLE, "depth/*.png", 5000.0),
    "tum_fr1_rpy": Sequence("tum_fr1_rpy", SHARED_DATA / "tum_fr1_rpy", "depth/*.png", 5000.0),
    "realsense_d435": Sequence(
        "realsense_d435", SHARED_DATA / "realsense_d435_office", "depth/*.png", 1000.0
    ),
    "7scenes_redkitchen": Sequence(
        "7scenes_redkitchen",
        SHARED_DATA / "7scenes_redkitchen",
        "depth/*.depth.png",
        1000.0,
        "rgb/*.color.jpg",
    ),
}
SHARED_SEQUENCES = [name for name in SEQUENCES if name != "sample"]


def read_png(path: Path) -> np.ndarray[Any, Any]:
    import imagecodecs

    return np.asarray(imagecodecs.png_decode(path.read_bytes()))


_cache: dict[tuple[str, int], list[np.ndarray[Any, Any]]] = {}


def load_depths(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """``count`` depth frames spread evenly over sequence ``name``; skips when it is absent."""
    seq = SEQUENCES[name]
    if not seq.present:
        pytest.skip(f"{seq.root} is not present")
    key = (name, count)
    if key not in _cache:
        paths = seq.depth_paths()
        picks = np.linspace(0, len(paths) - 1, min(count, len(paths))).round().astype(int)
        _cache[key] = [read_png(paths[i]) for i in sorted(set(picks))]
    return _cache[key]


_color_cache: dict[tuple[str, int], list[np.ndarray[Any, Any]]] = {}


def load_colors(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """The first ``count`` consecutive RGB frames of sequence ``name``; skips when absent."""
    import imagecodecs

    seq = SEQUENCES[name]
    if not seq.present:
        pytest.skip(f"{seq.root} is not present")
    key = (name, count)
    if key not in _color_cache:
        paths = sorted(seq.root.glob(seq.color_glob))[:count]
        _color_cache[key] = [np.asarray(imagecodecs.imread(str(p)))[..., :3] for p in paths]
    return _color_cache[key]


def to_metres(depth: np.ndarray[Any, Any], scale: float) -> np.ndarray[Any, Any]:
    """float32 metres with NaN for no measurement, as ROS 32FC1 depth images are."""
    metres = (depth / scale).astype(np.float32)
    metres[depth == 0] = np.nan
    return metres


@pytest.fixture(scope="session")
def sample_depths() -> list[np.ndarray[Any, Any]]:
    return load_depths("sample", 15)


SPOT_BAG = SHARED_DATA / "bags" / "spot" / "raw.bag"
SPOT_TOPIC = "/spot/depth/frontleft/image"


def load_spot_depth() -> np.ndarray[Any, Any]:
    """The one Spot front-left depth frame (424×240 16UC1, mm, 36 % holes); skips when absent."""
    if not SPOT_BAG.is_file():
        pytest.skip(f"{SPOT_BAG} is not present")
    if "spot" not in _cache:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        typestore = get_typestore(Stores.ROS1_NOETIC)
        with AnyReader([SPOT_BAG], default_typestore=typestore) as reader:
            conns = [c for c in reader.connections if c.topic == SPOT_TOPIC]
            _, _, raw = next(iter(reader.messages(connections=conns)))
            msg = reader.deserialize(raw, conns[0].msgtype)
        order = ">u2" if msg.is_bigendian else "<u2"
        image = np.frombuffer(bytes(msg.data), order).reshape(msg.height, msg.width)
        _cache["spot"] = [np.ascontiguousarray(image, dtype=np.uint16)]
    return _cache["spot"][0]


def sparsify_depth(depth: np.ndarray[Any, Any], seed: int = 0) -> np.ndarray[Any, Any]:
    """Real depth with large regions removed the way active depth sensors lose them.

    Deterministic for a given ``seed``. Four physical causes are imitated, each on the image
    itself (so edges and surfaces stay the sensor's own):

    * **range limit**: everything beyond the 75th percentile of the valid depth is dropped
      (the projector's pattern is too faint far away);
    * **dark and shiny surfaces**: smooth blobs covering about a third of the view are
      dropped (a low-frequency random field, thresholded: absorbing or specular materials
      return no pattern);
    * **occlusion shadows**: on the far side of every depth step of more than 8 % a band of
      12 pixels is dropped (the projector does not see behind the near object's edge);
    * **edge speckle**: half the pixels within 2 pixels of a step are dropped at random
      (mixed pixels the sensor's filters reject).

    The result keeps 35–50 % of the pixels of a dense frame, like a RealSense looking at
    a cluttered scene with dark and glossy objects.
    """
    rng = np.random.default_rng(seed)
    d = np.asarray(depth)
    h, w = d.shape
    out = d.copy()
    valid = d > 0
    if not valid.any():
        return out
    drop = d > np.percentile(d[valid], 75)
    # A smooth random field: a coarse grid of noise, upsampled bilinearly.
    gh, gw = max(2, h // 60 + 2), max(2, w // 60 + 2)
    grid = rng.standard_normal((gh, gw))
    ys = np.linspace(0, gh - 1, h)
    xs = np.linspace(0, gw - 1, w)
    y0 = np.minimum(ys.astype(int), gh - 2)
    x0 = np.minimum(xs.astype(int), gw - 2)
    fy = (ys - y0)[:, None]
    fx = (xs - x0)[None, :]
    field = (
        grid[y0][:, x0] * (1 - fy) * (1 - fx)
        + grid[y0 + 1][:, x0] * fy * (1 - fx)
        + grid[y0][:, x0 + 1] * (1 - fy) * fx
        + grid[y0 + 1][:, x0 + 1] * fy * fx
    )
    drop |= field > np.quantile(field, 0.67)
    # Depth steps: the far side of a jump between horizontal neighbours.
    left = d[:, :-1].astype(np.float64)
    right = d[:, 1:].astype(np.float64)
    both = (left > 0) & (right > 0)
    far_right = both & (right > left * 1.08)
    far_left = both & (left > right * 1.08)
    step = np.zeros_like(valid)
    step[:, 1:] |= far_right
    step[:, :-1] |= far_left
    shadow = np.zeros_like(valid)
    for k in range(12):
        shadow[:, 1 + k :] |= far_right[:, : w - 1 - k]
    drop |= shadow
    near = step.copy()
    for k in (1, 2):
        near[:, k:] |= step[:, :-k]
        near[:, :-k] |= step[:, k:]
        near[k:, :] |= step[:-k, :]
        near[:-k, :] |= step[k:, :]
    drop |= near & (rng.random((h, w)) < 0.5)
    out[drop] = 0
    return out


def load_frames(name: str, count: int) -> list[np.ndarray[Any, Any]]:
    """Depth frames of a sequence, of its ``-sparse`` variant, or the Spot frame (``spot``)."""
    if name == "spot":
        return [load_spot_depth()]
    if name.endswith("-sparse"):
        return [
            sparsify_depth(d, seed=i)
            for i, d in enumerate(load_depths(name.removesuffix("-sparse"), count))
        ]
    return load_depths(name, count)


#: Every depth test set: the sequences, their sparse variants and the Spot frame.
DEPTH_SETS = [*SEQUENCES, *(f"{n}-sparse" for n in SEQUENCES), "spot"]
