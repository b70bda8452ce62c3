"""What a depth error bound does to point clouds and to a TSDF mesh.

1. Point-to-point RMSE (``pcdcodec.metrics.point_to_point``, the larger of both directions)
   between the cloud of each original frame and the cloud of its bounded-error decoding
   (``Projector.to_points``), on every depth test set, at each bound.
2. TSDF fusion of 7-Scenes RedKitchen at its stored poses (``examples/tsdf_fusion.py``'s
   ``fuse``: Open3D VoxelBlockGrid, 1 cm voxels, 3 m range) from the lossless frames and from
   the bounded-error frames; the meshes' vertices are compared by Chamfer distance (the mean of
   both directions' mean nearest-vertex distances), their RMSE and 95th percentile.

Run: ``python scripts/bounded_cloud_effects.py [--frames 10] [--tsdf-frames 150]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples"))

import pcdcodec  # noqa: E402
from benchmarks.data import DEPTH_SETS, SEQUENCES, load_frames  # noqa: E402
from pcdcodec.metrics import point_to_point  # noqa: E402

BOUNDS = (0.005, 0.01)


def _camera(name: str) -> tuple[pcdcodec.CameraIntrinsics, float] | None:
    if name == "spot":
        return None
    seq = SEQUENCES[name.removesuffix("-sparse")]
    return seq.camera, seq.depth_scale


def cloud_table(count: int) -> None:
    print(
        "| set | bound | point-to-point RMSE (mm), mean over frames | worst frame (mm) "
        "| mean depth (m) | RMSE / mean depth |"
    )
    print("|---|---|---|---|---|---|")
    for name in DEPTH_SETS:
        cam = _camera(name)
        if cam is None:
            continue
        try:
            frames = load_frames(name, count)
        except BaseException:  # absent
            continue
        proj = pcdcodec.Projector(cam[0], depth_scale=cam[1])
        mean_depth = float(np.mean([d[d > 0].mean() for d in frames])) / cam[1]
        for rel in BOUNDS:
            codec = pcdcodec.get_codec("depthac", max_rel_error=rel)
            rmses = []
            for d in frames:
                back = codec.decode(codec.encode(d))
                a, b = proj.to_points(d)[0], proj.to_points(back)[0]
                rmses.append(point_to_point(a, b).rmse)
            print(
                f"| {name} | {100 * rel:g} % | {1000 * np.mean(rmses):.2f} "
                f"| {1000 * max(rmses):.2f} | {mean_depth:.2f} "
                f"| {100 * np.mean(rmses) / mean_depth:.3f} % |"
            )


def tsdf_table(count: int) -> None:
    import dataclasses

    import open3d as o3d
    from tsdf_fusion import fuse  # examples/tsdf_fusion.py

    from pcdcodec.datasets import open_folder

    seq = SEQUENCES["7scenes_redkitchen"]
    if not seq.present:
        print(f"{seq.root} is absent: no TSDF comparison")
        return
    source = open_folder(seq.root, max_frames=count, **seq.reader_options())
    frames = [f for f in source if f.pose is not None]
    reference = fuse(frames, seq.camera, seq.depth_scale)
    ref_v = np.asarray(reference.vertices)
    ref_pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(ref_v))
    print()
    print(
        f"TSDF of 7-Scenes RedKitchen, {len(frames)} frames with poses; lossless mesh: "
        f"{len(ref_v):,} vertices"
    )
    print(
        "| bound | ratio vs raw uint16 | vertices | Chamfer (mm) | RMSE (mm) | 95th pct (mm) "
        "| largest (mm) |"
    )
    print("|---|---|---|---|---|---|---|")
    for rel in BOUNDS:
        codec = pcdcodec.get_codec("depthac", max_rel_error=rel)
        lossy, size = [], 0
        for f in frames:
            data = codec.encode(f.depth)
            size += len(data)
            lossy.append(dataclasses.replace(f, depth=codec.decode(data)))
        mesh = fuse(lossy, seq.camera, seq.depth_scale)
        v = np.asarray(mesh.vertices)
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(v))
        d1 = np.asarray(ref_pc.compute_point_cloud_distance(pc))
        d2 = np.asarray(pc.compute_point_cloud_distance(ref_pc))
        both = np.concatenate([d1, d2])
        chamfer = (d1.mean() + d2.mean()) / 2
        raw = sum(f.depth.nbytes for f in frames)
        print(
            f"| {100 * rel:g} % | {raw / size:.1f}× | {len(v):,} | {1000 * chamfer:.2f} "
            f"| {1000 * np.sqrt(np.mean(both**2)):.2f} | {1000 * np.percentile(both, 95):.2f} "
            f"| {1000 * both.max():.1f} |"
        )


def main(argv: Any = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10, help="frames per set for the clouds")
    parser.add_argument("--tsdf-frames", type=int, default=150, help="7-Scenes frames to fuse")
    args = parser.parse_args(argv)
    cloud_table(args.frames)
    tsdf_table(args.tsdf_frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
