"""The examples run as a user runs them and do what they say."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(script: str, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=cwd,
        timeout=600,
    )


def test_roundtrip_sample(tmp_path: Path) -> None:
    out = run("roundtrip_sample.py", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    for name in ("jpegxl", "lz4", "png16", "rvl", "zstd"):
        assert f"{name} " in out.stdout
    assert "NO" not in out.stdout.split("bit-exact", 1)[1]


def test_record_and_replay(tmp_path: Path) -> None:
    target = tmp_path / "s.pcdc"
    out = run("record_and_replay.py", str(target), cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert target.exists()
    assert "depth bit-exact in every frame" in out.stdout
    assert "index 7" in out.stdout


def test_compare_codecs(tmp_path: Path) -> None:
    out = run("compare_codecs.py", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "Table IV" in out.stdout
    assert (tmp_path / "codec-report" / "stream_sizes.png").exists()
