"""Fuzzing bags: seeded mutants of a small ROS 1, ROS 2 sqlite3 and ROS 2 mcap bag, each read
through every view of the changed topic.

Message fields (Image, CompressedImage, CameraInfo, PointCloud2, header stamps) and the bag's
bytes are changed; only pcdcodec's own errors naming the bag may come out, no data may differ
from the clean bag where the change could not legitimately alter it, memory stays within a
bound that follows the declared camera (the address space is capped while a view reads), and
nothing hangs (a watchdog dumps every thread's stack and stops the run).
``tests/run_fuzz_bags.py`` runs the same cases by the thousands.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from .bag_fuzz import FORMATS, OK_OUTCOMES, Clean, make_clean, run_case

SEED = 18
CASES = 40  # per format


@pytest.fixture(scope="module")
def cleans(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Clean]:
    folder = tmp_path_factory.mktemp("bagfuzz")
    return {fmt: make_clean(fmt, folder) for fmt in FORMATS}


@pytest.mark.parametrize("fmt", FORMATS)
def test_mutated_bags_give_right_frames_or_named_errors(
    cleans: dict[str, Clean], fmt: str, tmp_path: Path
) -> None:
    outcomes: Counter[str] = Counter()
    failures = []
    for case in range(CASES):
        result = run_case(cleans[fmt], SEED, case, tmp_path, timeout=60.0)
        outcomes[result.outcome] += 1
        if result.outcome not in OK_OUTCOMES:
            failures.append(f"{result.outcome}: {result.detail}")
    assert not failures, "\n".join(failures)
    # The cases reach past the first checks: some read through, some are caught.
    assert outcomes["detected"] > 0
    assert outcomes["identical"] + outcomes["changed-as-allowed"] > 0
