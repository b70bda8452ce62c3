"""Shared fixtures: the bundled sample and, when present, the real sequences in ../shared/data."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

# The sequences and their loaders are shared with the benchmarks, so both read the same frames.
from pcdcodec.bench.sequences import (
    REPO,
    SAMPLE,
    SEQUENCES,
    SHARED_DATA,
    load_colors,
    load_depths,
)

__all__ = [
    "REPO",
    "SAMPLE",
    "SEQUENCES",
    "SHARED_DATA",
    "SHARED_SEQUENCES",
    "load_colors",
    "load_depths",
    "to_metres",
]

SHARED_SEQUENCES = [name for name in SEQUENCES if name != "sample"]


def to_metres(depth: np.ndarray[Any, Any], scale: float) -> np.ndarray[Any, Any]:
    """float32 metres with NaN for no measurement, as ROS 32FC1 depth images are."""
    metres = (depth / scale).astype(np.float32)
    metres[depth == 0] = np.nan
    return metres


@pytest.fixture(scope="session")
def sample_depths() -> list[np.ndarray[Any, Any]]:
    return load_depths("sample", 15)
