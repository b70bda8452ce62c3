"""scripts/depthac_profile.py: its decoder variants reproduce the real decoder on small frames."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from pcdcodec.bench.sequences import load_frames

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script() -> ModuleType:
    path = REPO / "scripts" / "depthac_profile.py"
    spec = importlib.util.spec_from_file_location("depthac_profile", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["depthac_profile"] = module
    spec.loader.exec_module(module)
    return module


def frames() -> dict[str, np.ndarray]:
    depth = np.ascontiguousarray(load_frames("sample", 1)[0][200:260, 300:380])
    ramp = (np.arange(60 * 80, dtype=np.uint16) * 7 + 100).reshape(60, 80)
    return {
        "holes and value table": depth,
        "no holes": np.where(depth > 0, depth, 4000).astype(np.uint16),
        "no value table": ramp,
    }


@pytest.mark.parametrize("name", list(frames()))
def test_every_variant_checks_out_and_the_steps_are_reported(script: ModuleType, name: str) -> None:
    depth = frames()[name]
    # profile() asserts that the traced decode, every ladder stage and the replays reproduce
    # the real decoder's output and bits before it times anything.
    result = script.profile(depth, rounds=1)
    assert "binary decisions" in result["steps"]
    assert result["times"]["decode"] > 0
    decisions = result["decisions"]
    assert decisions["mask"] == (1.0 if (depth == 0).any() else 0.0)
    assert decisions["zero"] == pytest.approx((depth > 0).mean())
    assert result["bytes"] > 0
