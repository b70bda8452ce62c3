"""The size of a three-camera recording against three PointCloud2 topics, and against three
one-camera recordings of the same frames.

Run: ``python scripts/rig_bytes.py [--frames 150] [--json OUT]``.

The cameras are the dense sequences of ``../shared/data`` (TUM fr1_rpy, RealSense D435 office,
7-Scenes redkitchen: three sensors with their own intrinsics and depth scales), or, where one is
absent, the bundled sample. Each camera's frames keep their own spacing and start 0, 11 and 23
ms apart; the rig file is written with the default codecs, frames handed in in time order. The
PointCloud2 baseline is an XYZRGB cloud of each frame's valid points, 32 bytes per point (the
messages' own headers not counted), one topic per camera.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec import CameraSpec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import load_folder, load_sample

PC2_BYTES = 32
NAMES = ("tum_fr1_rpy", "realsense_d435", "7scenes_redkitchen")


def _sequences(frames: int) -> list[tuple[str, Any]]:
    out = []
    for name in NAMES:
        spec = SEQUENCES[name]
        if spec.present:
            out.append((name, load_folder(spec.root, max_frames=frames, **spec.reader_options())))
        else:
            out.append((f"sample (for {name})", load_sample(max_frames=frames)))
    return out


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=150, help="frames per camera")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv)
    seqs = _sequences(args.frames)
    names = ["cam0", "cam1", "cam2"]
    events = []
    valid = {}
    for c, (_, seq) in enumerate(seqs):
        t0 = int(seq[0].timestamp_ns)
        for k, f in enumerate(seq):
            events.append((int(f.timestamp_ns) - t0 + c * 11_000_000 + 10**9, c, k))
        valid[names[c]] = int(sum(np.count_nonzero(f.depth) for f in seq))
    events.sort()
    result: dict[str, Any] = {"frames_per_camera": args.frames, "cameras": {}}
    with tempfile.TemporaryDirectory() as tmp:
        rig_path = Path(tmp) / "rig.pcdc"
        specs = [
            CameraSpec(names[c], seq.intrinsics, seq.depth_scale) for c, (_, seq) in enumerate(seqs)
        ]
        with pcdcodec.open(rig_path, "w", cameras=specs) as rig:
            for t, c, k in events:
                f = seqs[c][1][k]
                rig.write(names[c], f.color, f.depth, t)
        separate = 0
        for c, (label, seq) in enumerate(seqs):
            path = Path(tmp) / f"{names[c]}.pcdc"
            with pcdcodec.open(
                path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale
            ) as one:
                one.write_frames(seq)
            size = path.stat().st_size
            separate += size
            pc2 = valid[names[c]] * PC2_BYTES
            result["cameras"][names[c]] = {
                "sequence": label,
                "frames": len(seq),
                "one_camera_file_bytes": size,
                "pointcloud2_bytes": pc2,
                "ratio_alone": pc2 / size,
            }
        with pcdcodec.open(rig_path) as rec:
            assert rec.verify().ok
        rig_size = rig_path.stat().st_size
    pc2_total = sum(v["pointcloud2_bytes"] for v in result["cameras"].values())
    result.update(
        rig_bytes=rig_size,
        three_files_bytes=separate,
        pointcloud2_bytes=pc2_total,
        ratio=pc2_total / rig_size,
        rig_over_three_files=rig_size / separate,
    )
    print("| camera | sequence | frames | PointCloud2 | alone (.pcdc) | ratio alone |")
    print("|---|---|---:|---:|---:|---:|")
    for name, v in result["cameras"].items():
        print(
            f"| {name} | {v['sequence']} | {v['frames']} | {v['pointcloud2_bytes'] / 1e6:,.1f} MB "
            f"| {v['one_camera_file_bytes'] / 1e6:,.2f} MB | {v['ratio_alone']:.1f}x |"
        )
    print(
        f"\nthree-camera recording: {rig_size / 1e6:,.2f} MB against {pc2_total / 1e6:,.1f} MB of "
        f"three PointCloud2 topics: {result['ratio']:.1f}x; the three one-camera files take "
        f"{separate / 1e6:,.2f} MB (the rig file is {result['rig_over_three_files']:.4f} of that)"
    )
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
