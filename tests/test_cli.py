"""The command-line tool, run as a user runs it."""

from __future__ import annotations

import subprocess
import sys

import pcdcodec


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pcdcodec", *args], capture_output=True, text=True, check=False
    )


def test_codecs_lists_every_codec_with_its_defaults() -> None:
    out = run("codecs")
    assert out.returncode == 0, out.stderr
    for name in pcdcodec.list_codecs():
        assert f"  {name} " in out.stdout
    assert "effort=2" in out.stdout
    assert "crf=18" in out.stdout


def test_codecs_of_one_kind() -> None:
    out = run("codecs", "--kind", "depth")
    assert out.returncode == 0
    assert "jpegxl" in out.stdout
    assert "h264" not in out.stdout


def test_bad_arguments_exit_non_zero_with_a_message() -> None:
    out = run("codecs", "--kind", "video")
    assert out.returncode == 2
    assert "invalid choice: 'video'" in out.stderr
    assert run().returncode == 2


def test_version() -> None:
    out = run("--version")
    assert out.returncode == 0
    assert pcdcodec.__version__ in out.stdout
