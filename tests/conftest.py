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
