"""What a SIGKILL costs a recording: frames handed to the writer vs frames readable after.

Run: ``python scripts/writer_kill_test.py [--kills 24] [--modes paced,idle] [--seed 0]
[--writer REV] [--step 1] [--color SPEC]``.

A child process records the bundled sample (640×480, looped) with the default codecs
(``--color`` names another color codec, as a JSON config) and is killed with SIGKILL at a
random point; the file it leaves is then read as it is (unfinished, without an index) and
through ``pcdcodec recover``. The child prints each frame's number and the time just before
handing it to ``write()``, so the parent knows every frame handed in, even one whose
``write()`` never returned; it also prints the writer's ``frames_complete`` then, so the
parent knows whether the codecs had caught up (every earlier frame written) when the last
frame was handed in. On a machine too busy to encode 30 frames a second, frames wait
in the writer's queue, and a kill loses them too.

* ``paced``: frames handed in at 30 fps, without pause. The kill comes 0.3 to 3 s after the
  first frame is readable (past the codecs' start-up; ``scripts/writer_start_kill.py`` kills
  from the first frame on).
* ``idle``: bursts of 1 to 8 frames at 30 fps, each followed by an idle gap of 0.02 to 1 s; the
  kill comes at a random point of a random burst or gap. Kills 50 ms or more after the last
  ``write()`` returned are counted apart: there the writer is idle and should lose nothing.

``--step 2`` records every second pixel (320×240), a quarter of the work per frame, for a
machine too busy to encode 640×480 at 30 fps. ``--writer REV`` runs the ``RecordingWriter``
of an earlier commit instead (its ``pcdcodec/recording/writer.py``, with the rest of the
package as checked out), for the figures before a change.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pcdcodec  # noqa: E402

CHILD = textwrap.dedent(
    """
    import importlib.util, json, random, sys, time
    import pcdcodec
    path, mode, seed, writer_file = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    step = int(sys.argv[5])
    color = json.loads(sys.argv[6]) if sys.argv[6] else pcdcodec.DEFAULT_COLOR_CODEC
    if writer_file:
        spec = importlib.util.spec_from_file_location(
            "pcdcodec.recording._writer_under_test", writer_file
        )
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        Writer = module.RecordingWriter
    else:
        Writer = pcdcodec.RecordingWriter
    rng = random.Random(seed)
    seq = pcdcodec.load_sample()
    cam = seq.intrinsics
    if step > 1:  # every step-th pixel: less to encode per frame
        cam = pcdcodec.CameraIntrinsics(
            cam.width // step, cam.height // step,
            cam.fx / step, cam.fy / step, cam.cx / step, cam.cy / step,
        )
    frames = [(f.color[::step, ::step].copy(), f.depth[::step, ::step].copy()) for f in seq]
    rec = Writer(path, intrinsics=cam, depth_scale=seq.depth_scale, color=color)
    k = 0
    start = time.monotonic()
    while True:
        burst = 10**9 if mode == "paced" else rng.randint(1, 8)
        for _ in range(burst):
            time.sleep(max(0.0, start + k / 30 - time.monotonic()))
            print(k, time.monotonic(), rec.frames_complete, flush=True)
            color, depth = frames[k % len(frames)]
            rec.write(color, depth, k * 33_333_333)
            print("returned", time.monotonic(), flush=True)
            k += 1
        gap = rng.uniform(0.02, 1.0)
        time.sleep(gap)
        start += gap + 1 / 30
    """
)


@dataclass
class Mode:
    kills: int = 0
    handed: int = 0
    readable: int = 0
    recovered: int = 0
    losses: list[int] = field(default_factory=list)
    idle_losses: list[int] = field(default_factory=list)  # kills >= 50 ms after a write()
    recover_mismatch: int = 0
    rates: list[float] = field(default_factory=list)  # frames handed in per second, paced
    # Kills where every frame before the last one handed in was written when it was handed
    # in: the codecs had kept up with the caller.
    kept_up_losses: list[int] = field(default_factory=list)


def readable(path: Path) -> int:
    with warnings.catch_warnings():  # a killed writer's file is incomplete: that is the point
        warnings.simplefilter("ignore", pcdcodec.errors.PcdcodecWarning)
        with pcdcodec.open(path) as rec:
            return len(rec)


def wait_readable(path: Path, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if path.exists() and readable(path) >= 1:
                return
        except pcdcodec.PcdcodecError:
            pass  # the file's first bytes are still being written
        time.sleep(0.01)
    raise SystemExit(f"no frame readable in {path} after {timeout:.0f} s")


def kill_once(
    workdir: Path,
    mode: str,
    seed: int,
    writer_file: str,
    step: int,
    color: str,
    rng: random.Random,
    stats: Mode,
) -> None:
    path = workdir / f"{mode}-{seed}.pcdc"
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path), mode, str(seed), writer_file, str(step), color],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert proc.stdout is not None
    try:
        wait_readable(path)
        time.sleep(rng.uniform(0.3, 3.0))
        killed_at = time.monotonic()
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    events = [line.split() for line in proc.stdout.read().splitlines() if line.strip()]
    proc.stdout.close()
    lines = [e for e in events if e[0] != "returned"]  # one per frame handed in
    handed = len(lines)
    # Idle: the last write() had returned, 50 ms or more before the kill. (A line the kill
    # cut short counts as not idle.)
    last = events[-1]
    since_last = killed_at - float(last[1]) if last[0] == "returned" and len(last) == 2 else 0.0
    found = readable(path)
    recovered_path = workdir / f"{mode}-{seed}-recovered.pcdc"
    recovered = pcdcodec.recording.recover(path, recovered_path)
    stats.kills += 1
    stats.handed += handed
    stats.readable += found
    stats.recovered += recovered
    stats.losses.append(handed - found)
    if mode == "paced" and handed > 31 and len(lines[-1]) == 3:
        # Over the last 30 frames: below 30 fps, write() waited for the codecs.
        stats.rates.append(30 / (float(lines[-1][1]) - float(lines[-31][1])))
    if recovered != found:
        stats.recover_mismatch += 1
    if len(lines[-1]) == 3 and int(lines[-1][2]) == handed - 1:
        stats.kept_up_losses.append(handed - found)
    if since_last >= 0.05:
        stats.idle_losses.append(handed - found)
    path.unlink()
    recovered_path.unlink()


def histogram(losses: list[int]) -> str:
    if not losses:
        return "-"
    counts: dict[int, int] = {}
    for lost in losses:
        counts[lost] = counts.get(lost, 0) + 1
    return ", ".join(f"{lost} lost: {n}" for lost, n in sorted(counts.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kills", type=int, default=24, help="kills per mode (default 24)")
    parser.add_argument("--modes", default="paced,idle", help="paced, idle or both")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--writer", default="", help="git revision of the writer to test")
    parser.add_argument(
        "--step", type=int, default=1, help="keep every STEP-th pixel (2: 320x240; default 1)"
    )
    parser.add_argument(
        "--color", default="", help="color codec config as JSON (default: the default codec)"
    )
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        writer_file = ""
        if args.writer:
            source = subprocess.run(
                ["git", "show", f"{args.writer}:pcdcodec/recording/writer.py"],
                cwd=ROOT,
                capture_output=True,
                text=True,
                check=True,
            ).stdout
            (workdir / "writer.py").write_text(source)
            writer_file = str(workdir / "writer.py")
        size = f"{640 // args.step}x{480 // args.step}"
        print(
            f"writer: {args.writer or 'as checked out'}; {size}; color "
            f"{args.color or pcdcodec.DEFAULT_COLOR_CODEC}; {args.kills} kills per mode"
        )
        print(
            "| mode | kills | handed in | readable | lost per kill | kills with the codecs "
            "caught up | kills ≥ 50 ms after a write() returned |"
        )
        print("|---|---|---|---|---|---|---|")
        for mode in args.modes.split(","):
            stats = Mode()
            for k in range(args.kills):
                kill_once(
                    workdir,
                    mode,
                    args.seed * 1000 + k,
                    writer_file,
                    args.step,
                    args.color,
                    rng,
                    stats,
                )
            print(
                f"| {mode} | {stats.kills} | {stats.handed} | {stats.readable} | "
                f"{histogram(stats.losses)} | {len(stats.kept_up_losses)}: "
                f"{histogram(stats.kept_up_losses)} | {len(stats.idle_losses)}: "
                f"{histogram(stats.idle_losses)} |",
                flush=True,
            )
            if stats.rates:
                rates = sorted(stats.rates)
                print(
                    f"  paced: frames handed in per second before the kill, min "
                    f"{rates[0]:.1f}, median {rates[len(rates) // 2]:.1f}, max {rates[-1]:.1f}"
                )
            if stats.recover_mismatch:
                print(f"  recover found another count than the reader {stats.recover_mismatch}x")


if __name__ == "__main__":
    main()
