"""Reading a recording in order on two cores against one, interleaved.

Writes the sample, TUM fr1_rpy and RealSense D435 frames of the benchmarks (30 frames each,
the sample's 15) as default recordings, then plays each back, round after round, in four ways:
today's default pinned to one CPU (the one-core figure), ``threads=1``, ``threads=2``, and
``threads=2`` pinned to one CPU (whether reading ahead pays on one core), each with and without
building the tensor point cloud. Prints frames per second (median over rounds), the ratio of
``threads=2`` to one core (median, and its range over the rounds) and how busy the other
processes kept the machine meanwhile (in cores, from ``/proc/stat``: a quiet machine reads 0);
a round in which they kept more than ``--max-load`` cores busy is left out and run again.

    python benchmarks/read_threads.py --rounds 9
    python benchmarks/read_threads.py --rounds 5 --frames 120 --sets tum_fr1_rpy realsense_d435
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from benchmarks import test_bench_recording as bench
from benchmarks.test_bench_recording import PRESENT, cached, one_core, play, write

WAYS: dict[str, tuple[int | None, bool]] = {
    "one core": (None, True),
    "threads=1": (1, False),
    "threads=2": (2, False),
    "threads=2, one core": (2, True),
}


def busy_seconds() -> float:
    """CPU seconds the whole machine has been busy (all cores)."""
    with open("/proc/stat") as f:
        values = [int(v) for v in f.readline().split()[1:]]
    return (sum(values) - values[3] - values[4]) / os.sysconf("SC_CLK_TCK")


def timed(run: Callable[[], int]) -> tuple[float, float]:
    """Wall seconds of ``run()`` and the cores the other processes kept busy meanwhile."""
    b0, c0, t0 = busy_seconds(), time.process_time(), time.perf_counter()
    run()
    wall = time.perf_counter() - t0
    others = busy_seconds() - b0 - (time.process_time() - c0)
    return wall, max(0.0, others / wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--sets", nargs="*", default=PRESENT)
    parser.add_argument(
        "--max-load",
        type=float,
        default=0.1,
        help="leave out rounds in which other processes kept more cores busy than this",
    )
    parser.add_argument(
        "--frames",
        type=int,
        default=bench.FRAMES,
        help="frames of each real set (the benchmarks' 30; the sample has 15)",
    )
    args = parser.parse_args()
    bench.FRAMES = args.frames
    work = Path(tempfile.mkdtemp(prefix="read-threads-"))
    print(f"| set | playback | {' | '.join(WAYS)} | threads=2 / one core | other load |")
    print("|---|---|" + "---|" * (len(WAYS) + 2))
    for name in args.sets:
        seq = cached(name)
        path = write(seq, work / f"{name}.pcdc")
        with pcdcodec.open(path) as rec:
            frames = len(rec)
        for clouds in (True, False):
            walls: dict[str, list[float]] = {way: [] for way in WAYS}
            loads: list[float] = []
            dropped = 0
            for round_ in range(args.rounds * 20):  # the first round warms up
                if len(walls["one core"]) == args.rounds:
                    break
                got = {}
                for way, (threads, pinned) in WAYS.items():
                    run = functools.partial(play, path, threads, clouds)
                    if pinned:
                        with one_core():
                            got[way] = timed(run)
                    else:
                        got[way] = timed(run)
                load = max(load for _, load in got.values())
                if not round_:
                    continue
                if load > args.max_load:
                    dropped += 1
                    time.sleep(1.0)  # wait for the other processes to calm down
                    continue
                loads.append(load)
                for way, (wall, _) in got.items():
                    walls[way].append(wall)
            fps = {way: frames / statistics.median(w) for way, w in walls.items()}
            ratios = [a / b for a, b in zip(walls["one core"], walls["threads=2"], strict=True)]
            print(
                f"| {name} | {'decode + cloud' if clouds else 'decode'} | "
                + " | ".join(f"{fps[way]:.1f}" for way in WAYS)
                + f" | {fps['threads=2'] / fps['one core']:.2f} "
                f"({min(ratios):.2f}–{max(ratios):.2f}) | "
                f"{statistics.median(loads):.2f} (max {max(loads):.2f}; "
                f"{dropped} busier round(s) left out) |",
                flush=True,
            )


if __name__ == "__main__":
    main()
