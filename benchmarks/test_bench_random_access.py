"""Random access against reading in order: ``rec[i]`` for random ``i`` over a 300-frame default
recording takes at most 2× the time per frame of reading in order.

Each round reads the recording once in order and once in a new random order, one after the
other (which goes first alternates), so a slow spell on a shared machine lands on both; the
summary table gives the ratio per set (median and range over rounds). The recording is each
set played forward and back to 300 frames (:mod:`benchmarks.random_access`, which also breaks
the time down and tabulates ``gop``). A smoke run (``--benchmark-disable``) reads 40 frames.
"""

from __future__ import annotations

import hashlib
import random
import statistics
import time
from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from benchmarks.random_access import FRAMES, PRESENT, at_random, in_order, sequence, write


def digests(frame: pcdcodec.Frame) -> tuple[str, str]:
    color = b"" if frame.color is None else frame.color.tobytes()
    return hashlib.sha256(color).hexdigest(), hashlib.sha256(frame.depth.tobytes()).hexdigest()


@pytest.mark.parametrize("name", PRESENT)
def test_random_access_against_reading_in_order(benchmark: Any, tmp_path: Path, name: str) -> None:
    frames = 40 if benchmark.disabled else FRAMES
    path = write(sequence(name), tmp_path / f"{name}.pcdc", frames=frames)
    # Correct, not just fast: random frames are exactly the frames read in order.
    with pcdcodec.open(path) as rec:
        expected = [digests(f) for f in rec]
        for i in random.Random(1).sample(range(frames), 20):
            assert digests(rec[i]) == expected[i]
    rng = random.Random(0)
    ordered: list[float] = []
    shuffled: list[float] = []

    def one_round() -> None:
        order = list(range(frames))
        rng.shuffle(order)
        passes = [(ordered, lambda: in_order(path)), (shuffled, lambda: at_random(path, order))]
        if len(ordered) % 2:
            passes.reverse()
        valid = []
        for times, run in passes:
            t0 = time.perf_counter()
            valid.append(run())
            times.append((time.perf_counter() - t0) / frames)
        assert valid[0] == valid[1]

    benchmark.group = "recording: rec[i] at random against reading in order, 300 frames"
    benchmark.pedantic(one_round, rounds=5, iterations=1, warmup_rounds=1)
    ordered, shuffled = ordered[-5:], shuffled[-5:]  # without the warm-up round
    ratios = [b / a for a, b in zip(ordered, shuffled, strict=True)]
    benchmark.extra_info.update(
        kind="random-access",
        sequence=name,
        frames=frames,
        in_order_ms=1000 * statistics.median(ordered),
        random_ms=1000 * statistics.median(shuffled),
        ratio=statistics.median(ratios),
        ratio_min=min(ratios),
        ratio_max=max(ratios),
    )
