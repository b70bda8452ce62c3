"""The lossy depth rate-distortion comparison (``pcdcodec bench --depth-rd``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pcdcodec.bench.depth_rd import (
    METHODS,
    available_methods,
    depth_rd,
    plot_depth_rd,
    rd_markdown,
    write_rd_csv,
)
from pcdcodec.errors import InputError


def _crops(sample_depths: list[Any]) -> list[Any]:
    return [np.ascontiguousarray(d[160:256, 240:368]) for d in sample_depths[:3]]


def test_every_method_runs_and_ours_keeps_its_bound(
    sample_depths: list[Any], tmp_path: Path
) -> None:
    frames = _crops(sample_depths)
    methods = available_methods()
    assert "depthac bounded (ours)" in methods
    points = depth_rd(frames, 5000.0, sequence="crop", methods=methods)
    assert len(points) == sum(len(METHODS[m][2]) for m in methods)
    for p in points:
        assert p.frames == 3
        assert p.ratio > 1
        assert p.bytes_per_frame > 0
    ours = [p for p in points if p.method == "depthac bounded (ours)"]
    for p in ours:
        rel = float(p.setting.split("=")[1])
        assert p.max_rel_error <= rel
        assert p.holes_created == 0
        assert p.holes_filled == 0
    assert ours[-1].ratio > ours[0].ratio  # a looser bound compresses more
    if "LERC" in methods:
        for p in (p for p in points if p.method == "LERC"):
            assert p.max_error_m <= float(p.setting.split("=")[1]) + 1e-9
    table = rd_markdown(points)
    assert table.count("\n") == len(points) + 1
    csv = write_rd_csv(points, tmp_path / "rd.csv").read_text().splitlines()
    assert len(csv) == len(points) + 1
    png = plot_depth_rd(points, tmp_path / "rd.png", title="crop")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_bad_input_is_refused(sample_depths: list[Any]) -> None:
    frames = _crops(sample_depths)
    with pytest.raises(InputError, match="at least one frame"):
        depth_rd([], 5000.0)
    with pytest.raises(InputError, match="uint16"):
        depth_rd([f.astype(np.float32) for f in frames], 5000.0)
    with pytest.raises(InputError, match="unknown depth RD method"):
        depth_rd(frames, 5000.0, methods=["gzip"])
    with pytest.raises(InputError, match="depth_scale"):
        depth_rd(frames, 0.0)


def test_cli_depth_rd(tmp_path: Path) -> None:
    from pcdcodec.datasets import sample_dir

    out = tmp_path / "rd"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pcdcodec",
            "bench",
            str(sample_dir()),
            "--depth-rd",
            "--frames",
            "1",
            "-q",
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "depthac bounded (ours)" in result.stdout
    assert (out / "depth_rd.csv").is_file()
    assert (out / "depth_rd.png").is_file()


def test_cli_depth_rd_takes_a_depth_only_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import pcdcodec
    from pcdcodec.cli import main
    from pcdcodec.datasets import load_sample

    seq = load_sample(max_frames=2)
    path = tmp_path / "depth_only.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=None
    ) as rec:
        for frame in seq:
            rec.write(None, frame.depth, frame.timestamp_ns)
    assert main(["bench", str(path), "--depth-rd", "--frames", "1", "-q", "--no-plots"]) == 0
    assert "depthac bounded (ours)" in capsys.readouterr().out
    # The whole-stream comparison still needs color, and says so.
    assert main(["bench", str(path), "--frames", "1", "-q"]) == 1
    assert "no color stream" in capsys.readouterr().err


def test_bench_reads_a_bag_as_encode_does() -> None:
    from pcdcodec.bench.evaluation import frames_of
    from tests.conftest import SHARED_DATA

    bag = SHARED_DATA / "bags" / "spot" / "raw.bag"
    if not bag.is_file():
        pytest.skip("the Spot bag of ../shared/data is not present")
    import pcdcodec

    cam = pcdcodec.CameraIntrinsics(424, 240, 300.0, 300.0, 212.0, 120.0)
    name, frames, intrinsics, scale = frames_of(bag, 1, cam, None, need_color=False)
    assert name == "raw"
    assert len(frames) == 1
    assert frames[0].depth.shape == (240, 424)
    assert intrinsics == cam
    assert scale > 0
