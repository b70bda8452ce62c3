"""Fuzzing recordings: a few hundred seeded mutants of several codec pairs, each read in full.

Only pcdcodec's own errors may come out, nothing may hang (a watchdog dumps every thread's stack
and stops the run), and no frame or setting may differ from the clean file's without an error.
``tests/run_fuzz_recordings.py`` runs the same cases by the tens of thousands.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from pcdcodec.cli import main

from .recording_fuzz import CONFIGS, OK_OUTCOMES, Clean, make_clean, mutate, run_case

SEED = 20260
CASES = 100  # per codec pair


@pytest.fixture(scope="module")
def cleans(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Clean]:
    folder = tmp_path_factory.mktemp("fuzz")
    return {name: make_clean(name, folder) for name in CONFIGS}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_mutated_recordings_give_right_frames_or_errors(
    cleans: dict[str, Clean], name: str, tmp_path: Path
) -> None:
    outcomes: Counter[str] = Counter()
    failures = []
    structural = 0
    for case in range(CASES):
        result = run_case(cleans[name], SEED, case, tmp_path, timeout=60.0)
        outcomes[result.outcome] += 1
        structural += "(structure)" in result.detail
        if result.outcome not in OK_OUTCOMES:
            failures.append(f"{result.outcome}: {result.detail}")
    assert not failures, "\n".join(failures)
    # The mutations reach the places that matter: most are noticed, at open or later.
    assert outcomes["detected-at-open"] >= CASES // 10
    assert outcomes["detected"] >= CASES // 10
    # Whole messages removed, swapped, duplicated, retimed... with every CRC recomputed.
    assert structural >= CASES // 10


def test_cli_never_shows_a_traceback_for_a_mutant(
    cleans: dict[str, Clean], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    statuses: Counter[int] = Counter()
    for case in range(40):
        one_camera = [name for name in CONFIGS if not CONFIGS[name].get("rig")]
        clean = cleans[one_camera[case % len(one_camera)]]
        data, what = mutate(clean, SEED + 1, case)
        path = tmp_path / "m.pcdc"
        path.write_bytes(data)
        for command in ("info", "verify"):
            status = main([command, str(path)])
            err = capsys.readouterr().err
            statuses[status] += 1
            assert status in (0, 1), what
            if status == 1 and command == "info":
                assert err.startswith("error: "), what
            assert "Traceback" not in err, what
    assert statuses[1] > 0
