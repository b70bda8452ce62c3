"""Writing and reading recordings: frames per second with the default codecs.

Targets: a 640×480 stream records at ≥ 30 fps on two cores (color and depth are encoded on two
threads). Decoding plus the tensor point cloud of the default recording plays back at ≥ 100 fps
on one core, on the sample, TUM and D435, and no slower than the same recording with
``depth="jpegxl"``: the playback benchmark pins the process to a single CPU while it runs and
puts the two depth codecs side by side in one group per set (``scripts/playback_profile.py``
says where the time of a played frame goes, step by step). Reading in order with
``threads=2`` plays back ≥ 1.7× as fast as one core on a quiet 2-core machine: the
``threads`` benchmarks put ``threads=1`` and ``threads=2`` side by side in one group per set
(``benchmarks/read_threads.py`` measures the ratio interleaved, against a pinned core).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import RGBDSequence, load_folder, load_sample

FRAMES = 30
PRESENT = [name for name in ("sample", "tum_fr1_rpy", "realsense_d435") if SEQUENCES[name].present]


def sequence(name: str) -> RGBDSequence:
    if name == "sample":
        return load_sample()
    seq = load_folder(
        SEQUENCES[name].root,
        max_frames=FRAMES,
        layout="folders" if name == "realsense_d435" else "auto",
        depth_scale=SEQUENCES[name].depth_scale,
    )
    if seq.intrinsics is None:
        h, w = seq[0].depth.shape
        seq.intrinsics = pcdcodec.CameraIntrinsics(w, h, 615.0, 615.0, w / 2, h / 2)
    return seq


_cache: dict[str, RGBDSequence] = {}


def cached(name: str) -> RGBDSequence:
    if name not in _cache:
        _cache[name] = sequence(name)
    return _cache[name]


def write(seq: RGBDSequence, path: Path, depth: str = pcdcodec.DEFAULT_DEPTH_CODEC) -> Path:
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


@contextmanager
def one_core() -> Iterator[None]:
    """Pin this process (all its threads) to one CPU while the block runs."""
    if not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    # The last CPU: on shared machines CPU 0 also serves interrupts and is measurably slower.
    os.sched_setaffinity(0, {max(before)})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


@pytest.mark.parametrize("name", PRESENT)
def test_record(benchmark: Any, tmp_path: Path, name: str) -> None:
    seq = cached(name)
    path = tmp_path / "bench.pcdc"
    benchmark.group = "recording: write with the default codecs (h264 + depthac), two threads"
    benchmark.extra_info.update(kind="recording", op="write", sequence=name, frames=len(seq))
    benchmark.pedantic(write, args=(seq, path), rounds=3, iterations=1, warmup_rounds=1)
    with pcdcodec.open(path) as rec:
        assert len(rec) == len(seq)  # correct, not just fast
        assert (rec[len(seq) // 2].depth == seq[len(seq) // 2].depth).all()


def play(path: Path, threads: int | None = None, clouds: bool = True) -> int:
    """Read every frame in order; the number of points (clouds) or of valid depth pixels."""
    points = 0
    with pcdcodec.open(path, threads=threads) as rec:
        for frame in rec:
            if clouds:
                points += frame.to_point_cloud(tensor=True).point.positions.shape[0]
            else:
                points += int(np.count_nonzero(frame.depth))
    return points


@pytest.mark.parametrize("depth", ["jpegxl", "depthac"])
@pytest.mark.parametrize("name", PRESENT)
def test_playback_with_point_clouds_one_core(
    benchmark: Any, tmp_path: Path, name: str, depth: str
) -> None:
    seq = cached(name)
    path = write(seq, tmp_path / "play.pcdc", depth)
    expected = sum(int((f.depth > 0).sum()) for f in seq)
    benchmark.group = f"recording: decode + point cloud (tensor), one core, {name}"
    benchmark.extra_info.update(
        kind="recording", op="play", sequence=name, frames=len(seq), depth=depth
    )
    with one_core():
        points = benchmark.pedantic(play, args=(path,), rounds=3, iterations=1, warmup_rounds=1)
    assert points == expected


_written: dict[str, Path] = {}


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("clouds", [True, False], ids=["decode+cloud", "decode"])
@pytest.mark.parametrize("name", PRESENT)
def test_playback_threads(
    benchmark: Any,
    tmp_path_factory: pytest.TempPathFactory,
    name: str,
    clouds: bool,
    threads: int,
) -> None:
    seq = cached(name)
    if name not in _written:
        _written[name] = write(seq, tmp_path_factory.mktemp("threads") / f"{name}.pcdc")
    expected = sum(int((f.depth > 0).sum()) for f in seq)
    what = "decode + point cloud (tensor)" if clouds else "decode"
    benchmark.group = f"recording: in-order {what}, {name}, threads=1 against threads=2"
    benchmark.extra_info.update(
        kind="recording",
        op="play" if clouds else "decode",
        sequence=name,
        frames=len(seq),
        threads=threads,
    )
    points = benchmark.pedantic(
        play, args=(_written[name], threads, clouds), rounds=5, iterations=1, warmup_rounds=1
    )
    assert points == expected


# A fresh process (one-off costs are paid once per process): open a writer, then write and flush
# frames one at a time; prints how long open() took, the first frame's write() + flush(), and
# the median of the next frames'.
FIRST_FRAME = """
import statistics, sys, time
import pcdcodec
seq = pcdcodec.load_sample(max_frames=12)
began = time.perf_counter()
rec = pcdcodec.open(sys.argv[1], "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale)
took = [time.perf_counter() - began]
for k, f in enumerate(seq):
    began = time.perf_counter()
    rec.write(f.color, f.depth, k * 33_333_333)
    rec.flush()
    took.append(time.perf_counter() - began)
rec.close()
print(took[0], took[1], statistics.median(took[3:]))
"""


def test_first_frame_against_a_steady_one(benchmark: Any, tmp_path: Path) -> None:
    """How much longer a fresh writer's first frame takes to be written than a steady frame
    (``extra_info["ratio"]``; the codecs are readied when the writer opens, so the ratio stays
    near the cost of a keyframe), and how long ``open()`` takes (``open_ms``)."""
    import subprocess
    import sys

    runs: list[tuple[float, ...]] = []

    def run() -> None:
        path = tmp_path / "first.pcdc"
        path.unlink(missing_ok=True)
        out = subprocess.run(
            [sys.executable, "-c", FIRST_FRAME, str(path)],
            capture_output=True,
            text=True,
            check=True,
            cwd=tmp_path,
        ).stdout
        runs.append(tuple(float(v) for v in out.split()))

    benchmark.group = "recording: a fresh writer's first frame against a steady one"
    benchmark.pedantic(run, rounds=5, iterations=1, warmup_rounds=1)
    opened, first, steady = (float(np.median([r[i] for r in runs])) for i in range(3))
    benchmark.extra_info.update(
        kind="first-frame",
        open_ms=round(opened * 1000, 1),
        first_ms=round(first * 1000, 1),
        steady_ms=round(steady * 1000, 1),
        ratio=round(first / steady, 2),
    )
