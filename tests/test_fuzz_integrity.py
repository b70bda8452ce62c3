"""Fuzzing joins of damaged parts (every codec pair, a rig among them) and Zarr format 2 chunks
(every depth codec): each case gives the right data or a PcdcodecError (naming the damaged part,
for a join), never a foreign exception, wrong data, a joined file that does not read, or a hang.
``python -m tests.run_fuzz_integrity`` runs the same cases by the thousands."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

import pcdcodec

from .integrity_fuzz import (
    JOIN_OK,
    ZARR_OK,
    JoinParts,
    join_case,
    make_join_parts,
    make_zarr,
    zarr_case,
)
from .recording_fuzz import CONFIGS

SEED = 30
JOIN_CASES = 12  # per codec pair
ZARR_CASES = 16  # per depth codec


@pytest.fixture(scope="module")
def parts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, JoinParts]:
    folder = tmp_path_factory.mktemp("join-fuzz")
    return {name: make_join_parts(name, folder) for name in CONFIGS}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_joining_a_damaged_part_gives_right_frames_or_an_error_naming_it(
    parts: dict[str, JoinParts], name: str, tmp_path: Path
) -> None:
    outcomes: Counter[str] = Counter()
    failures = []
    for case in range(JOIN_CASES):
        result = join_case(parts[name], SEED, case, tmp_path)
        outcomes[result.outcome] += 1
        if result.outcome not in JOIN_OK:
            failures.append(f"{result.outcome}: {result.detail}")
    assert not failures, "\n".join(failures)
    assert outcomes["refused-naming-part"] >= JOIN_CASES // 3


@pytest.mark.parametrize("name", pcdcodec.list_codecs("depth"))
def test_zarr_v2_chunks_replaced_give_the_frame_or_an_error(name: str, tmp_path: Path) -> None:
    pytest.importorskip("numcodecs")
    zarr = pytest.importorskip("zarr")
    if int(zarr.__version__.split(".")[0]) < 3:
        pytest.skip(f"zarr {zarr.__version__} is older than 3")
    clean = make_zarr(name, tmp_path)
    outcomes: Counter[str] = Counter()
    failures = []
    for case in range(ZARR_CASES):
        result = zarr_case(clean, SEED, case, tmp_path)
        outcomes[result.outcome] += 1
        if result.outcome not in ZARR_OK:
            failures.append(f"{result.outcome}: {result.detail}")
    assert not failures, "\n".join(failures)
    assert outcomes["detected"] >= ZARR_CASES // 2
