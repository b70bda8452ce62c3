"""Print the tables of docs/paper-reproduction.md, measured on every sequence present.

Run: ``python benchmarks/paper_tables.py [--frames 30]``. It evaluates the original method's
codecs (OpenCV's five color codecs through PyAV, LZ4 depth on uint16 and on float32 metres)
next to pcdcodec's choices on the bundled sample and on ``../shared/data`` when present.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import load_folder

CAMERAS = {
    "realsense_d435": pcdcodec.CameraIntrinsics(640, 480, 615.0, 615.0, 320.0, 240.0),
    "7scenes_redkitchen": pcdcodec.CameraIntrinsics(640, 480, 585.0, 585.0, 320.0, 240.0),
}
PAPER_COLOR = ["ffv1", "huffyuv", "mjpeg", "mpeg4", "h264"]
OURS_COLOR = ["h265", "av1"]
DEPTH = ["lz4", "zstd", "jpegxl", "depthac"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=30)
    args = parser.parse_args()
    kib = 1024.0
    for name, seq_info in SEQUENCES.items():
        if not seq_info.present:
            continue
        seq = load_folder(
            seq_info.root,
            max_frames=args.frames,
            depth_scale=seq_info.depth_scale,
            intrinsics=CAMERAS.get(name),
            layout=seq_info.layout,  # D435's lists hold time deltas: read it as plain folders
        )
        if seq.intrinsics is None:
            seq.intrinsics = pcdcodec.CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
        ev = pcdcodec.evaluate(
            seq, depth=DEPTH, color=PAPER_COLOR + OURS_COLOR, frames=args.frames, rd=False
        )
        valid = float(np.mean([np.count_nonzero(f.depth) / f.depth.size for f in seq]))
        pc2 = ev.pointcloud2_bytes_per_frame
        dense = pc2 * valid
        print(f"\n### {name}: {ev.frames} frames, {100 * valid:.0f} % of pixels with depth\n")
        print("| color | KiB/frame | ratio vs RGB24 | PSNR dB | SSIM | encode ms | decode ms |")
        print("|---|---|---|---|---|---|---|")
        for c in ev.color:
            psnr = "lossless" if c.psnr == float("inf") else f"{c.psnr:.2f}"
            print(
                f"| {c.codec} | {c.bytes_per_frame / kib:.1f} | {c.ratio_rgb24:.1f} | {psnr} | "
                f"{c.ssim:.3f} | {c.encode_ms:.1f} | {c.decode_ms:.1f} |"
            )
        print()
        print(
            "| depth | KiB/frame (uint16) | ratio vs uint16 | KiB/frame (float32 m) | "
            "ratio vs float32 | encode ms | decode ms |"
        )
        print("|---|---|---|---|---|---|---|")
        f32_raw = ev.width * ev.height * 4
        for d in ev.depth:
            f32 = d.ratio_float32_input or float("nan")
            print(
                f"| {d.codec} | {d.bytes_per_frame / kib:.1f} | {d.ratio_uint16:.2f} | "
                f"{f32_raw / f32 / kib:.1f} | {f32:.2f} | {d.encode_ms:.1f} | "
                f"{d.decode_ms:.1f} |"
            )
        print()
        print(
            "| color + depth | KiB/frame | vs PointCloud2 (organized) | vs PointCloud2 "
            "(valid points only) |"
        )
        print("|---|---|---|---|")
        color = {c.codec: c for c in ev.color}
        depth = {d.codec: d for d in ev.depth}
        lz4_f32 = f32_raw / (depth["lz4"].ratio_float32_input or 1.0)
        rows = [
            (
                "h264 + lz4 on float32 (the paper's lossy setup)",
                color["h264"].bytes_per_frame + lz4_f32,
            ),
            (
                "ffv1 + lz4 on float32 (the paper's lossless setup)",
                color["ffv1"].bytes_per_frame + lz4_f32,
            ),
            ("h264 + lz4 (uint16)", color["h264"].bytes_per_frame + depth["lz4"].bytes_per_frame),
            ("ffv1 + lz4 (uint16)", color["ffv1"].bytes_per_frame + depth["lz4"].bytes_per_frame),
            ("ffv1 + jpegxl", color["ffv1"].bytes_per_frame + depth["jpegxl"].bytes_per_frame),
            ("h264 + jpegxl", color["h264"].bytes_per_frame + depth["jpegxl"].bytes_per_frame),
            ("av1 + jpegxl", color["av1"].bytes_per_frame + depth["jpegxl"].bytes_per_frame),
            (
                "ffv1 + depthac (recommended lossless)",
                color["ffv1"].bytes_per_frame + depth["depthac"].bytes_per_frame,
            ),
            (
                "h264 + depthac (recommended visually lossless, the default)",
                color["h264"].bytes_per_frame + depth["depthac"].bytes_per_frame,
            ),
            (
                "av1 + depthac (recommended smallest)",
                color["av1"].bytes_per_frame + depth["depthac"].bytes_per_frame,
            ),
        ]
        for label, size in rows:
            print(f"| {label} | {size / kib:.1f} | {pc2 / size:.1f} | {dense / size:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
