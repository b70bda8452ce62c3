#!/usr/bin/env python3
"""Mutate recordings by the tens of thousands and check that each reads right or fails cleanly.

The cases are those of ``tests/test_fuzz_recording.py`` (see ``tests/recording_fuzz.py``): for
each codec pair a small clean recording is written, then case ``k`` of ``--seed`` changes its
bytes in one way (mostly aimed at the header, metadata, record headers, summary and footer; a
quarter of the cases remove, swap, duplicate, move or retime whole messages, swap payloads,
drop a metadata record or write the file unchunked, every CRC and the summary recomputed:
region "structure"), and the mutant is opened, decoded frame by frame against the clean file,
and verified. A case fails
on an exception outside pcdcodec's tree, a frame or setting that differs without an error,
frames lost without a word, or a hang (``--timeout``; the stacks of all threads are printed).

    python -m tests.run_fuzz_recordings --cases 20000 --seed 1 --jobs 2 --out fuzz-out

Failing mutants are kept under ``--out`` with the clean files they came from. Exit status 1
when any case failed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.fuzz_tally import Tally  # noqa: E402
from tests.recording_fuzz import (  # noqa: E402
    CONFIGS,
    OK_OUTCOMES,
    Clean,
    load_clean,
    make_clean,
    mutate,
    run_case,
)

_cleans: dict[str, Clean] = {}
_work: Path = Path()


def _init(paths: dict[str, str], work: str) -> None:
    global _work
    _work = Path(work)
    for name, path in paths.items():
        _cleans[name] = load_clean(name, Path(path))


def _run(job: tuple[str, int, int, float]) -> tuple[str, int, str, str, str]:
    name, seed, case, timeout = job
    clean = _cleans[name]
    result = run_case(clean, seed, case, _work, timeout=timeout)
    kind = result.detail.split("(", 1)[1].split(")", 1)[0]
    return name, case, kind, result.outcome, result.detail


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=20000, help="number of mutants in all")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--first", type=int, default=0, help="first case number")
    parser.add_argument(
        "--configs", default=",".join(CONFIGS), help=f"codec pairs, from {','.join(CONFIGS)}"
    )
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds before a hang")
    parser.add_argument("--out", type=Path, help="keep clean files, failing mutants, summary")
    args = parser.parse_args(argv)
    names = args.configs.split(",")
    unknown = [n for n in names if n not in CONFIGS]
    if unknown or args.cases < 1 or args.jobs < 1:
        parser.error(f"unknown codec pairs {unknown}" if unknown else "--cases/--jobs must be >= 1")

    out = args.out or Path(tempfile.mkdtemp(prefix="pcdcodec-fuzz-"))
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-fuzz-work-"))
    paths = {name: str(make_clean(name, out).path) for name in names}
    jobs = [
        (names[k % len(names)], args.seed, k, args.timeout)
        for k in range(args.first, args.first + args.cases)
    ]
    tally = Tally(len(jobs), OK_OUTCOMES, names, "config", every=1000)
    with multiprocessing.get_context("spawn").Pool(
        args.jobs, initializer=_init, initargs=(paths, str(work))
    ) as pool:
        for name, case, kind, outcome, detail in pool.imap_unordered(_run, jobs, chunksize=16):
            if tally.add(name, kind, case, outcome, detail):
                clean = load_clean(name, Path(paths[name]))
                data, _ = mutate(clean, args.seed, case)
                (out / f"fail-{name.replace('+', '-')}-{args.seed}-{case}.pcdc").write_bytes(data)
    head = {"cases": len(jobs), "seed": args.seed, "first": args.first}
    return tally.finish(out, head, "by_config", "by_region")


if __name__ == "__main__":
    sys.exit(main())
