"""The pytest plugin: a user's ten-line benchmark file on their own folder gives ratios, bytes
per frame, PSNR and depth error beside pytest-benchmark's timings."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from pcdcodec.testing import codec_label, format_summary, load_rgbd

REPO = Path(__file__).resolve().parents[1]


def _pytest(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "pcdcodec.bench.pytest_plugin", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
        check=False,
    )


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder the project has never seen: rgb/ + depth/ images, no lists."""
    root = tmp_path_factory.mktemp("mine")
    sample = pcdcodec.datasets.sample_dir()
    for sub in ("rgb", "depth"):
        (root / sub).mkdir()
        for p in sorted((sample / sub).iterdir())[:4]:
            shutil.copy(p, root / sub / p.name)
    return root


def test_user_benchmark_file_prints_the_columns(tmp_path: Path, user_folder: Path) -> None:
    shutil.copy(REPO / "examples" / "benchmark_my_data.py", tmp_path / "bench_mine.py")
    out = _pytest(
        "bench_mine.py",
        f"--pcdcodec-data=office={user_folder}",
        "--pcdcodec-depth-scale=5000",
        "--pcdcodec-codecs=zstd,rvl,h264,ffv1",
        "--pcdcodec-frames=3",
        "--benchmark-only",
        "--benchmark-min-rounds=1",
        "--benchmark-max-time=0.001",
        "--benchmark-warmup=off",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    text = out.stdout
    assert "4 passed" in text  # zstd, rvl; h264, ffv1
    assert "test_depth[office-zstd]" in text
    depth_table = text.split("depth codecs:", 1)[1].split("color codecs:", 1)[0]
    assert "| office" in depth_table
    assert "KiB/frame" in depth_table
    assert "encode ms" in depth_table
    assert "bit-exact (max error 0)" in depth_table
    color_table = text.split("color codecs:", 1)[1]
    assert "PSNR dB" in color_table
    ffv1 = next(line for line in color_table.splitlines() if "| ffv1" in line)
    assert "inf" in ffv1  # lossless
    h264 = next(line for line in color_table.splitlines() if "| h264" in line)
    assert 25 < float(h264.split("|")[5]) < 60  # PSNR in dB


def test_marker_parametrises_given_codecs(tmp_path: Path) -> None:
    (tmp_path / "test_mark.py").write_text(
        "import pytest\n"
        "from pcdcodec.testing import record_depth\n"
        "@pytest.mark.pcdcodec_codecs('lz4', {'id': 'zstd', 'level': 9})\n"
        "def test_it(benchmark, rgbd_sequence, depth_codec):\n"
        "    record_depth(benchmark, depth_codec, rgbd_sequence)\n"
        "    assert benchmark.extra_info['ratio'] > 1\n"
        "    assert benchmark.extra_info['max_depth_error'] == 0\n"
        "    benchmark(lambda: None)\n"
    )
    out = _pytest("-v", "--pcdcodec-frames=2", "--benchmark-disable", cwd=tmp_path)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "test_it[sample-lz4] PASSED" in out.stdout
    assert "test_it[sample-zstd] PASSED" in out.stdout


def test_missing_data_path_is_a_usage_error(tmp_path: Path) -> None:
    shutil.copy(REPO / "examples" / "benchmark_my_data.py", tmp_path / "bench_mine.py")
    out = _pytest("bench_mine.py", "--pcdcodec-data", str(tmp_path / "nope"), cwd=tmp_path)
    assert out.returncode != 0
    assert "nope" in out.stdout + out.stderr


def test_helpers_in_process() -> None:
    seq = load_rgbd(None, 2)
    assert len(seq) == 2
    assert seq.name == "sample"
    assert codec_label(pcdcodec.get_codec("zstd")) == "zstd"
    assert codec_label(pcdcodec.get_codec("zstd", level=9)) == "zstd(level=9)"

    class Stats:
        median = 0.002

    class Bench:
        def __init__(self, info: dict[str, Any]) -> None:
            self.extra_info = info
            self.stats = Stats()

    info = {"pcdcodec": "depth", "codec": "zstd", "sequence": "s", "frames": 2}
    rows = [
        Bench({**info, "ratio": 4.0, "bytes_per_frame": 2048, "max_depth_error": 0.0, "op": op})
        for op in ("encode", "decode")
    ]
    lines = format_summary(rows)
    row = next(line for line in lines if "| zstd" in line)
    assert row.split("|")[3].strip() == "4.00"
    assert row.split("|")[4].strip() == "2.0"
    assert row.split("|")[5].strip() == row.split("|")[6].strip() == "2.00"
    lossy = [Bench({**info, "ratio": 9.0, "bytes_per_frame": 1024, "max_depth_error": 3.0})]
    assert "max err" in "\n".join(format_summary(lossy))


def test_docs_show_the_example() -> None:
    doc = (REPO / "docs" / "benchmarking.md").read_text()
    block = doc.split("```python\n", 1)[1].split("```", 1)[0]
    assert block == (REPO / "examples" / "benchmark_my_data.py").read_text()


def test_benchmarks_stand_alone_and_core_does_not_load_the_plugin() -> None:
    for path in (REPO / "benchmarks").glob("*.py"):
        assert "tests.conftest" not in path.read_text(), path
    code = (
        "import sys, pcdcodec, pcdcodec.recording;"
        "print(any(m.startswith(('pcdcodec.bench', 'pytest')) for m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
