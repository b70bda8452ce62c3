#!/usr/bin/env python3
"""Join damaged parts and replace Zarr format 2 chunks by the thousands; each must read right or
fail with pcdcodec's own error.

The cases are those of ``tests/test_fuzz_integrity.py`` (see ``tests/integrity_fuzz.py``): for each
codec pair (a rig among them) two clean parts of one recording are written, the second is mutated
as ``python -m tests.run_fuzz_recordings`` mutates a recording, and the two are joined; for each
depth codec a Zarr format 2 array is written and one chunk replaced (its bytes mutated, or a frame
of another shape, dtype or codec, or nothing) before the frame is read. A join case fails when the
join raises anything but a PcdcodecError naming the damaged part, leaves its output behind, or
writes a file that does not verify or differs from the clean parts; a Zarr case fails on a foreign
exception or a frame that differs without an error; either fails on a hang (``--timeout``).

    python -m tests.run_fuzz_integrity --join-cases 2000 --zarr-cases 3000 --seed 1 --out out

Exit status 1 when any case failed; ``--out`` gets ``summary.json``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import pcdcodec  # noqa: E402
from tests.fuzz_tally import Tally  # noqa: E402
from tests.integrity_fuzz import (  # noqa: E402
    JOIN_OK,
    ZARR_OK,
    join_case,
    make_join_parts,
    make_zarr,
    zarr_case,
)
from tests.recording_fuzz import CONFIGS  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--join-cases", type=int, default=2000, help="join cases in all")
    parser.add_argument("--zarr-cases", type=int, default=3000, help="Zarr cases in all")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds before a hang")
    parser.add_argument("--out", type=Path, help="where summary.json goes")
    args = parser.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="pcdcodec-fuzz-"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-fuzz-work-"))
    configs = list(CONFIGS)
    codecs = pcdcodec.list_codecs("depth")
    groups = [f"join {n}" for n in configs] + [f"zarr {n}" for n in codecs]
    tally = Tally(args.join_cases + args.zarr_cases, JOIN_OK + ZARR_OK, groups, "group", 500)
    parts = {name: make_join_parts(name, out) for name in configs}
    for case in range(args.join_cases):
        name = configs[case % len(configs)]
        result = join_case(parts[name], args.seed, case, work, args.timeout)
        kind = result.detail.split("(", 1)[1].split(")", 1)[0]
        tally.add(f"join {name}", f"join {kind}", case, result.outcome, result.detail)
    arrays = {name: make_zarr(name, out) for name in codecs}
    for case in range(args.zarr_cases):
        name = codecs[case % len(codecs)]
        result = zarr_case(arrays[name], args.seed, case, work, args.timeout)
        kind = result.detail.split("(", 1)[1].split(")", 1)[0]
        tally.add(f"zarr {name}", f"zarr {kind}", case, result.outcome, result.detail)
    head = {"join_cases": args.join_cases, "zarr_cases": args.zarr_cases, "seed": args.seed}
    return tally.finish(out, head, "by_group", "by_kind")


if __name__ == "__main__":
    sys.exit(main())
