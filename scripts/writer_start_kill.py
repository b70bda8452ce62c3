"""What a SIGKILL costs a recording from its first frame on, and how far behind the writer is.

Run: ``python scripts/writer_start_kill.py [--kills 40] [--seed 0] [--span 1.0] [--step 1]
[--compare REV]``.

A child process opens a writer (the default codecs) and records the bundled sample (640×480,
looped; ``--step 2`` keeps every second pixel, 320×240) at 30 frames a second. It is killed
with SIGKILL at a random time from 0 to ``--span`` seconds after its first frame is handed in,
so the kills fall on the writer's first frames, where one-off costs (loading compiled loops,
opening the video encoder) would hold frames back. The child prints each frame's number before
handing it to ``write()``, and the writer's ``frames_complete`` when ``write()`` returns, so the
parent knows every frame handed in (even one whose ``write()`` never returned) and how far
behind the writer was (frames handed in minus frames readable) after each ``write()``.

The first table gives, per writer, the kills, the frames handed in and readable after the kill
(the file is read as it is, unfinished), the frames lost per kill, and how long ``open()``
took. The second gives, for each of the first 30 frames, how far behind the writer was when
that frame's ``write()`` returned: the median and the largest over the runs that got that far.

``--compare REV`` runs the package of an earlier commit (``git archive REV pcdcodec``) as well,
the kills of the two alternating, for figures before and after a change on one machine under
one load. Each writer first records a few frames unmeasured, so numba's disk cache is warm in
both. The kill times come from ``--seed``: the same seed gives the same kill times.
"""

from __future__ import annotations

import argparse
import io
import os
import random
import signal
import statistics
import subprocess
import sys
import tarfile
import tempfile
import textwrap
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pcdcodec  # noqa: E402

FIRST = 30  # frames whose lag is reported

CHILD = textwrap.dedent(
    """
    import sys, time
    import pcdcodec
    path, step, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    seq = pcdcodec.load_sample()
    cam = seq.intrinsics
    if step > 1:  # every step-th pixel: less to encode per frame
        cam = pcdcodec.CameraIntrinsics(
            cam.width // step, cam.height // step,
            cam.fx / step, cam.fy / step, cam.cx / step, cam.cy / step,
        )
    frames = [(f.color[::step, ::step].copy(), f.depth[::step, ::step].copy()) for f in seq]
    began = time.monotonic()
    rec = pcdcodec.open(path, "w", intrinsics=cam, depth_scale=seq.depth_scale)
    print("open", time.monotonic() - began, pcdcodec.__file__, flush=True)
    start = time.monotonic()
    for k in range(count):
        time.sleep(max(0.0, start + k / 30 - time.monotonic()))
        print("frame", k, flush=True)
        color, depth = frames[k % len(frames)]
        rec.write(color, depth, k * 33_333_333)
        print("returned", k, rec.frames_complete, flush=True)
    rec.close()
    """
)


@dataclass
class Runs:
    """What the kills of one writer found."""

    name: str
    path: str  # PYTHONPATH of the child
    handed: int = 0
    readable: int = 0
    losses: list[int] = field(default_factory=list)
    opens: list[float] = field(default_factory=list)  # seconds open() took
    behind: list[list[int]] = field(default_factory=lambda: [[] for _ in range(FIRST)])


def readable(path: Path) -> int:
    """Frames a reader finds in the file the kill left (none where it holds no frame yet)."""
    if not path.exists():
        return 0
    try:
        with warnings.catch_warnings():  # a killed writer's file is incomplete: that is the point
            warnings.simplefilter("ignore", pcdcodec.errors.PcdcodecWarning)
            with pcdcodec.open(path) as rec:
                return len(rec)
    except pcdcodec.PcdcodecError:
        return 0  # killed before its first frame's records were written


def child(root: str, path: Path, step: int, count: int) -> subprocess.Popen[str]:
    # Run in the file's folder: ``python -c`` puts the working folder first on sys.path,
    # where a checkout's own package would shadow the one under test.
    return subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path), str(step), str(count)],
        stdout=subprocess.PIPE,
        text=True,
        cwd=path.parent,
        env={**os.environ, "PYTHONPATH": root},
    )


def prime(runs: Runs, workdir: Path, step: int) -> None:
    """Record a few frames unmeasured: numba's disk cache of the child's package is then warm."""
    proc = child(runs.path, workdir / "prime.pcdc", step, 3)
    proc.communicate()
    if proc.returncode:
        raise SystemExit(f"{runs.name}: the writer failed (exit code {proc.returncode})")
    (workdir / "prime.pcdc").unlink()


def kill_once(runs: Runs, workdir: Path, step: int, after: float) -> None:
    path = workdir / "k.pcdc"
    proc = child(runs.path, path, step, 10**6)
    assert proc.stdout is not None
    lines: list[list[str]] = []
    try:
        while True:  # up to the first frame handed in
            line = proc.stdout.readline()
            if not line:
                raise SystemExit(f"{runs.name}: the writer ended before its first frame")
            lines.append(line.split())
            if lines[-1][0] == "frame":
                break
        time.sleep(after)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    lines += [line.split() for line in proc.stdout.read().splitlines()]
    proc.stdout.close()
    handed = sum(1 for e in lines if e and e[0] == "frame")
    found = readable(path)
    runs.handed += handed
    runs.readable += found
    runs.losses.append(handed - found)
    runs.opens.append(float(lines[0][1]))
    if not lines[0][2].startswith(runs.path):
        raise SystemExit(f"{runs.name}: the child ran the package at {lines[0][2]}")
    for e in lines:
        # A line the kill cut short is left out.
        if len(e) == 3 and e[0] == "returned" and int(e[1]) < FIRST:
            k = int(e[1])
            runs.behind[k].append(k + 1 - int(e[2]))
    path.unlink(missing_ok=True)


def extract(rev: str, into: Path) -> str:
    """The package of commit ``rev``, written under ``into``; its path for PYTHONPATH."""
    data = subprocess.run(
        ["git", "archive", rev, "pcdcodec"], cwd=ROOT, capture_output=True, check=True
    ).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(into, filter="data")
    return str(into)


def histogram(losses: list[int]) -> str:
    counts = {n: losses.count(n) for n in sorted(set(losses))}
    return ", ".join(f"{n}: {c}" for n, c in counts.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kills", type=int, default=40, help="kills per writer (default 40)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--span", type=float, default=1.0, help="kill up to SPAN s after the first frame"
    )
    parser.add_argument("--step", type=int, default=1, help="keep every STEP-th pixel")
    parser.add_argument("--compare", default="", help="git revision to run as well, before")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        writers = [Runs("as checked out", str(ROOT))]
        if args.compare:
            writers.insert(0, Runs(args.compare, extract(args.compare, workdir / "rev")))
        for runs in writers:
            prime(runs, workdir, args.step)
        for _ in range(args.kills):
            after = rng.uniform(0.0, args.span)
            for runs in writers:  # alternating: both under the same load
                kill_once(runs, workdir, args.step, after)
    size = f"{640 // args.step}x{480 // args.step}"
    print(
        f"SIGKILL 0 to {args.span} s after the first frame, 30 fps, {size}, default codecs, "
        f"seed {args.seed}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}\n"
    )
    print("| writer | kills | handed in | readable | lost per kill: kills | max lost | open() s |")
    print("|---|---|---|---|---|---|---|")
    for r in writers:
        print(
            f"| {r.name} | {len(r.losses)} | {r.handed} | {r.readable} | {histogram(r.losses)} "
            f"| {max(r.losses)} | {statistics.median(r.opens):.2f} |"
        )
    print("\nFrames handed in but not yet readable when write(k) returned: median (max), runs\n")
    print("| k | " + " | ".join(r.name for r in writers) + " |")
    print("|---|" + "---|" * len(writers))
    for k in range(FIRST):
        cells = []
        for r in writers:
            b = r.behind[k]
            cells.append(f"{statistics.median(b):g} ({max(b)}), {len(b)}" if b else "-")
        print(f"| {k} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
