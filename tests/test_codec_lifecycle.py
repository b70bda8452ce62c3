"""Codecs are created, used and dropped without deadlocks: a short run of the stress script.

``scripts/stress_codecs.py`` writes, reads twice, reads at random, verifies, exports and drops
recordings of every stream codec under a watchdog that dumps every thread's stack on a hang.
Reading an AV1 recording twice used to deadlock (a dav1d worker freeing a Python-owned packet
needed the GIL that the main thread held while freeing the decoder); the AV1 case below hung
on its first run before packets were handed to FFmpeg in memory it owns.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import pcdcodec

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "stress_codecs.py"


def _stress(*args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=timeout
    )


def test_every_stream_codec_is_created_and_dropped_without_a_hang() -> None:
    result = _stress("--runs", "1", "--frames", "12", "--size", "160x120", "--timeout", "120")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "1 runs without a hang" in result.stdout


def test_av1_read_twice_does_not_deadlock() -> None:
    if not pcdcodec.codec_class("av1").is_available():
        pytest.skip("av1 is unavailable here")
    result = _stress(
        *("--runs", "1", "--codecs", "av1", "--size", "640x480", "--frames", "40"),
        *("--timeout", "120", "--no-export"),
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "1 runs without a hang" in result.stdout


def test_the_watchdog_dumps_every_thread_on_a_timeout() -> None:
    result = _stress("--runs", "1", "--codecs", "ffv1", "--frames", "40", "--timeout", "0.01")
    # The watchdog stops the process after the dump (exit status 1); reading other threads'
    # stacks while they run can also end it with a signal once the dump is out.
    assert result.returncode != 0
    assert "Timeout (0:00:00.01" in result.stderr
    assert "most recent call first" in result.stderr
