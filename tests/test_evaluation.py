"""pcdcodec.evaluate and `pcdcodec bench`: a tiny sequence, end to end."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.results import default_setting
from pcdcodec.datasets import RGBDSequence, load_sample, sample_dir

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def tiny() -> RGBDSequence:
    return load_sample(max_frames=4)


@pytest.fixture(scope="module")
def evaluation(tiny: RGBDSequence) -> pcdcodec.Evaluation:
    return pcdcodec.evaluate(tiny, depth=["lz4", "jpegxl"], color=["h264", "ffv1"], frames=4)


def test_rows_and_ratios_are_consistent(evaluation: pcdcodec.Evaluation) -> None:
    ev = evaluation
    assert (ev.frames, ev.width, ev.height) == (4, 640, 480)
    assert [d.codec for d in ev.depth] == ["lz4", "jpegxl"]
    for d in ev.depth:
        assert d.exact
        assert d.exact_fraction == 1.0
        assert d.cloud_rmse_m == 0.0
        assert d.ratio_uint16 == pytest.approx(640 * 480 * 2 / d.bytes_per_frame)
        assert d.ratio_float32 == pytest.approx(2 * d.ratio_uint16)
        assert d.ratio_float32_input is not None
        assert d.encode_ms > 0
        assert d.decode_ms > 0
    lz4, jxl = ev.depth
    assert jxl.ratio_uint16 > 3 * lz4.ratio_uint16  # JPEG XL's lead on real depth
    h264, ffv1 = ev.color
    assert ffv1.lossless
    assert ffv1.psnr == float("inf")
    assert ffv1.ssim == pytest.approx(1.0)
    assert 30 < h264.psnr < 60
    assert 0.8 < h264.ssim < 1.0
    assert h264.bits_per_pixel == pytest.approx(8 * h264.bytes_per_frame / (640 * 480))
    assert len(ev.streams) == 4
    for s in ev.streams:
        c = next(r for r in ev.color if r.codec == s.color)
        d = next(r for r in ev.depth if r.codec == s.depth)
        assert s.bytes_per_frame == pytest.approx(c.bytes_per_frame + d.bytes_per_frame)
        assert s.ratio_pointcloud2 == pytest.approx(640 * 480 * 32 / s.bytes_per_frame)
        assert s.lossless == (s.color == "ffv1")
    # The rate-distortion sweep: more bits, better quality.
    rd = [p for p in ev.rd if p.codec == "h264"]
    assert len(rd) == 5
    rd.sort(key=lambda p: p.bits_per_pixel)
    assert rd[-1].psnr > rd[0].psnr


def test_report_tables(evaluation: pcdcodec.Evaluation) -> None:
    md = evaluation.to_markdown()
    for title in ("Table I", "Table II", "Table III", "Table IV"):
        assert title in md
    assert "| h264 | jpegxl |" in md
    assert "| ffv1 | lz4 |" in md


def test_written_files(evaluation: pcdcodec.Evaluation, tmp_path: Path) -> None:
    import imagecodecs

    written = evaluation.write(tmp_path)
    names = {p.name for p in written}
    assert {
        "report.md",
        "results.json",
        "depth.csv",
        "color.csv",
        "streams.csv",
        "rd.csv",
        "color_rd.png",
        "depth_ratio_speed.png",
        "stream_sizes.png",
    } <= names
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["frames"] == 4
    assert [d["codec"] for d in data["depth"]] == ["lz4", "jpegxl"]
    with (tmp_path / "streams.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4
    assert float(rows[0]["ratio_pointcloud2"]) > 1
    for png in ("color_rd.png", "depth_ratio_speed.png", "stream_sizes.png"):
        raw = (tmp_path / png).read_bytes()
        assert raw.startswith(PNG_MAGIC)
        image = np.asarray(imagecodecs.png_decode(raw))
        assert image.ndim == 3
        assert image.shape[0] > 200
        assert image.shape[1] > 300
        assert image.std() > 10  # not a blank canvas


def test_evaluate_a_recording(tmp_path: Path, tiny: RGBDSequence) -> None:
    path = tmp_path / "t.pcdc"
    with pcdcodec.open(path, "w", intrinsics=tiny.intrinsics, depth_scale=5000.0) as rec:
        rec.write_frames(tiny)
    ev = pcdcodec.evaluate(path, depth=["zstd"], color=["mjpeg"], rd=False)
    assert ev.frames == 4
    assert ev.depth[0].exact
    assert ev.rd == []


def test_bad_requests(tmp_path: Path, tiny: RGBDSequence) -> None:
    with pytest.raises(pcdcodec.UnknownCodecError, match="'lz5'"):
        pcdcodec.evaluate(tiny, depth=["lz5"])
    with pytest.raises(pcdcodec.UnknownCodecError, match="depth codec"):
        pcdcodec.evaluate(tiny, depth=["h264"])
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(pcdcodec.InputError, match="not an RGB-D folder"):
        pcdcodec.evaluate(empty)


def test_cli_bench_on_the_bundled_sample(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pcdcodec",
            "bench",
            str(sample_dir()),
            "--frames",
            "3",
            "--depth",
            "lz4,rvl",
            "--color",
            "h264",
            "--no-rd",
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    assert "Table II" in result.stdout
    assert "| rvl |" in result.stdout
    assert (out / "stream_sizes.png").read_bytes().startswith(PNG_MAGIC)
    assert not (out / "color_rd.png").exists()  # --no-rd: no sweep, no curve
    bad = subprocess.run(
        [sys.executable, "-m", "pcdcodec", "bench", str(sample_dir()), "--color", "h263"],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert bad.returncode == 1
    assert "unknown codec 'h263'" in bad.stderr


def test_peer_rows(tiny: RGBDSequence) -> None:
    pytest.importorskip("DracoPy")
    pytest.importorskip("rvl")
    ev = pcdcodec.evaluate(tiny, depth=["rvl"], color=["h264"], frames=2, rd=False, peers=True)
    names = [p["name"] for p in ev.peers]
    assert names.count("draco") == 2
    assert "rvl-pypi" in names
    rvl_peer = next(p for p in ev.peers if p["name"] == "rvl-pypi")
    assert rvl_peer["lossless"] is True
    # The peer RVL writes our bitstream plus a 4-byte pixel count.
    assert rvl_peer["bytes_per_frame"] > ev.depth[0].bytes_per_frame - 200
    assert "## Peers" in ev.to_markdown()


def _depth_row(codec: str, ratio: float, ms: float, exact: bool = True) -> Any:
    from pcdcodec.bench.evaluation import DepthRow

    err = 0.0 if exact else 0.002
    return DepthRow(
        codec, {"id": codec}, 4, 1000.0, ratio, 2 * ratio, None, ms, ms, exact,
        1.0 if exact else 0.5, err, err, err, err, err,
    )  # fmt: skip


def _color_row(codec: str, ratio: float, ms: float, lossless: bool) -> Any:
    from pcdcodec.bench.evaluation import ColorRow

    psnr = float("inf") if lossless else 35.0
    return ColorRow(codec, {"id": codec}, 4, 1000.0, 0.1, ratio, ms, ms, psnr, 0.9, lossless)


def test_recommendation_and_columns_constant_by_construction() -> None:
    from pcdcodec.bench.evaluation import Evaluation

    ev = Evaluation("s", 4, 640, 480)
    ev.depth = [_depth_row("jpegxl", 15.0, 4.0), _depth_row("lz4", 4.0, 0.5)]
    ev.color = [
        _color_row("h264", 70.0, 3.0, False),
        _color_row("av1", 90.0, 30.0, False),
        _color_row("ffv1", 2.8, 10.0, True),
    ]
    rec = ev.recommend()
    assert rec["depth"]["by ratio"].startswith("jpegxl (15.00x")
    assert rec["depth"]["by speed"].startswith("lz4 (1.0 ms")
    assert rec["color"]["by ratio"].startswith("av1 (90.0x, PSNR 35.00 dB)")
    assert rec["color"]["by speed"].startswith("h264")
    assert rec["lossless color"]["by ratio"].startswith("ffv1 (2.8x, exact)")
    text = ev.to_markdown()
    assert text.rstrip().splitlines()[-1].startswith("- lossless color: by ratio ffv1")
    table = text.split("## Table II", 1)[1].split("##", 1)[0]
    assert "RMSE" not in table  # every codec exact: the error columns would be all zero
    assert "float32 input" not in table
    assert "bit-exact" in table
    ev.depth.append(_depth_row("png16", 30.0, 2.0, exact=False))  # as if it were lossy
    table = ev.to_markdown().split("## Table II", 1)[1].split("##", 1)[0]
    assert "RMSE" in table
    assert "| png16 | 1.0 | 30.00 | 2.00 | 2.00 | no | 2.000" in table
    assert ev.recommend()["depth"]["by ratio"].startswith("jpegxl")  # inexact is not a pick
    assert "depth with an error bound" not in ev.recommend()  # png16 states no bound
    bounded = _depth_row("depthac", 50.0, 8.0, exact=False)
    bounded.config["max_rel_error"] = 0.005
    ev.depth.append(bounded)
    rec = ev.recommend()
    assert rec["depth"]["by ratio"].startswith("jpegxl")
    assert rec["depth with an error bound"]["by ratio"].startswith(
        "depthac (max_rel_error=0.005) (50.00x, largest error 2.0 mm)"
    )


def test_stream_rows_tell_a_bounded_depth_codec_from_the_lossless_one(tiny: RGBDSequence) -> None:
    ev = pcdcodec.evaluate(
        tiny,
        depth=["depthac", {"id": "depthac", "max_rel_error": 0.01}],
        color=["ffv1"],
        frames=3,
        rd=False,
    )
    rows = {row.depth: row for row in ev.streams}
    assert set(rows) == {"depthac", "depthac (max_rel_error=0.01)"}
    assert rows["depthac"].lossless
    assert not rows["depthac (max_rel_error=0.01)"].lossless
    assert rows["depthac (max_rel_error=0.01)"].bytes_per_frame < rows["depthac"].bytes_per_frame


def test_each_curve_passes_through_its_table_row_and_stars_the_default() -> None:
    # 12 frames: more than a short sweep would take, so a curve measured on fewer frames than
    # Table I would put its point elsewhere.
    seq = load_sample(max_frames=12)
    ev = pcdcodec.evaluate(seq, depth=["lz4"], color=["h264", {"id": "h265", "crf": 28}], frames=12)
    h264, h265 = ev.color
    assert h264.frames == h265.frames == 12
    curves = {name: {p.setting: p for p in ev.rd if p.codec == name} for name in ("h264", "h265")}
    # h264 at its default: the starred point is Table I's row.
    star = curves["h264"][default_setting("h264") or ""]
    assert (star.bits_per_pixel, star.psnr) == (h264.bits_per_pixel, h264.psnr)
    # h265 measured at crf=28: that point is its row; its default (crf=24) is on the curve too.
    assert default_setting("h265") == "crf=24"
    assert (curves["h265"]["crf=28"].bits_per_pixel, curves["h265"]["crf=28"].psnr) == (
        h265.bits_per_pixel,
        h265.psnr,
    )
    default = curves["h265"]["crf=24"]
    assert default.bits_per_pixel > h265.bits_per_pixel  # a lower crf spends more bits
    assert sorted(curves["h265"]) == ["crf=16", "crf=22", "crf=24", "crf=28", "crf=34"]


def test_the_color_codecs_people_choose_between_are_compared_by_default(tmp_path: Path) -> None:
    available = pcdcodec.list_codecs("color", available_only=True)
    expected = [name for name in ("h264", "h265", "av1") if name in available]
    assert "h264" in expected
    ev = pcdcodec.evaluate(load_sample(max_frames=2), depth=["lz4"], rd=False)
    assert [c.codec for c in ev.color] == expected
    assert [(s.color, s.depth) for s in ev.streams] == [(name, "lz4") for name in expected]
    command = ["bench", str(sample_dir()), "--frames", "2", "--depth", "lz4", "--no-rd", "-q"]
    result = subprocess.run(
        [sys.executable, "-m", "pcdcodec", *command],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    table = result.stdout.split("Table I:", 1)[1].split("Table II", 1)[0]
    assert [line.split("|")[1].strip() for line in table.splitlines() if line.startswith("| ")][
        1:
    ] == expected
