"""Fuzzing camera files: seeded mutants of small RealSense ``.bag`` and Azure Kinect ``.mkv``
files (and of the real ones when present), each opened and read in full.

Only pcdcodec's own errors naming the file may come out, nothing may hang (a watchdog dumps
every thread's stack and stops the run), memory stays within a bound set by the cameras, and no
frame may differ from the clean file's unless the mutation declares it (see
``tests/camera_file_fuzz.py``). ``tests/run_fuzz_camera_files.py`` runs the same cases by the
thousands.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from .camera_file_fuzz import OK_OUTCOMES, Clean, available_cleans, make_clean, run_case

SEED = 20261
#: cases per clean file: the small built files get most, the real ones (slower to rebuild) fewer
CASES = {"rs-lz4": 40, "rs-uncompressed": 30, "rs-mjpeg": 30, "rs-real": 16, "mkv-k4a": 150,
         "mkv-real": 50}  # fmt: skip


@pytest.fixture(scope="module")
def cleans(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Clean]:
    folder = tmp_path_factory.mktemp("camera-fuzz")
    return {name: make_clean(name, folder) for name in available_cleans()}


@pytest.mark.parametrize("name", list(CASES))
def test_mutated_camera_files_give_right_frames_or_errors(
    cleans: dict[str, Clean], name: str, tmp_path: Path
) -> None:
    if name not in cleans:
        pytest.skip(f"{name}: the real file is not present")
    outcomes: Counter[str] = Counter()
    failures = []
    for case in range(CASES[name]):
        result = run_case(cleans[name], SEED, case, tmp_path, timeout=60.0)
        outcomes[result.outcome] += 1
        if result.outcome not in OK_OUTCOMES:
            failures.append(f"{result.outcome}: {result.detail}")
    assert not failures, "\n".join(failures)
    # The mutations reach what the readers check: many are caught, some read the same.
    assert outcomes["detected"] >= CASES[name] // 5, outcomes
    assert outcomes["identical"] + outcomes["changed-as-declared"] >= CASES[name] // 10, outcomes


def test_cli_info_never_shows_a_traceback_for_a_mutant(
    cleans: dict[str, Clean], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pcdcodec.cli import main

    from .camera_file_fuzz import mutate

    statuses: Counter[int] = Counter()
    for name in ("rs-lz4", "mkv-k4a"):
        for case in range(20):
            data, what, _ = mutate(cleans[name], SEED + 1, case)
            path = tmp_path / ("m.bag" if name.startswith("rs") else "m.mkv")
            path.write_bytes(data)
            status = main(["info", str(path)])
            err = capsys.readouterr().err
            statuses[status] += 1
            assert status in (0, 1), what
            assert "Traceback" not in err, what
            if status == 1:
                assert err.startswith("error: "), (what, err)
                assert str(path) in err, (what, err)
    assert statuses[0] > 0
    assert statuses[1] > 0
