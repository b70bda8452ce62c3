"""Feed a recording to a PyTorch DataLoader, shuffled and in order, and print the throughput.

Trains nothing: it reads every frame the way a training loop would, through
``pcdcodec.torch.RecordingDataset`` (any frame at random, here shuffled) and
``IterableRecordingDataset`` (in order, split between the workers), with worker processes.
Without arguments it records the bundled sample first (with ``pcdcodec.torch.TRAINING_COLOR``,
the color codec ``docs/learning.md`` suggests for training data); otherwise it reads the
recordings given (files, folders or glob patterns).

Run: ``python examples/torch_dataloader.py [RECORDING ...] [--workers N] [--batch N]``
(needs ``pip install "pcdcodec[torch]"``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

from torch.utils.data import DataLoader

import pcdcodec
from pcdcodec.torch import TRAINING_COLOR, IterableRecordingDataset, RecordingDataset


def record_sample(folder: Path) -> Path:
    """The bundled sample as a recording made for training."""
    seq = pcdcodec.load_sample()
    path = folder / "sample.pcdc"
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color=TRAINING_COLOR,
    ) as rec:
        for frame in seq:
            rec.write(frame.color, frame.depth, frame.timestamp_ns, pose=frame.pose)
    return path


def epoch(loader: DataLoader[Any], what: str) -> None:
    """Take every batch of ``loader`` and print how fast the frames came."""
    t0 = time.perf_counter()
    frames = 0
    shape = None
    for batch in loader:
        frames += len(batch["index"])
        shape = tuple(batch["color"].shape)
    seconds = time.perf_counter() - t0
    print(
        f"{what}: read {frames} frames in {seconds:.2f} s, {frames / seconds:.1f} frames/s "
        f"(a batch of color: {shape})"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recordings", nargs="*", help="recordings (default: the sample)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--batch", type=int, default=4)
    args = parser.parse_args()
    if args.recordings:
        return run(args.recordings, args.workers, args.batch)
    with tempfile.TemporaryDirectory() as folder:  # the sample's recording goes with it
        return run([str(record_sample(Path(folder)))], args.workers, args.batch)


def run(sources: list[str], workers: int, batch: int) -> int:
    """Iterate the recordings shuffled and in order, printing the throughput of each."""
    fields = ["color", "depth_metres", "pose", "index"]

    shuffled = RecordingDataset(sources, fields)
    print(f"{shuffled}: {len(shuffled)} frames")
    item = shuffled[0]
    print("an item: " + ", ".join(f"{k} {getattr(v, 'shape', v)}" for k, v in item.items()))
    loader = DataLoader(shuffled, batch_size=batch, shuffle=True, num_workers=workers)
    epoch(loader, f"shuffled, {workers} workers")

    in_order = IterableRecordingDataset(sources, fields)
    loader = DataLoader(in_order, batch_size=batch, num_workers=workers)
    epoch(loader, f"in order, {workers} workers")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
