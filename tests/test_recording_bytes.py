"""scripts/recording_bytes.py: every byte of a recording in exactly one category, and the payloads
as the writer counted them."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

import pcdcodec
from pcdcodec.datasets import load_sample

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script() -> ModuleType:
    path = REPO / "scripts" / "recording_bytes.py"
    spec = importlib.util.spec_from_file_location("recording_bytes", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["recording_bytes"] = module
    spec.loader.exec_module(module)
    return module


def test_payloads_are_what_the_writer_wrote(script: ModuleType, tmp_path: Path) -> None:
    seq = load_sample(max_frames=4)
    path = tmp_path / "rec.pcdc"
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
        for k, frame in enumerate(seq):
            w.write(frame.color, frame.depth, pose=frame.pose if k % 2 else None)
    result = script.breakdown(path)
    parts = result["bytes"]
    assert sum(parts.values()) == result["size"] == path.stat().st_size
    assert result["frames"] == 4
    assert parts["color packets"] == w.bytes_color
    assert parts["depth frame bodies"] + parts["depth frame headers"] == w.bytes_depth
    assert parts["depth frame headers"] == 4 * (28 + len("depthac"))
    assert parts["frame digest payloads"] == 4 * 100
    assert parts["pose payloads"] > 2 * 128  # two frames with a pose: matrix and transform
    assert "compressed chunk contents" not in parts


def test_main_prints_a_table(
    script: ModuleType, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    seq = load_sample(max_frames=2)
    path = tmp_path / "rec.pcdc"
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
        w.write_frames(seq)
    results = script.main([str(path)])
    out = capsys.readouterr().out
    assert "| **overhead** |" in out
    assert results[str(path)]["overhead_per_frame"] > 0
