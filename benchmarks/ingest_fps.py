"""Ingest throughput: frames per second of ``pcdcodec.encode`` from an organized PointCloud2 bag.

    python benchmarks/ingest_fps.py FOLDER FRAMES DEPTH_SCALE LAYOUT FOCAL

writes a ROS 1 bag of ``FRAMES`` organized PointCloud2 XYZRGB clouds made from an RGB-D folder
(640×480, ``FOCAL`` in pixels, principal point at the centre), then records it twice with the
default codecs and, interleaved, with ``jpegxl`` depth, and prints the rates (reading and
decoding the clouds included).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import pcdcodec
from pcdcodec.datasets import open_folder


def main() -> None:
    root, n, scale, layout = Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    focal = float(sys.argv[5])
    cam = pcdcodec.CameraIntrinsics(640, 480, focal, focal, 319.5, 239.5)
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-ingest-"))
    src = open_folder(root, max_frames=n, depth_scale=scale, intrinsics=cam, layout=layout)
    bag = work / "clouds.bag"
    pcdcodec.export_bag(src, bag, images=False, cloud=True)
    for _ in range(2):
        for depth in (pcdcodec.DEFAULT_DEPTH_CODEC, "jpegxl"):
            t0 = time.perf_counter()
            s = pcdcodec.encode(bag, work / "out.pcdc", overwrite=True, depth=depth)
            dt = time.perf_counter() - t0
            print(
                f"{root.name}, {depth}: {s.frames} frames, bag {bag.stat().st_size / 2**20:.0f} "
                f"MiB -> {s.bytes / 2**20:.2f} MiB, {s.frames / dt:.1f} fps",
                flush=True,
            )


if __name__ == "__main__":
    main()
