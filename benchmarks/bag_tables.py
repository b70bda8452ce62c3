"""The paper's Tables III and IV measured from real bag files, as the original method measured them.

Run: ``python benchmarks/bag_tables.py [--frames N] [--keep DIR]``. For every real sequence present
in ``../shared/data`` it writes a ROS 1 bag of organized PointCloud2 XYZRGB clouds (640×480, 32
bytes per point, plus CameraInfo, uncompressed as ``rosbag record`` writes), then records that bag
into ``.pcdc`` with the defaults (h264 + depthac), with lossless color (ffv1 + depthac) and with
jpegxl depth, and prints for each: the bag's size, the recordings' sizes and ratios, the ingest
speed (frames per second from the bag, reading and decoding the clouds included), and the
largest xyz error and color difference of the clouds rebuilt from the recording against the
bag's clouds.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import open_folder

CAMERAS = {
    "tum_fr1_rpy": pcdcodec.CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "realsense_d435": pcdcodec.CameraIntrinsics(640, 480, 615.0, 615.0, 320.0, 240.0),
    "7scenes_redkitchen": pcdcodec.CameraIntrinsics(640, 480, 585.0, 585.0, 320.0, 240.0),
}
CONFIGS = {
    "defaults (h264 + depthac)": {},
    "lossless color (ffv1 + depthac)": {"color": "ffv1"},
    "h264 + jpegxl": {"depth": "jpegxl"},
}


def bag_clouds(bag: Path) -> Any:
    """The bag's clouds as structured arrays, one at a time."""
    from rosbags.highlevel import AnyReader

    from pcdcodec.ros import messages as rm

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.msgtype == "sensor_msgs/msg/PointCloud2"]
        for c, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, c.msgtype)
            layout = rm.cloud_layout(msg, c.topic)
            yield rm.cloud_points(msg, layout, c.topic)


def rebuild_errors(bag: Path, rec_path: Path) -> tuple[float, int]:
    """Largest |xyz| error (m) over valid points, and largest color difference, over all frames."""
    worst, worst_color = 0.0, 0
    with pcdcodec.open(rec_path) as rec:
        for frame, pts in zip(rec, bag_clouds(bag), strict=True):
            xyz = rec.projector.to_organized(frame.depth)
            want = np.stack([pts["x"], pts["y"], pts["z"]], axis=-1).astype(np.float32)
            valid = np.isfinite(want[..., 2])
            if not np.array_equal(valid, np.isfinite(xyz[..., 2])):
                return float("inf"), 255
            if valid.any():
                worst = max(worst, float(np.abs(xyz[valid] - want[valid]).max()))
            packed = pts["rgb"].astype(np.uint32)
            rgb = np.stack([(packed >> s) & 255 for s in (16, 8, 0)], axis=-1).astype(np.int16)
            assert frame.color is not None
            worst_color = max(worst_color, int(np.abs(frame.color.astype(np.int16) - rgb).max()))
    return worst, worst_color


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=None, help="frames per sequence (all)")
    parser.add_argument("--keep", type=Path, default=None, help="keep the bags in this folder")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="pcdcodec-bags-")) if args.keep is None else args.keep
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for name, info in SEQUENCES.items():
            if name == "sample" or not info.present:
                continue
            source = open_folder(
                info.root,
                max_frames=args.frames,
                depth_scale=info.depth_scale,
                intrinsics=CAMERAS.get(name),
                layout="folders" if name == "realsense_d435" else "auto",
            )
            bag = work / f"{name}.bag"
            if not bag.exists():
                pcdcodec.export_bag(source, bag, images=False, cloud=True)
            bag_bytes = bag.stat().st_size
            for label, options in CONFIGS.items():
                out = work / f"{name}-{'lossless' if options else 'default'}.pcdc"
                start = time.perf_counter()
                summary = pcdcodec.encode(bag, out, overwrite=True, **options)
                seconds = time.perf_counter() - start
                err, color_err = rebuild_errors(bag, out)
                fps = summary.frames / seconds
                rows.append(
                    (name, label, summary.frames, bag_bytes, summary.bytes, fps, err, color_err)
                )
                print(rows[-1], file=sys.stderr, flush=True)
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    mib = 2**20
    print("| sequence | frames | PointCloud2 bag | configuration | .pcdc | ratio | ingest fps "
          "| max xyz error | max color diff |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for name, label, n, bag_bytes, size, fps, err, color_err in rows:
        print(
            f"| {name} | {n} | {bag_bytes / mib:,.0f} MiB | {label} | {size / mib:.2f} MiB | "
            f"{bag_bytes / size:,.0f}x | {fps:.1f} | {err:.2g} m | {color_err} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
