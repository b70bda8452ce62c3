#!/usr/bin/env python3
"""Mutate ROS bags by the thousands and check that each reads right or fails cleanly.

The cases are those of ``tests/test_fuzz_bags.py`` (see ``tests/bag_fuzz.py``): for each storage
format (ROS 1, ROS 2 sqlite3, ROS 2 mcap) a small clean bag is written, then case ``k`` of
``--seed`` changes one message field (Image, CompressedImage, CameraInfo, PointCloud2, a header
stamp) or the written file's bytes, and the mutant is read through every view of the changed
topic: opened, iterated, indexed, and a stretch read alone. A case fails on an exception outside
pcdcodec's tree, an error that does not name the bag, data that differs where the change could
not alter it, an index that disagrees with iteration, memory past the bound set by the declared
camera (``--memory``), or a hang (``--timeout``; the stacks of all threads are printed).

    python -m tests.run_fuzz_bags --cases 3000 --seed 1 --jobs 2 --out bag-fuzz-out

``--cases`` counts cases per format. A summary (counts per format and outcome, the failing
cases) goes to ``--out/summary.json``. Exit status 1 when any case failed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.bag_fuzz import FORMATS, OK_OUTCOMES, Clean, make_clean, run_case  # noqa: E402
from tests.fuzz_tally import Tally  # noqa: E402

_cleans: dict[str, Clean] = {}
_work: Path = Path()


def _init(formats: list[str], work: str) -> None:
    global _work
    _work = Path(work) / f"w{multiprocessing.current_process().pid}"
    _work.mkdir(parents=True, exist_ok=True)
    for fmt in formats:
        _cleans[fmt] = make_clean(fmt, _work)


def _run(job: tuple[str, int, int, float, str]) -> tuple[str, int, str, str, str]:
    fmt, seed, case, timeout, memory = job
    result = run_case(_cleans[fmt], seed, case, _work, timeout=timeout, memory=memory)
    kind = result.detail.split(" ")[5] if result.detail.count(" ") > 5 else "?"
    return fmt, case, kind, result.outcome, result.detail


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=3000, help="number of mutants per format")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--first", type=int, default=0, help="first case number")
    parser.add_argument("--formats", default=",".join(FORMATS), help=f"from {','.join(FORMATS)}")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds before a hang")
    parser.add_argument("--out", type=Path, help="where the summary goes")
    parser.add_argument(
        "--memory",
        choices=("limit", "trace"),
        default="limit",
        help="cap the address space while reading (fast) or trace every allocation (slow)",
    )
    args = parser.parse_args(argv)
    formats = args.formats.split(",")
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or args.cases < 1 or args.jobs < 1:
        parser.error(f"unknown formats {unknown}" if unknown else "--cases/--jobs must be >= 1")

    out = args.out or Path(tempfile.mkdtemp(prefix="pcdcodec-bagfuzz-"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-bagfuzz-work-"))
    jobs = [
        (fmt, args.seed, k, args.timeout, args.memory)
        for k in range(args.first, args.first + args.cases)
        for fmt in formats
    ]
    tally = Tally(len(jobs), OK_OUTCOMES, formats, "format", every=500)
    with multiprocessing.get_context("spawn").Pool(
        args.jobs, initializer=_init, initargs=(formats, str(work))
    ) as pool:
        for fmt, case, kind, outcome, detail in pool.imap_unordered(_run, jobs, chunksize=8):
            tally.add(fmt, kind, case, outcome, detail)
    head = {"cases_per_format": args.cases, "seed": args.seed, "first": args.first}
    return tally.finish(out, head, "by_format", "by_kind")


if __name__ == "__main__":
    sys.exit(main())
