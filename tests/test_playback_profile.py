"""scripts/playback_profile.py: the steps of a played frame, on two frames of the sample."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script() -> ModuleType:
    path = REPO / "scripts" / "playback_profile.py"
    spec = importlib.util.spec_from_file_location("playback_profile", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["playback_profile"] = module
    spec.loader.exec_module(module)
    return module


def test_profile_reports_every_step(script: ModuleType, tmp_path: Path) -> None:
    seq = script.load("sample", 2)
    path = script.write(seq, tmp_path / "two.pcdc", "depthac")
    result = script.profile(path, rounds=1)
    assert result["frames"] == 2
    assert set(result["steps"]) == set(script.STEPS)
    assert result["total_ms"] > 0
    assert result["fps"] == pytest.approx(1000 / result["total_ms"])
    for step in ("open", "record reading", "color decode", "depth decode", "point cloud"):
        assert result["steps"][step] > 0, step
    text = script.table("sample", "depthac", result)
    assert "depth decode" in text
    assert "fps (one core)" in text


def test_main_runs_on_the_sample(script: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["--sets", "sample", "--frames", "2", "--rounds", "1", "--depth", "jpegxl"]
    assert script.main(args) == 0
    out = capsys.readouterr().out
    assert "sample, depth=jpegxl: 2 frames" in out
    assert "point cloud" in out
