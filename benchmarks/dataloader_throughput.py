"""Training-data throughput: ``pcdcodec.torch`` datasets against PNG files and raw ``.npy``.

For each set (the TUM fr1_rpy, RealSense D435 and 7-Scenes frames of ``../shared/data`` where
present, the bundled sample otherwise) this writes the same ``--frames`` frames (each set played
forward and back, as ``benchmarks/random_access.py`` does) several ways: a ``.pcdc`` recording
per ``--variants`` value (a color codec spec as the command line takes it, ``training`` for
``pcdcodec.torch.TRAINING_COLOR``; depthac depth), a color PNG and a 16-bit depth PNG per frame
(OpenCV, zlib level 6), and a color and a depth ``.npy`` per frame. The color quality of each
recording (PSNR of its decoded color against the original frames, mean and lowest frame) is
printed with its size. Then, round after round (after one to warm up), each in
turn and in a new random order every round, so that a slow spell of a shared machine lands on
all of them:

- one process reads every frame (color and depth) in a random order and in order, and its frames
  per second are printed (median over rounds, range in brackets), wall-clock and CPU time;
- a ``DataLoader`` (batches of 8, fork) with 1, 2 and 4 workers reads an epoch, shuffled (and,
  for the recording, also in order through ``IterableRecordingDataset``): frames per second
  from its first batch to its last.

The bytes per frame of each way of storing the frames come with them, and the CPU time that
writing each recording took per frame (every thread of the process: color and depth encoding).

    python benchmarks/dataloader_throughput.py --rounds 3
    python benchmarks/dataloader_throughput.py --variants training h264:gop=5 av1:gop=2 \
        --workers 1 2 --frames 150
"""

from __future__ import annotations

import argparse
import random
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from torch.utils.data import DataLoader, Dataset

import pcdcodec
from benchmarks.random_access import PRESENT, SETS, looped, sequence
from pcdcodec.registry import parse_codec_spec
from pcdcodec.torch import TRAINING_COLOR, IterableRecordingDataset, RecordingDataset

FRAMES = 300
FIELDS = ["color", "depth"]


class PngFrames(Dataset[Any]):
    """Frame ``i`` from ``color/{i}.png`` (RGB) and ``depth/{i}.png`` (16-bit)."""

    def __init__(self, root: Path, n: int) -> None:
        self.root, self.n = root, n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> dict[str, Any]:
        bgr = cv2.imread(str(self.root / "color" / f"{i:06d}.png"), cv2.IMREAD_COLOR)
        depth = cv2.imread(str(self.root / "depth" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        return {"color": cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), "depth": depth}


class NpyFrames(Dataset[Any]):
    """Frame ``i`` from ``color/{i}.npy`` and ``depth/{i}.npy``."""

    def __init__(self, root: Path, n: int) -> None:
        self.root, self.n = root, n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> dict[str, Any]:
        return {
            "color": np.load(self.root / "color" / f"{i:06d}.npy"),
            "depth": np.load(self.root / "depth" / f"{i:06d}.npy"),
        }


def write_files(seq: Any, root: Path, frames: int) -> tuple[Path, Path]:
    """The frames as PNG files and as ``.npy`` files; the two folders."""
    png, npy = root / "png", root / "npy"
    for top in (png, npy):
        (top / "color").mkdir(parents=True)
        (top / "depth").mkdir(parents=True)
    level = [cv2.IMWRITE_PNG_COMPRESSION, 6]
    for k, (rgb, depth) in enumerate(looped(seq, frames)):
        name = f"{k:06d}"
        cv2.imwrite(str(png / "color" / f"{name}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), level)
        cv2.imwrite(str(png / "depth" / f"{name}.png"), depth, level)
        np.save(npy / "color" / f"{name}.npy", rgb)
        np.save(npy / "depth" / f"{name}.npy", depth)
    return png, npy


def color_config(variant: str) -> dict[str, Any]:
    """The color codec config of a variant: ``"training"`` (``TRAINING_COLOR``) or a codec spec
    as the command line takes it, e.g. ``"h264:gop=5,tune=fastdecode"``."""
    if variant == "training":
        return dict(TRAINING_COLOR)
    return parse_codec_spec(variant, kind="color").get_config()


def psnr(a: Any, b: Any) -> float:
    """Peak signal-to-noise ratio of two uint8 images, in dB (99 where they are equal)."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return 10 * float(np.log10(255.0**2 / mse)) if mse else 99.0


def color_quality(seq: Any, path: Path, frames: int) -> tuple[float, float]:
    """Mean and lowest PSNR of the recording's decoded color against the original frames."""
    with pcdcodec.open(path) as rec:
        values = [
            psnr(frame.color, rgb) for frame, (rgb, _) in zip(rec, looped(seq, frames), strict=True)
        ]
    return statistics.fmean(values), min(values)


def write_recording(seq: Any, path: Path, frames: int, variant: str) -> Path:
    """``frames`` frames of ``seq`` at 30 fps, color as ``variant`` says, depth the default."""
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color=color_config(variant),
        fps=30.0,
        overwrite=True,
    ) as rec:
        for k, (rgb, d) in enumerate(looped(seq, frames)):
            rec.write(rgb, d, timestamp=round(k * 1e9 / 30))
    return path


def folder_bytes(root: Path) -> int:
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file())


def one_pass(items: Iterable[Any]) -> tuple[float, float, int]:
    """Wall-clock and CPU seconds to take every item, and the number of items."""
    c0, t0 = time.process_time(), time.perf_counter()
    n = 0
    for item in items:
        assert item["depth"].dtype == np.uint16
        n += 1
    return time.perf_counter() - t0, time.process_time() - c0, n


def loader_pass(dataset: Any, workers: int, shuffle: bool) -> float:
    """Frames per second of one DataLoader epoch, from its first batch to its last."""
    loader = DataLoader(
        dataset,
        batch_size=8,
        shuffle=shuffle,
        num_workers=workers,
        multiprocessing_context="fork" if workers else None,
    )
    it = iter(loader)
    first = next(it)
    t0 = time.perf_counter()
    n = 0
    for batch in it:
        n += len(batch["depth"])
    del first
    return n / (time.perf_counter() - t0)


def spread(values: list[float], digits: int = 0) -> str:
    if not values:
        return "-"
    med = statistics.median(values)
    return f"{med:.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="*", default=PRESENT, choices=[*SETS, "sample"])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--frames", type=int, default=FRAMES)
    parser.add_argument(
        "--variants",
        nargs="*",
        default=["training", "h264:gop=5,tune=fastdecode", "h264:gop=5", "h264"],
        help='color of the recordings to write: "training" (TRAINING_COLOR) or a codec spec '
        '("h264:gop=5,tune=fastdecode")',
    )
    parser.add_argument("--workers", nargs="*", type=int, default=[1, 2, 4])
    parser.add_argument(
        "--loader-variant", default=None, help="recording of the DataLoader runs (first variant)"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    print(f"pcdcodec {pcdcodec.__version__}; {args.frames} frames per set; {args.rounds} rounds")
    for name in args.sets:
        work = Path(tempfile.mkdtemp(prefix="dataloader-"))
        try:
            measure(name, work, args, rng)
        finally:
            shutil.rmtree(work, ignore_errors=True)


def measure(name: str, work: Path, args: argparse.Namespace, rng: random.Random) -> None:
    """Write set ``name`` each way into ``work``, measure, print its tables."""
    loader_gop = args.loader_variant or args.variants[0]
    seq = sequence(name)
    recs: dict[str, Path] = {}
    encode_ms: dict[str, float] = {}
    for k, g in enumerate(args.variants):
        c0 = time.process_time()  # every thread of the process: the encoders' too
        recs[g] = write_recording(seq, work / f"variant{k}.pcdc", args.frames, g)
        encode_ms[f"pcdc {g}"] = (time.process_time() - c0) * 1000 / args.frames
    quality = {f"pcdc {g}": color_quality(seq, p, args.frames) for g, p in recs.items()}
    png, npy = write_files(seq, work, args.frames)
    n = args.frames
    sizes = {f"pcdc {g}": p.stat().st_size / n for g, p in recs.items()}
    sizes["PNG"] = folder_bytes(png) / n
    sizes["npy"] = folder_bytes(npy) / n
    makers: dict[str, Callable[[list[int]], Iterable[Any]]] = {}
    for g, p in recs.items():
        makers[f"pcdc {g}|random"] = lambda o, p=p: _indexed(RecordingDataset(p, FIELDS), o)
        makers[f"pcdc {g}|in order"] = lambda o, p=p: IterableRecordingDataset(p, FIELDS)
    makers["PNG|random"] = lambda o: _indexed(PngFrames(png, n), o)
    makers["PNG|in order"] = lambda o: _indexed(PngFrames(png, n), list(range(n)))
    makers["npy|random"] = lambda o: _indexed(NpyFrames(npy, n), o)
    makers["npy|in order"] = lambda o: _indexed(NpyFrames(npy, n), list(range(n)))
    wall: dict[str, list[float]] = {k: [] for k in makers}
    cpu: dict[str, list[float]] = {k: [] for k in makers}
    loaders: dict[str, Callable[[], Any]] = {
        f"pcdc {loader_gop}|random": lambda: RecordingDataset(recs[loader_gop], FIELDS),
        f"pcdc {loader_gop}|in order": lambda: IterableRecordingDataset(recs[loader_gop], FIELDS),
        "PNG|random": lambda: PngFrames(png, n),
        "npy|random": lambda: NpyFrames(npy, n),
    }
    loader_fps: dict[tuple[str, int], list[float]] = {
        (k, w): [] for k in loaders for w in args.workers
    }
    for round_ in range(args.rounds + 1):
        order = list(range(n))
        rng.shuffle(order)
        keys = list(makers)
        rng.shuffle(keys)
        for key in keys:
            w_s, c_s, got = one_pass(makers[key](order))
            assert got == n
            if round_:  # the first round warms up (page cache, compiled kernels)
                wall[key].append(n / w_s)
                cpu[key].append(n / c_s)
        if not round_:
            continue
        runs = list(loader_fps)
        rng.shuffle(runs)
        for key, w in runs:
            ds = loaders[key]()
            loader_fps[(key, w)].append(loader_pass(ds, w, key.endswith("random")))
    print(f"\n## {name}: {n} frames of {seq.intrinsics.width}x{seq.intrinsics.height}")
    print(
        "\n| stored as | bytes/frame | PNG / this | npy / this | color PSNR, dB (lowest) "
        "| random fps | in order fps | CPU: random fps | in order fps | encode CPU ms/frame |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, size in sizes.items():
        r, o = f"{label}|random", f"{label}|in order"
        mean, low = quality.get(label, (99.0, 99.0))
        encode = f"{encode_ms[label]:.1f}" if label in encode_ms else "-"
        print(
            f"| {label} | {size:,.0f} | {sizes['PNG'] / size:.1f} | {sizes['npy'] / size:.1f} | "
            f"{mean:.2f} ({low:.2f}) | "
            f"{spread(wall[r])} | "
            f"{spread(wall[o])} | {spread(cpu[r])} | {spread(cpu[o])} | {encode} |"
        )
    if not args.workers:
        return
    heads = " | ".join(f"{w} worker{'s' * (w > 1)}" for w in args.workers)
    print(f"\n| DataLoader, frames/s | {heads} |")
    print("|---|" + "---|" * len(args.workers))
    for key in loaders:
        cells = " | ".join(spread(loader_fps[(key, w)]) for w in args.workers)
        print(f"| {key.replace('|', ', ')} | {cells} |")
    sys.stdout.flush()


def _indexed(dataset: Any, order: list[int]) -> Iterable[Any]:
    return (dataset[i] for i in order)


if __name__ == "__main__":
    main()
