"""What frame digests and the seal cost: file size and read time, with them and without.

Run: ``python benchmarks/integrity_cost.py [--frames 60] [--repeat 5]``.

The bundled sample (640x480, 15 frames, repeated to ``--frames``) is recorded at the
defaults; a copy is made without the frame digest messages, the seal and the ``integrity`` key
(as pcdcodec wrote files before them), and both are read: opening (index and seal check),
every frame in order (decoding, digests checked on the way), and ``verify()``. The two files
are read in turn, and each time (CPU time of all threads) is the best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.recording.rewrite import rewrite


def timed(step: Callable[[], object]) -> float:
    """CPU seconds of the process (all threads): steadier than wall time on a busy machine."""
    start = time.process_time()
    step()
    return time.process_time() - start


def open_only(path: Path) -> None:
    with pcdcodec.open(path):
        pass


def read_all(path: Path) -> None:
    with pcdcodec.open(path) as rec:
        for _ in rec:
            pass


def verify(path: Path) -> None:
    with pcdcodec.open(path) as rec:
        assert rec.verify().ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    seq = pcdcodec.load_sample()
    sample = list(seq)
    folder = Path(tempfile.mkdtemp(prefix="pcdcodec-integrity-"))
    files = {"without": folder / "plain.pcdc", "with": folder / "sealed.pcdc"}
    with pcdcodec.open(
        files["with"], "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale
    ) as rec:
        for k in range(args.frames):  # the sample over and over
            f = sample[k % len(sample)]
            rec.write(f.color, f.depth, k * 33_333_333)
    rewrite(files["with"], files["without"], strip_integrity=True)
    steps = {"open": open_only, "read all": read_all, "verify": verify}
    best: dict[tuple[str, str], float] = {}
    for _ in range(args.repeat):
        for step_name, step in steps.items():
            for name, path in files.items():
                t = timed(lambda step=step, path=path: step(path))
                best[name, step_name] = min(best.get((name, step_name), t), t)
    print(f"{args.frames} frames (the sample, repeated), defaults; CPU time, best of {args.repeat}")
    for name, path in files.items():
        times = ", ".join(f"{s} {best[name, s] * 1000:.1f} ms" for s in steps)
        print(f"{name:>7} digests: {path.stat().st_size} bytes; {times}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
