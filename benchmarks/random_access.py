"""Random access against reading in order: ``rec[i]`` for random ``i`` over a 300-frame recording.

Writes a recording of ``--frames`` frames (default 300) for each set: the TUM fr1_rpy, RealSense
D435 and 7-Scenes frames of ``../shared/data`` where present (the bundled sample otherwise), each
played forward and back again as often as it takes (no set has 300 frames; going back and forth
keeps the motion smooth, so the color stream codes as a real one would). Then, round after round,
it reads the recording in order and in a random order (a new permutation each round), one after
the other, each from a fresh :func:`pcdcodec.open`, and prints the milliseconds per frame of both
(median over rounds) and their ratio, random over in order (median, and its range over rounds):
the "random access" row of the targets asks for at most 2. Both in wall-clock time and in the
process's CPU time, which the other processes of a shared machine disturb far less.

``--breakdown`` adds where a random frame's time goes, measured in one more pass of each kind:
depth (read, check, decode), color packets (read, check), color decoding (the frames from the
keyframe before the one asked for, which random access decodes but does not show), color
conversion (YUV to RGB) and the rest (building the frame, its pose, the digests); and how many
color packets each frame decoded. ``--gops`` writes one recording per keyframe interval and adds
the color bytes per frame, the file's bytes per frame and its ratio against a PointCloud2
XYZRGB (32 bytes per point) of the valid points: how ``gop`` trades random access against
size. ``--depth`` and ``--color`` choose the codecs, so the table can be measured again when a
codec changes (a faster depth decoder makes the color stream's share, and so the ratio, larger).

    python benchmarks/random_access.py --rounds 5 --breakdown
    python benchmarks/random_access.py --rounds 5 --gops 5 10 15 30 60
    python benchmarks/random_access.py --rounds 5 --gops 5 10 15 30 60 --color h265
    python benchmarks/random_access.py --rounds 5 --depth rvl --sets tum_fr1_rpy
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.results import POINTCLOUD2_BYTES_PER_POINT
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import RGBDSequence, load_folder, load_sample

#: The sets of the measurement, where present; the bundled sample stands in when none is.
SETS = [name for name in ("tum_fr1_rpy", "realsense_d435", "7scenes_redkitchen")]
PRESENT = [name for name in SETS if SEQUENCES[name].present] or ["sample"]
FRAMES = 300


def sequence(name: str) -> RGBDSequence:
    """Every frame of set ``name`` (the sample's 15 for ``"sample"``)."""
    if name == "sample":
        return load_sample()
    s = SEQUENCES[name]
    seq = load_folder(s.root, **s.reader_options())
    if seq.intrinsics is None:
        seq.intrinsics = s.camera
    return seq


def looped(seq: RGBDSequence, frames: int) -> Iterator[tuple[Any, Any]]:
    """``frames`` (color, depth) pairs: the sequence forward, back, forward, ... (never a cut)."""
    n = len(seq)
    order = list(range(n)) + list(range(n - 2, 0, -1)) if n > 1 else [0]
    for k in range(frames):
        frame = seq[order[k % len(order)]]
        yield frame.color, frame.depth


def write(
    seq: RGBDSequence,
    path: Path,
    *,
    frames: int = FRAMES,
    color: str = "h264",
    gop: int | None = None,
    depth: str | None = None,
) -> Path:
    """A recording of ``frames`` frames of ``seq`` at 30 fps with the given codecs."""
    codec = pcdcodec.get_codec(color, gop=gop) if gop is not None else pcdcodec.get_codec(color)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color=codec,
        depth=depth or pcdcodec.DEFAULT_DEPTH_CODEC,
        fps=30.0,
        overwrite=True,
    ) as rec:
        for k, (rgb, d) in enumerate(looped(seq, frames)):
            rec.write(rgb, d, timestamp=round(k * 1e9 / 30))
    return path


def in_order(path: Path, threads: int | None = None) -> int:
    """Read every frame in order; the number of valid depth pixels."""
    valid = 0
    with pcdcodec.open(path, threads=threads) as rec:
        for frame in rec:
            valid += int(np.count_nonzero(frame.depth))
    return valid


def at_random(path: Path, order: list[int], threads: int | None = None) -> int:
    """Read the frames ``order`` names, one ``rec[i]`` each; the number of valid depth pixels."""
    valid = 0
    with pcdcodec.open(path, threads=threads) as rec:
        for i in order:
            valid += int(np.count_nonzero(rec[i].depth))
    return valid


def interleaved(
    path: Path, rounds: int, seed: int = 0, threads: int | None = None
) -> dict[str, list[float]]:
    """Seconds per frame in order and at random, one pass of each per round (after one to warm
    up): wall-clock time, and this process's CPU time (all its threads), which other processes
    on a shared machine disturb far less."""
    with pcdcodec.open(path) as rec:
        n = len(rec)
    rng = random.Random(seed)
    times: dict[str, list[float]] = {
        "in order": [],
        "random": [],
        "in order cpu": [],
        "random cpu": [],
    }
    for round_ in range(rounds + 1):
        order = list(range(n))
        rng.shuffle(order)
        passes: list[tuple[str, Callable[[], int]]] = [
            ("in order", lambda: in_order(path, threads)),
            ("random", lambda order=order: at_random(path, order, threads)),  # type: ignore[misc]
        ]
        if round_ % 2:  # alternate which goes first, so a slow spell lands on both
            passes.reverse()
        got = []
        for key, run in passes:
            c0, t0 = time.process_time(), time.perf_counter()
            got.append(run())
            if round_:
                times[key].append((time.perf_counter() - t0) / n)
                times[key + " cpu"].append((time.process_time() - c0) / n)
        assert got[0] == got[1], "random access read other frames than reading in order"
    return times


@contextmanager
def timing(cls: Any, name: str, into: dict[str, float], key: str) -> Iterator[None]:
    """Add the seconds spent in ``cls.name`` (when the class has it) to ``into[key]``."""
    original = getattr(cls, name, None)
    if original is None:
        yield
        return

    def timed(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            into[key] = into.get(key, 0.0) + time.perf_counter() - t0
            into[key + " calls"] = into.get(key + " calls", 0.0) + 1

    setattr(cls, name, timed)
    try:
        yield
    finally:
        setattr(cls, name, original)


def breakdown(path: Path, order: list[int]) -> dict[str, float]:
    """Milliseconds per frame of each step of reading the frames of ``order`` one by one."""
    from contextlib import ExitStack

    from pcdcodec.color.ffmpeg import FFmpegDecoder
    from pcdcodec.recording._packets import PacketAccess
    from pcdcodec.recording.reader import Recording

    spent: dict[str, float] = {}
    with ExitStack() as stack:
        stack.enter_context(timing(Recording, "_depth", spent, "depth"))
        stack.enter_context(timing(PacketAccess, "_packet", spent, "color packets"))
        stack.enter_context(timing(FFmpegDecoder, "_run", spent, "color decode"))
        # The conversion to RGB: one picture at a time where the decoder converts on demand.
        stack.enter_context(timing(FFmpegDecoder, "_rgb", spent, "color to RGB"))
        if not hasattr(FFmpegDecoder, "_rgb"):
            stack.enter_context(timing(FFmpegDecoder, "_frames", spent, "color to RGB"))
        with pcdcodec.open(path) as rec:
            t0 = time.perf_counter()
            for i in order:
                rec[i]
            total = time.perf_counter() - t0
    n = len(order)
    convert = spent.get("color to RGB", 0.0)
    decode = spent.get("color decode", 0.0)
    if not hasattr(FFmpegDecoder, "_rgb"):
        decode -= convert  # _frames ran inside _run
    rows = {
        "depth": spent.get("depth", 0.0),
        "color packets": spent.get("color packets", 0.0),
        "color decode": decode,
        "color to RGB": convert,
    }
    rows["frame, pose, digests"] = total - sum(rows.values())
    out = {key: 1000 * value / n for key, value in rows.items()}
    out["total"] = 1000 * total / n
    out["packets decoded per frame"] = spent.get("color decode calls", 0.0) / n
    out["pictures converted per frame"] = spent.get("color to RGB calls", 0.0) / n
    return out


def sizes(path: Path) -> dict[str, float]:
    """Bytes per frame of the color packets and of the file, and the file's ratio against a
    PointCloud2 XYZRGB of the valid points."""
    with pcdcodec.open(path) as rec:
        n = len(rec)
        color = sum(len(p.data) for p in rec.packets())
        points = sum(int(np.count_nonzero(rec.depth(i))) for i in range(n))
    file_bytes = path.stat().st_size
    return {
        "color B/frame": color / n,
        "file B/frame": file_bytes / n,
        "x PointCloud2": points * POINTCLOUD2_BYTES_PER_POINT / file_bytes,
    }


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="*", default=PRESENT)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--frames", type=int, default=FRAMES)
    parser.add_argument("--color", default="h264", help="color codec (default h264)")
    parser.add_argument("--depth", default=None, help="depth codec (default: the default)")
    parser.add_argument(
        "--gops",
        nargs="*",
        type=int,
        default=None,
        help="keyframe intervals to write (default: the codec's own, ⅓ s of frames)",
    )
    parser.add_argument("--threads", type=int, default=None, help="pcdcodec.open(threads=)")
    parser.add_argument("--breakdown", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="random-access-"))
    depth = args.depth or pcdcodec.DEFAULT_DEPTH_CODEC
    gops: list[int | None] = list(args.gops) if args.gops else [None]
    print(
        f"{args.frames} frames, color {args.color}, depth {depth}, threads {args.threads}, "
        f"{args.rounds} rounds; ms per frame (median), random / in order (median, range)"
    )
    print(
        "| set | gop | in order ms | random ms | random / in order | CPU: in order ms "
        "| random ms | random / in order | color B/frame | file B/frame | x PointCloud2 |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    details = []
    for name in args.sets:
        seq = sequence(name)
        for gop in gops:
            path = write(
                seq,
                work / f"{name}-{gop}.pcdc",
                frames=args.frames,
                color=args.color,
                gop=gop,
                depth=depth,
            )
            t = interleaved(path, args.rounds, args.seed, args.threads)
            cells = []
            for clock in ("", " cpu"):
                ordered, shuffled = t["in order" + clock], t["random" + clock]
                ratios = [b / a for a, b in zip(ordered, shuffled, strict=True)]
                cells.append(
                    f"{1000 * statistics.median(ordered):.2f} "
                    f"| {1000 * statistics.median(shuffled):.2f} | {spread(ratios)}"
                )
            size = sizes(path)
            print(
                f"| {name} | {gop or 'default'} | {cells[0]} | {cells[1]} "
                f"| {size['color B/frame']:.0f} | {size['file B/frame']:.0f} "
                f"| {size['x PointCloud2']:.0f} |",
                flush=True,
            )
            if args.breakdown:
                order = list(range(args.frames))
                random.Random(args.seed).shuffle(order)
                details.append(
                    (
                        name,
                        gop,
                        breakdown(path, list(range(args.frames))),
                        breakdown(path, order),
                    )
                )
            path.unlink()
    if details:
        print()
        print("where a frame's time goes, ms per frame (one pass of each)")
        keys = list(details[0][2])
        print("| set | gop | read | " + " | ".join(keys) + " |")
        print("|---|---|---|" + "---|" * len(keys))
        for name, gop, ordered_steps, random_steps in details:
            for label, steps in (("in order", ordered_steps), ("random", random_steps)):
                print(
                    f"| {name} | {gop or 'default'} | {label} | "
                    + " | ".join(f"{steps[k]:.2f}" for k in keys)
                    + " |"
                )


if __name__ == "__main__":
    main()
