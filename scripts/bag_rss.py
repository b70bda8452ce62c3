"""Peak memory of recording a large PointCloud2 bag: bags are streamed, so it stays bounded.

Run: ``python scripts/bag_rss.py [--gib 2.0] [--dir /tmp]``. Writes a ROS 1 bag of organized
640×480 XYZRGB clouds (the bundled sample's frames repeated with new stamps) of at least
``--gib`` GiB, and a small one of the same frames, then records each into ``.pcdc`` with the
defaults in a fresh process and prints the peak resident memory of each. Bounded memory means
the two peaks are about equal, whatever the bag's size.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.sources.base import Source

_CHILD = """
import resource, sys, time
import pcdcodec
start = time.perf_counter()
s = pcdcodec.encode(sys.argv[1], sys.argv[2], overwrite=True)
took = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"{s.frames} {s.bytes} {took:.1f} {peak:.0f}")
"""


class Repeated(Source):
    """The bundled sample's frames again and again, 33 ms apart: a long stream, lazily."""

    def __init__(self, frames: int) -> None:
        seq = pcdcodec.load_sample()
        self.path = pcdcodec.datasets.sample_dir()
        self.intrinsics = seq.intrinsics
        self.depth_scale = seq.depth_scale
        self.metadata = {}
        self._seq = seq
        self._n = frames

    def __len__(self) -> int:
        return self._n

    def __iter__(self):  # type: ignore[no-untyped-def]
        for i in range(self._n):
            f = self._seq[i % len(self._seq)]
            yield pcdcodec.Frame(f.color, f.depth, 1_000_000_000 + i * 33_333_333)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--gib", type=float, default=2.0)
    parser.add_argument("--dir", type=Path, default=None)
    args = parser.parse_args()
    per_frame = 640 * 480 * 32
    big_frames = int(args.gib * 2**30 / per_frame) + 1
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        rows = []
        for frames in (30, big_frames):
            bag = Path(tmp) / f"clouds-{frames}.bag"
            start = time.perf_counter()
            pcdcodec.export_bag(Repeated(frames), bag, images=False, cloud=True)
            wrote = time.perf_counter() - start
            out = subprocess.run(
                [sys.executable, "-c", _CHILD, str(bag), str(Path(tmp) / "out.pcdc")],
                check=True, capture_output=True, text=True,
            ).stdout.split()  # fmt: skip
            n, size, took, peak = int(out[0]), int(out[1]), float(out[2]), float(out[3])
            rows.append((bag.stat().st_size, n, size, took, peak, wrote))
            bag.unlink()
    print("| bag size | frames | .pcdc | encode s | fps | peak RSS |")
    print("|---|---|---|---|---|---|")
    for bag_bytes, n, size, took, peak, _ in rows:
        print(
            f"| {bag_bytes / 2**30:.2f} GiB | {n} | {size / 2**20:.1f} MiB | {took:.1f} | "
            f"{n / took:.1f} | {peak:.0f} MiB |"
        )
    print(f"(this process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
