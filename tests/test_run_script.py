"""``scripts/run``: each job installs what it needs. The demo gets the package and its core
dependencies; the tests and benchmarks the ``dev`` extras too (CI runs ``scripts/run test``).

The script runs in a copy of the repository's ``scripts/run`` and ``pyproject.toml`` whose
``.venv`` holds stand-ins that log their arguments instead of installing anything.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

_STAND_IN = """#!/usr/bin/env bash
echo "$(basename "$0") $*" >> "{log}"
case "$*" in
  *"import torch"*) exit 1 ;;
esac
exit 0
"""


def _executable(path: Path, text: str) -> None:
    path.write_text(text)
    path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)


@pytest.fixture
def checkout(tmp_path: Path) -> tuple[Path, Path, dict[str, str]]:
    if shutil.which("bash") is None or shutil.which("sha256sum") is None:
        pytest.skip("scripts/run needs bash and sha256sum")
    root = tmp_path / "repo"
    (root / "scripts").mkdir(parents=True)
    shutil.copy2(REPO / "scripts" / "run", root / "scripts" / "run")
    shutil.copy2(REPO / "pyproject.toml", root / "pyproject.toml")
    log = tmp_path / "calls.log"
    log.touch()
    bin_dir = root / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    for name in ("python", "pcdcodec", "ruff", "mypy"):
        _executable(bin_dir / name, _STAND_IN.format(log=log))
    # The system libraries open3d needs, as ldconfig would list them.
    tools = tmp_path / "tools"
    tools.mkdir()
    _executable(tools / "ldconfig", "#!/bin/sh\necho libusb-1.0.so.0 libgomp.so.1\n")
    env = dict(os.environ, PATH=f"{tools}{os.pathsep}{os.environ['PATH']}", PYTHON=sys.executable)
    return root, log, env


def _run(checkout: tuple[Path, Path, dict[str, str]], *args: str) -> list[str]:
    """The stand-ins' calls made by ``scripts/run ARGS``."""
    root, log, env = checkout
    before = len(log.read_text().splitlines())
    out = subprocess.run(
        ["bash", str(root / "scripts" / "run"), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    return log.read_text().splitlines()[before:]


def _installs(calls: list[str]) -> list[str]:
    return [c for c in calls if "pip install" in c and "--upgrade pip" not in c]


def test_the_demo_installs_the_core_dependencies_only(
    checkout: tuple[Path, Path, dict[str, str]],
) -> None:
    calls = _run(checkout, "demo", "--frames", "3")
    assert _installs(calls) == ["python -m pip install -q -e ."]
    assert not any("torch" in c or "[dev]" in c for c in calls)
    assert calls[-1] == "pcdcodec demo --frames 3"
    # Installed once: a second demo installs nothing.
    assert _installs(_run(checkout, "demo")) == []


def test_the_tests_add_the_dev_extras_and_run_as_ci_does(
    checkout: tuple[Path, Path, dict[str, str]],
) -> None:
    _run(checkout, "demo")
    calls = _run(checkout, "test", "-x")
    assert _installs(calls) == [
        "python -m pip install -q torch==2.13.0+cpu",
        "python -m pip install -q -e .[dev]",
    ]
    assert calls[-4:] == [
        "ruff check pcdcodec tests benchmarks examples",
        "ruff format --check pcdcodec tests benchmarks examples",
        "mypy ",
        "python -m pytest -q --benchmark-disable -x",
    ]
    # The dev install holds the core one: neither job installs again.
    assert _installs(_run(checkout, "demo")) == []
    assert _installs(_run(checkout, "test")) == []
    assert _installs(_run(checkout, "bench")) == []
