"""scripts/color_table.py: the color codec table at the default's quality, on a few frames."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script() -> ModuleType:
    path = REPO / "scripts" / "color_table.py"
    spec = importlib.util.spec_from_file_location("color_table", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["color_table"] = module
    spec.loader.exec_module(module)
    return module


def test_search_crf_finds_the_largest_setting_that_meets_the_target(script: ModuleType) -> None:
    for edge in (0, 1, 17, 30, 51):
        asked: list[int] = []

        def meets(c: int, edge: int = edge, asked: list[int] = asked) -> bool:
            asked.append(c)
            return c <= edge

        assert script.search_crf(meets, 0, 51, 22) == edge
        assert len(asked) <= 12
    assert script.search_crf(lambda c: False, 0, 51, 22) is None


def test_table_on_the_sample(script: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "table.json"
    result = script.main(
        ["--sets", "sample", "--frames", "6", "--gops", "30", "--rounds", "1", "--json", str(out)]
    )
    assert json.loads(out.read_text()) == json.loads(json.dumps(result))
    info = result["sets"]["sample"]
    assert info["frames"] == 6
    assert 0 < info["depth_bytes_per_frame"] < 640 * 480 * 2
    assert info["overhead_bytes_per_frame"] > 0
    assert info["pointcloud2_bytes_per_frame"] == 32 * info["valid_points"]
    rows = info["gops"]["30"]
    assert set(rows) == {"h264", "h265", "av1", "vp9"}
    ref = rows["h264"]
    assert ref["crf"] == 18
    for label, row in rows.items():
        # No candidate holds a frame back, and each is at least the default's quality.
        assert row["held"] == 0, label
        assert row["psnr"] >= ref["psnr"], label
        assert row["ssim"] >= ref["ssim"], label
        assert row["keyframes"] == 1, label
        # PSNR alone allows the same crf or a larger one; the size at equal PSNR lies between.
        assert row["psnr_only"]["crf"] >= row["crf"], label
        assert row["psnr_only"]["psnr"] >= ref["psnr"], label
        assert row["bytes_at_equal_psnr"] <= row["psnr_only"]["bytes_per_frame"] + 1e-9, label
        total = row["bytes_per_frame"] + info["depth_bytes_per_frame"]
        total += info["overhead_bytes_per_frame"]
        assert row["ratio"] == pytest.approx(info["pointcloud2_bytes_per_frame"] / total)
    common = result["common"]["30"]
    assert set(common) == {"h264", "h265", "av1", "vp9"}
    assert common["h264"]["wins"] is False
    for label, row in common.items():
        measured = row["sets"]["sample"]
        assert measured["crf"] == row["crf"] == rows[label]["crf"]
        assert measured["encode_fps"] > 0
        assert measured["decode_fps"] > 0
        assert measured["quality_no_worse"] is True
        assert isinstance(row["wins"], bool)
    assert list(common["h264"]["sets"]["sample"]["encode_vs_h264"]) == [1.0, 1.0]
