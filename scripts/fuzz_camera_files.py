#!/usr/bin/env python3
"""Mutate camera files by the thousands and check that each reads right or fails cleanly.

The cases are those of ``tests/test_fuzz_camera_files.py`` (see ``tests/camera_file_fuzz.py``):
small RealSense ``.bag`` files (lz4, uncompressed, MJPEG color) and a small Azure Kinect ``.mkv``
built with the cameras' own layouts, plus the real files under ``/work/shared/data/bags`` when
present. Case ``k`` of ``--seed`` changes one field (Image width/step/encoding, CameraInfo, depth
units, stamps, calibration JSON, tags, CodecPrivate, EBML sizes and IDs, block payloads) or some
bytes; the mutant is opened and every frame read. A case fails on an exception outside
pcdcodec's tree, an error that does not name the file, frames that differ without the file
declaring it, frames lost without a word, memory over the bound the cameras set, or a hang
(``--timeout``; the stacks of all threads are printed).

    python scripts/fuzz_camera_files.py --cases 4000 --seed 1 --jobs 2 --out fuzz-out
    python scripts/fuzz_camera_files.py --cleans mkv-k4a,mkv-real --cases 3000

``--cases`` is per clean file. Failing mutants are kept under ``--out``. Exit status 1 when any
case failed.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.camera_file_fuzz import (  # noqa: E402
    OK_OUTCOMES,
    Clean,
    available_cleans,
    make_clean,
    mutate,
    run_case,
)

_cleans: dict[str, Clean] = {}
_work: Path = Path()


def _init(names: list[str], work: str) -> None:
    global _work
    # A folder of its own: workers building the same clean file in one folder read each
    # other's half-written bags, and then judged every mutant against a wrong clean.
    _work = Path(work) / f"worker-{os.getpid()}"
    _work.mkdir()
    for name in names:
        _cleans[name] = make_clean(name, _work)


def _run(job: tuple[str, int, int, float]) -> tuple[str, int, str, str, str]:
    name, seed, case, timeout = job
    result = run_case(_cleans[name], seed, case, _work, timeout=timeout)
    kind = result.detail.split("(", 1)[1].split(")", 1)[0]
    return name, case, kind, result.outcome, result.detail


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=2000, help="mutants per clean file")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--first", type=int, default=0, help="first case number")
    known = available_cleans()
    parser.add_argument("--cleans", default=",".join(known), help=f"from {','.join(known)}")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds before a hang")
    parser.add_argument("--out", type=Path, help="keep failing mutants and the summary here")
    args = parser.parse_args(argv)
    names = args.cleans.split(",")
    unknown = [n for n in names if n not in known]
    if unknown or args.cases < 1 or args.jobs < 1:
        parser.error(f"unknown clean files {unknown}" if unknown else "--cases/--jobs >= 1")

    out = args.out or Path(tempfile.mkdtemp(prefix="pcdcodec-camera-fuzz-"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-camera-fuzz-work-"))
    (work / "failures").mkdir()
    jobs = [
        (name, args.seed, k, args.timeout)
        for k in range(args.first, args.first + args.cases)
        for name in names
    ]
    outcomes: Counter[str] = Counter()
    by_clean: dict[str, Counter[str]] = {n: Counter() for n in names}
    by_kind: dict[str, Counter[str]] = {}
    failures: list[dict[str, Any]] = []
    start = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(
        args.jobs, initializer=_init, initargs=(names, str(work))
    ) as pool:
        for done, (name, case, kind, outcome, detail) in enumerate(
            pool.imap_unordered(_run, jobs, chunksize=8), 1
        ):
            outcomes[outcome] += 1
            by_clean[name][outcome] += 1
            by_kind.setdefault(f"{name.split('-')[0]}:{kind}", Counter())[outcome] += 1
            if outcome not in OK_OUTCOMES:
                failures.append({"clean": name, "case": case, "outcome": outcome, "detail": detail})
                print(f"FAIL {outcome}: {detail}", flush=True)
                clean = make_clean(name, work / "failures")
                data, _, _ = mutate(clean, args.seed, case)
                suffix = ".bag" if clean.kind == "realsense" else ".mkv"
                (out / f"fail-{name}-{args.seed}-{case}{suffix}").write_bytes(data)
            if done % 1000 == 0:
                rate = done / (time.perf_counter() - start)
                print(f"{done}/{len(jobs)} cases, {rate:.0f}/s: {dict(outcomes)}", flush=True)
    seconds = time.perf_counter() - start
    summary = {
        "cases": len(jobs),
        "seed": args.seed,
        "first": args.first,
        "seconds": round(seconds, 1),
        "outcomes": dict(outcomes),
        "by_clean": {n: dict(c) for n, c in by_clean.items()},
        "by_mutation": {k: dict(c) for k, c in sorted(by_kind.items())},
        "failures": failures,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps({k: v for k, v in summary.items() if k != "failures"}, indent=2))
    print(f"{len(failures)} failing case(s) of {len(jobs)}; summary in {out / 'summary.json'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
