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

    python -m tests.run_fuzz_camera_files --cases 4000 --seed 1 --jobs 2 --out fuzz-out
    python -m tests.run_fuzz_camera_files --cleans mkv-k4a,mkv-real --cases 3000

``--cases`` is per clean file. Failing mutants are kept under ``--out``. Exit status 1 when any
case failed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import tempfile
from pathlib import Path

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
from tests.fuzz_tally import Tally  # noqa: E402

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
    tally = Tally(len(jobs), OK_OUTCOMES, names, "clean", every=1000)
    with multiprocessing.get_context("spawn").Pool(
        args.jobs, initializer=_init, initargs=(names, str(work))
    ) as pool:
        for name, case, kind, outcome, detail in pool.imap_unordered(_run, jobs, chunksize=8):
            if tally.add(name, f"{name.split('-')[0]}:{kind}", case, outcome, detail):
                clean = make_clean(name, work / "failures")
                data, _, _ = mutate(clean, args.seed, case)
                suffix = ".bag" if clean.kind == "realsense" else ".mkv"
                (out / f"fail-{name}-{args.seed}-{case}{suffix}").write_bytes(data)
    head = {"cases": len(jobs), "seed": args.seed, "first": args.first}
    return tally.finish(out, head, "by_clean", "by_mutation")


if __name__ == "__main__":
    sys.exit(main())
