"""Fuzz a depth codec's decoder with mutated, truncated and extended frames.

Every case must raise ``DecodeError`` or decode to exactly the original image; a crash,
a hang (each case is bounded by an alarm) or a wrong image fails the run.

    python -m tests.run_fuzz_depth --codec depthac --cases 100000 --seed 1

The frames are crops of the bundled sample and, when ``../shared/data`` is present, of every
real sequence and its sparse variant, as uint16 and float32 metres, plus a few whole frames.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import DEPTH_SETS, load_frames
from pcdcodec.depth import FrameCodec
from tests.fuzzing import fuzz_frames, fuzz_images


def _depths() -> list[np.ndarray]:
    import pytest

    depths: list[np.ndarray] = []
    for name in DEPTH_SETS:
        try:
            depths += load_frames(name, 3)
        except pytest.skip.Exception:
            continue
    return depths


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--codec", default="depthac")
    parser.add_argument("--cases", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--batch", type=int, default=1000, help="cases per set of frames")
    args = parser.parse_args()
    codec = pcdcodec.get_codec(args.codec)
    assert isinstance(codec, FrameCodec)
    depths = _depths()
    rng = np.random.default_rng(args.seed)

    def on_alarm(signum: int, frame: object) -> None:
        raise TimeoutError("a batch of fuzz cases ran past its time limit: a hang")

    signal.signal(signal.SIGALRM, on_alarm)
    total: Counter[str] = Counter()
    start = time.perf_counter()
    done = 0
    batch = 0
    while done < args.cases:
        n = min(args.batch, args.cases - done)
        images = fuzz_images(depths, rng, 12)
        if batch % 10 == 0:  # now and then whole frames, as sensors give them
            images.append(depths[int(rng.integers(len(depths)))])
        signal.alarm(max(60, n // 10))
        total += fuzz_frames(codec, images, n, seed=args.seed * 1_000_003 + batch)
        signal.alarm(0)
        done += n
        batch += 1
        if done % 10_000 == 0:
            print(f"  {done} cases, {time.perf_counter() - start:.0f} s", flush=True)
    elapsed = time.perf_counter() - start
    raised = sum(v for k, v in total.items() if not k.endswith(":exact"))
    exact = done - raised
    print(
        f"{args.codec}: {done} cases in {elapsed:.0f} s: {raised} raised DecodeError, "
        f"{exact} decoded exactly, 0 crashes, 0 hangs, 0 wrong images"
    )
    for kind, count in sorted(total.items()):
        print(f"  {kind:24} {count}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
