"""Write throughput of a default recording: the writer as checked out vs an earlier one.

Run: ``python benchmarks/writer_throughput.py --baseline REV [--frames 60] [--rounds 8]``.

It then times how long a frame handed to an idle writer (as checked out) takes to be written
and flushed to the file: ``write()`` of one frame every 0.2 s, then ``flush()``, which returns
once the writing thread has written and flushed it; median and maximum.

Both writers record the bundled sample (640×480, looped to ``--frames`` frames) with the
default codecs, as fast as the caller can hand frames in, from ``open`` to ``close``. They run
alternately in one process (ABBA order, so a drift in the machine's load falls on both), and
the result is the ratio of their frames per second, round by round: above 1, the writer as
checked out is faster. ``REV``'s ``pcdcodec/recording/writer.py`` is loaded with the rest of
the package as checked out.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pcdcodec  # noqa: E402


def baseline_writer(rev: str, workdir: Path) -> Any:
    source = subprocess.run(
        ["git", "show", f"{rev}:pcdcodec/recording/writer.py"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    path = workdir / "baseline_writer.py"
    path.write_text(source)
    # A name inside pcdcodec.recording, so the module's relative imports resolve.
    spec = importlib.util.spec_from_file_location("pcdcodec.recording._baseline_writer", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.RecordingWriter


def fps(writer: Any, frames: list[tuple[Any, Any]], seq: Any, path: Path) -> float:
    start = time.perf_counter()
    rec = writer(path, intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True)
    for k, (color, depth) in enumerate(frames):
        rec.write(color, depth, k * 33_333_333)
    rec.close()
    elapsed = time.perf_counter() - start
    with pcdcodec.open(path) as back:
        assert len(back) == len(frames)
    return len(frames) / elapsed


def idle_latency(frames: list[tuple[Any, Any]], seq: Any, path: Path) -> list[float]:
    """Seconds from handing a frame to an idle writer until it is written, per frame."""
    latencies = []
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True
    ) as rec:
        for k, (color, depth) in enumerate(frames):
            time.sleep(0.2)
            start = time.perf_counter()
            rec.write(color, depth, k * 33_333_333)
            rec.flush()
            latencies.append(time.perf_counter() - start)
            assert rec.frames_complete == k + 1
    return latencies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", required=True, help="git revision of the other writer")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--rounds", type=int, default=8)
    args = parser.parse_args()
    seq = pcdcodec.load_sample()
    frames = [(seq[k % len(seq)].color, seq[k % len(seq)].depth) for k in range(args.frames)]
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        old = baseline_writer(args.baseline, workdir)
        new = pcdcodec.RecordingWriter
        fps(new, frames[:5], seq, workdir / "warm.pcdc")  # the codecs' start-up, once
        ratios = []
        for r in range(args.rounds):
            order = [(old, "old"), (new, "new")]
            if r % 2:
                order.reverse()
            got = {name: fps(w, frames, seq, workdir / f"{name}.pcdc") for w, name in order}
            ratios.append(got["new"] / got["old"])
            print(
                f"round {r}: baseline {got['old']:.1f} fps, checked out {got['new']:.1f} fps, "
                f"ratio {ratios[-1]:.3f}",
                flush=True,
            )
        print(
            f"ratio (checked out / {args.baseline}) over {args.rounds} rounds of {args.frames} "
            f"frames: median {statistics.median(ratios):.3f}, min {min(ratios):.3f}, "
            f"max {max(ratios):.3f}"
        )
        ms = [1000 * t for t in idle_latency(frames[:30], seq, workdir / "idle.pcdc")]
        print(
            f"idle writer, from write() to written and flushed, {len(ms)} frames: median "
            f"{statistics.median(ms):.1f} ms, max {max(ms):.1f} ms"
        )


if __name__ == "__main__":
    main()
