"""Where the time of one played frame goes: decode plus tensor point cloud, on one core.

Run: ``python scripts/playback_profile.py [--sets sample,tum_fr1_rpy,realsense_d435]
[--frames 30] [--rounds 7] [--depth depthac,jpegxl]``.

Each set is written once per depth codec (h264 color, the default), then played as
``benchmarks/test_bench_recording.py`` plays it (``pcdcodec.open``, every frame in order,
``frame.to_point_cloud(tensor=True)``), with the process pinned to one CPU. The steps of a
played frame are timed apart, each as a pass over every frame, all interleaved round by round
(the best of ``--rounds`` each, so a busy neighbour lands on every step alike), in CPU time of
the process (see :data:`CLOCK`):

* **open**: ``pcdcodec.open`` (index, header records, seal), shared by the frames;
* **record reading**: every depth message, color packet and pose read from its chunk and
  checked against the frame's digest (``depth_bytes``, ``packets``, ``poses``);
* **color decode**: the h264 packets to YUV frames (PyAV, the decoder's thread settings);
* **yuv -> rgb**: those frames to RGB arrays (``to_ndarray(format="rgb24")``);
* **depth decode**: the depth codec's ``decode`` of each frame's bytes;
* **reader, other**: iterating the recording without point clouds, less the steps above
  (index look-ups, per-frame checks, ``Frame`` building);
* **point cloud**: ``to_point_cloud(tensor=True)`` of the decoded frames (positions and
  colors), its positions' count read as the benchmark reads it;
* **loop, other**: the whole played pass less the iteration and the point clouds.

The last two rows are differences of best times, so noise can make them slightly negative.
The table gives ms per frame and the share of the played frame, and fps of the whole pass.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import RGBDSequence, load_folder, load_sample

#: The process's CPU time: pinned to one core, that is its wall time less the time other
#: processes held the core (on a shared machine, a neighbour at real-time priority can take the
#: core for most of a second). ``--wall`` times with the wall clock instead.
CLOCK = time.process_time

STEPS = (
    "open",
    "record reading",
    "color decode",
    "yuv -> rgb",
    "depth decode",
    "reader, other",
    "point cloud",
    "loop, other",
)


@contextmanager
def one_core(cpu: int | None = None) -> Iterator[None]:
    """Pin the process to ``cpu`` (default: its last CPU, as CPU 0 also serves interrupts)
    while the block runs."""
    if not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {max(before) if cpu is None else cpu})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


def load(name: str, frames: int) -> RGBDSequence:
    """The first ``frames`` frames of a set, as the recording benchmark loads them."""
    if name == "sample":
        seq = load_sample()
        seq.frames = seq.frames[:frames]
        return seq
    s = SEQUENCES[name]
    seq = load_folder(
        s.root,
        max_frames=frames,
        layout="folders" if name == "realsense_d435" else "auto",
        depth_scale=s.depth_scale,
    )
    if seq.intrinsics is None:
        h, w = seq[0].depth.shape
        seq.intrinsics = pcdcodec.CameraIntrinsics(w, h, 615.0, 615.0, w / 2, h / 2)
    return seq


def write(seq: RGBDSequence, path: Path, depth: str) -> Path:
    """``seq`` recorded with the default color codec and ``depth``."""
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        depth=depth,
        overwrite=True,
    ) as rec:
        rec.write_frames(seq)
    return path


def play(path: Path) -> int:
    """The benchmark's played pass: decode every frame and build its tensor point cloud."""
    points = 0
    with pcdcodec.open(path) as rec:
        for frame in rec:
            points += frame.to_point_cloud(tensor=True).point.positions.shape[0]
    return points


def iterate(path: Path) -> int:
    """Every frame decoded in order, no point cloud."""
    n = 0
    with pcdcodec.open(path) as rec:
        for frame in rec:
            n += frame.depth.shape[0]
    return n


def open_only(path: Path) -> int:
    with pcdcodec.open(path) as rec:
        return len(rec)


def read_records(path: Path) -> int:
    """Every depth message, color packet and pose, read and checked, none decoded."""
    with pcdcodec.open(path) as rec:
        size = sum(len(rec.depth_bytes(i)) for i in range(len(rec)))
        size += sum(len(p.data) for p in rec.packets())
        rec.poses()
    return size


class Parts:
    """A recording's encoded frames and decoded images, made once, for the per-step passes."""

    def __init__(self, path: Path) -> None:
        import av

        with pcdcodec.open(path) as rec:
            self.depth_data = [rec.depth_bytes(i) for i in range(len(rec))]
            self.depth_codec = rec.depth_codec
            self.packets = list(rec.packets())
            self.extradata = rec.extradata
            codec: Any = rec.color_codec
            self.decoder_name: str = codec.decoder_name
            self.threads: int = codec.threads
            self.frames = list(rec)
            self.width, self.height = rec.intrinsics.width, rec.intrinsics.height
        self.av_packets = [self._av_packet(p) for p in self.packets]
        self.yuv = self.decode_color()
        assert len(self.yuv) == len(self.frames)
        self._av = av

    def _av_packet(self, p: Any) -> Any:
        from pcdcodec.color.ffmpeg import ffmpeg_packet

        avp = ffmpeg_packet(p.data)
        avp.pts, avp.dts = p.pts, p.dts
        return avp

    def decode_color(self) -> list[Any]:
        """The color packets decoded to FFmpeg frames, with the reader's decoder settings."""
        import av

        ctx: Any = av.CodecContext.create(self.decoder_name, "r")
        ctx.width, ctx.height = self.width, self.height
        if self.extradata:
            ctx.extradata = self.extradata
        ctx.thread_type = "SLICE"
        ctx.thread_count = self.threads
        out = []
        for p in self.av_packets:
            out.extend(ctx.decode(p))
        out.extend(ctx.decode(None))
        return out

    def to_rgb(self) -> int:
        return sum(f.to_ndarray(format="rgb24").shape[0] for f in self.yuv)

    def decode_depth(self) -> int:
        return sum(self.depth_codec.decode(d).shape[0] for d in self.depth_data)

    def clouds(self) -> int:
        return sum(f.to_point_cloud(tensor=True).point.positions.shape[0] for f in self.frames)


def best_times(passes: dict[str, Callable[[], Any]], rounds: int) -> dict[str, float]:
    """The best time (s) of each pass over ``rounds`` rounds, the passes interleaved."""
    best = dict.fromkeys(passes, float("inf"))
    for fn in passes.values():
        fn()  # warm: numba, FFmpeg, Open3D, the page cache
    for _ in range(rounds):
        for name, fn in passes.items():
            t = CLOCK()
            fn()
            best[name] = min(best[name], CLOCK() - t)
    return best


def profile(path: Path, rounds: int) -> dict[str, Any]:
    """The steps of a played frame of the recording at ``path`` (ms per frame), and its fps."""
    parts = Parts(path)
    n = len(parts.frames)
    t = best_times(
        {
            "play": lambda: play(path),
            "iterate": lambda: iterate(path),
            "open": lambda: open_only(path),
            "record reading": lambda: read_records(path),
            "color decode": parts.decode_color,
            "yuv -> rgb": parts.to_rgb,
            "depth decode": parts.decode_depth,
            "point cloud": parts.clouds,
        },
        rounds,
    )
    ms = {k: v * 1000 / n for k, v in t.items()}
    steps = {k: ms[k] for k in ("open", "record reading", "color decode", "yuv -> rgb")}
    steps["depth decode"] = ms["depth decode"]
    steps["reader, other"] = ms["iterate"] - sum(steps.values())
    steps["point cloud"] = ms["point cloud"]
    steps["loop, other"] = ms["play"] - ms["iterate"] - ms["point cloud"]
    return {"frames": n, "total_ms": ms["play"], "fps": 1000 / ms["play"], "steps": steps}


def table(name: str, depth: str, result: dict[str, Any]) -> str:
    total = result["total_ms"]
    lines = [
        f"{name}, depth={depth}: {result['frames']} frames, {total:.2f} ms per frame, "
        f"{result['fps']:.1f} fps (one core)"
    ]
    for step in STEPS:
        v = result["steps"][step]
        lines.append(f"  {step:<16}{v:8.2f} ms {100 * v / total:6.1f} %")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", default="sample,tum_fr1_rpy,realsense_d435")
    ap.add_argument("--depth", default="depthac,jpegxl", help="depth codecs, comma-separated")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cpu", type=int, default=None, help="the CPU to run on (default: the last)")
    ap.add_argument("--wall", action="store_true", help="time with the wall clock")
    args = ap.parse_args(argv)
    global CLOCK
    CLOCK = time.perf_counter if args.wall else time.process_time
    sets = [s for s in args.sets.split(",") if s == "sample" or SEQUENCES[s].present]
    with tempfile.TemporaryDirectory() as tmp, one_core(args.cpu):
        for name in sets:
            seq = load(name, args.frames)
            for depth in args.depth.split(","):
                path = write(seq, Path(tmp) / f"{name}-{depth}.pcdc", depth)
                print(table(name, depth, profile(path, args.rounds)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
