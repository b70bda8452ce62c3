"""Create, read, seek and drop the codecs of every stream codec in a loop, under a watchdog.

Run: ``python scripts/stress_codecs.py --runs 300`` (``--help`` for the options).

Each run, for every available PyAV stream codec (threaded where the codec allows, so worker
threads are in play), writes a short recording (encoders created, flushed and dropped), then
opens it and reads it twice in a row (the second pass re-creates the decoder and drops the
first), reads frames in random order (backward jumps re-create the decoder mid-stream), runs
``verify()``, closes it, and drops another open recording without closing it, to the garbage
collector. The paper-layout export (muxer and a full decode of the video) runs for a few
codecs. A watchdog (``faulthandler.dump_traceback_later``) dumps every thread's stack and exits
with status 1 if a run takes longer than ``--timeout`` seconds: a deadlock becomes a report
instead of a hung process. Exit status 0 means every run finished.
"""

from __future__ import annotations

import argparse
import faulthandler
import gc
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.color import PyAVCodec

#: Codecs whose export to the paper layout is exercised too.
EXPORTED = ("av1", "h264", "ffv1")


def stream_codecs() -> list[str]:
    return [
        name
        for name in pcdcodec.list_codecs("color", available_only=True)
        if issubclass(pcdcodec.codec_class(name), PyAVCodec)
    ]


def config(name: str, threads: int) -> dict[str, Any]:
    spec: dict[str, Any] = {"id": name}
    if "threads" in pcdcodec.codec_class(name).param_names():
        spec["threads"] = threads
    return spec


def write(path: Path, name: str, frames: list[Any], threads: int) -> None:
    h, w = frames[0].depth.shape
    cam = pcdcodec.CameraIntrinsics(w, h, 500.0, 500.0, w / 2, h / 2)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=cam,
        depth_scale=5000.0,
        color=config(name, threads),
        depth="zstd",
        overwrite=True,
    ) as rec:
        for i, f in enumerate(frames):
            rec.write(f.color, f.depth, i * 33_000_000)


def read(path: Path, rng: np.random.Generator) -> int:
    with pcdcodec.open(path) as rec:
        n = len(rec)
        for _ in range(2):  # two passes: the second re-creates the decoder
            count = sum(1 for _ in rec)
            if count != n:
                raise AssertionError(f"{path.name}: a pass gave {count} of {n} frames")
        for i in rng.integers(0, n, 8):
            rec[int(i)]
        rec[n - 1]
        rec[0]
        report = rec.verify()
        if not report.ok:
            raise AssertionError(f"{path.name}: verify found {report.errors}")
    dropped = pcdcodec.open(path)  # left to the garbage collector, decoder and all
    dropped[n // 2]
    del dropped
    gc.collect()
    return n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=100, help="runs (default: %(default)s)")
    parser.add_argument("--frames", type=int, default=40, help="frames per recording")
    parser.add_argument("--size", default="320x240", help="frame size WxH (default: %(default)s)")
    parser.add_argument("--threads", type=int, default=8, help="codec threads")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds one run may take")
    parser.add_argument("--codecs", default=None, help="comma-separated (default: all)")
    parser.add_argument("--no-export", action="store_true", help="skip the paper export")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.runs < 1 or args.frames < 2:
        parser.error("--runs must be at least 1 and --frames at least 2")
    w, h = (int(v) for v in args.size.lower().split("x"))
    names = args.codecs.split(",") if args.codecs else stream_codecs()
    sample = pcdcodec.load_sample()
    rng = np.random.default_rng(args.seed)
    frames = []
    for i in range(args.frames):
        f = sample[i % len(sample)]
        depth = np.ascontiguousarray(np.resize(f.depth, (h, w)))
        # Noise makes every frame costly to decode, so decoder threads are busy when dropped.
        noise = rng.integers(0, 48, (h, w, 1), dtype=np.uint8)
        color = np.ascontiguousarray(np.resize(f.color, (h, w, 3)) // 2 + noise)
        frames.append(pcdcodec.RGBDFrame(color, depth, i))
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-stress-"))
    print(f"{args.runs} runs over {', '.join(names)}: {args.frames} frames of {w}x{h}", flush=True)
    start = time.perf_counter()
    try:
        for run in range(1, args.runs + 1):
            faulthandler.dump_traceback_later(args.timeout, exit=True)
            t0 = time.perf_counter()
            for name in names:
                path = work / f"{name}.pcdc"
                write(path, name, frames, args.threads)
                read(path, rng)
                if name in EXPORTED and not args.no_export:
                    from pcdcodec.convert.paper import export_paper

                    export_paper(path, work / f"{name}-paper", overwrite=True)
            faulthandler.cancel_dump_traceback_later()
            print(f"run {run}/{args.runs} ok ({time.perf_counter() - t0:.1f} s)", flush=True)
    finally:
        faulthandler.cancel_dump_traceback_later()
        shutil.rmtree(work, ignore_errors=True)
    total = time.perf_counter() - start
    print(f"{args.runs} runs without a hang in {total:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
