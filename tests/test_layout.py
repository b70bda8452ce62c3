"""The repository's layout: benchmarks, scripts and examples use the package, never the tests.

What a benchmark or a script shares with the tests lives in the package (``pcdcodec.testing``,
``pcdcodec.bench``, ``pcdcodec.recording.rewrite``); drivers of the test suite's own cases (the
long fuzz runs, ``tests/run_fuzz_*.py``) live beside those cases in ``tests/``.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _imports_of_tests(path: Path, root: Path = REPO) -> list[str]:
    """The lines of ``path`` that import the ``tests`` package or a module of it."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        if any(name == "tests" or name.startswith("tests.") for name in names):
            found.append(f"{path.relative_to(root)}:{node.lineno}")
    return found


def test_benchmarks_scripts_and_examples_do_not_import_the_tests() -> None:
    files = [p for d in ("benchmarks", "scripts", "examples") for p in (REPO / d).rglob("*.py")]
    assert len(files) > 20  # the folders were found
    offenders = [line for path in files for line in _imports_of_tests(path)]
    assert offenders == []


def test_the_check_finds_an_import_of_the_tests(tmp_path: Path) -> None:
    sample = tmp_path / "probe.py"
    texts = ["from tests.recording_fuzz import x\n", "import os, tests.fuzzing as f\n"]
    clean = ["from pcdcodec.testing import bench_depth\n", "from .tests import y\n"]
    for text in texts + clean:
        sample.write_text(text)
        assert bool(_imports_of_tests(sample, tmp_path)) == (text in texts), text
