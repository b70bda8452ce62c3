"""scripts/depthac_model_costs.py: its count of today's decisions matches the real coder."""

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
    path = REPO / "scripts" / "depthac_model_costs.py"
    spec = importlib.util.spec_from_file_location("depthac_model_costs", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["depthac_model_costs"] = module
    spec.loader.exec_module(module)
    return module


def crop() -> np.ndarray:
    return np.ascontiguousarray(load_frames("sample", 1)[0][160:320, 240:440])


@pytest.mark.parametrize("holes", [True, False], ids=["holes", "no holes"])
def test_counted_bits_match_the_coded_size(script: ModuleType, holes: bool) -> None:
    depth = crop()
    if not holes:
        depth = np.where(depth > 0, depth, 4000).astype(np.uint16)
    result = script.costs(depth)
    # The counted decisions are the body less its flags byte, the value table and the coder's
    # final bytes: within a few percent of it, and never above it by more than rounding.
    assert 0.85 * result["real"] < result["counted"] <= result["real"] + 4
    assert result["counted"] >= result["residual"] > 0
    for key in (
        "tokens",
        "nz-token/q",
        "nz-token/q+signs",
        "nz-token/ctx",
        "two halves",
        "slower adaptation",
    ):
        assert 0.5 * result["residual"] < result[key] < 2 * result["residual"], key


def test_two_halves_cost_more_than_one_model(script: ModuleType) -> None:
    # Learning the models twice can only cost bits on a real frame.
    result = script.costs(crop())
    assert result["two halves"] > result["residual"]


def test_main_prints_a_row_per_set(script: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    assert script.main(["--sets", "sample", "--frames", "1"]) == 0
    out = capsys.readouterr().out
    assert "| sample |" in out
    row = next(line for line in out.splitlines() if line.startswith("| sample |"))
    assert len(row.split("|")) == 11
