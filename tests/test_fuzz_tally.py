"""The tally the long fuzz scripts share."""

from __future__ import annotations

import json
from pathlib import Path

from tests.fuzz_tally import Tally


def test_a_failing_case_is_kept_and_fails_the_run(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    tally = Tally(3, ("identical", "detected"), ["a", "b"], "format", every=2)
    assert not tally.add("a", "stamp", 0, "identical", "case 0")
    assert tally.add("b", "size", 1, "FOREIGN", "case 1: ValueError")
    assert not tally.add("a", "size", 2, "detected", "case 2")
    assert tally.finish(tmp_path, {"seed": 1}, "by_format", "by_kind") == 1
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["seed"] == 1
    assert summary["by_format"] == {"a": {"identical": 1, "detected": 1}, "b": {"FOREIGN": 1}}
    assert summary["by_kind"]["size"] == {"FOREIGN": 1, "detected": 1}
    assert summary["failures"] == [
        {"format": "b", "case": 1, "outcome": "FOREIGN", "detail": "case 1: ValueError"}
    ]
    printed = capsys.readouterr().out
    assert "FAIL FOREIGN: case 1: ValueError" in printed
    assert "2/3 cases" in printed


def test_a_clean_run_passes(tmp_path: Path) -> None:
    tally = Tally(1, ("identical",), ["a"], "clean", every=10)
    tally.add("a", "bytes", 0, "identical", "")
    assert tally.finish(tmp_path, {}, "by_clean", "by_mutation") == 0
