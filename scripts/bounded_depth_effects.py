"""What a depth error bound does to point clouds and TSDF meshes.

For every real sequence present (and the bundled sample), each depth codec spec is applied to
the frames, and the decoded depth is compared where users feel it:

* **ratio** against raw uint16 and the largest error found, relative and absolute;
* **per-point error**: the distance between each valid pixel's 3-D point from the original
  depth and from the decoded depth (same pixel, same ray; RMSE, 95th percentile and maximum in
  millimetres);
* **D1 point-to-point RMSE** (nearest neighbour both ways, ``pcdcodec.metrics.point_to_point``)
  on a few frames;
* on sequences with poses (7-Scenes, TUM): **TSDF meshes** fused from the original frames and
  from the decoded ones (Open3D ``VoxelBlockGrid``, 1 cm voxels), and their Chamfer distance:
  the mean of the nearest-vertex distances both ways, with the 95th percentile and the largest.

Run: ``python scripts/bounded_depth_effects.py [--frames 30] [--tsdf-frames 60]
[--spec depthac:max_rel_error=0.005 --spec ...]``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from examples.tsdf_fusion import fuse
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.metrics import point_to_point
from pcdcodec.registry import parse_codec_spec

DEFAULT_SPECS = [
    "depthac",
    "depthac:max_rel_error=0.005",
    "depthac:max_rel_error=0.01",
    "depthac:max_rel_error=0.02",
]
DEPTH_MAX = 4.0  # metres fused (the 1 cm voxels are those of examples/tsdf_fusion.py)


def frames_of(name: str, count: int) -> tuple[list[Any], Any, float]:
    seq = SEQUENCES[name]
    with pcdcodec.open_source(seq.root, **seq.reader_options()) as src:
        frames = []
        for frame in src:
            frames.append(frame)
        camera, scale = src.intrinsics, src.depth_scale
    step = max(1, len(frames) // count)
    return frames[::step][:count], camera, scale


def points(projector: Any, depth: Any, valid: Any) -> Any:
    xyz = projector.to_organized(depth)
    return xyz[valid]


def mesh_vertices(frames: list[Any], depths: list[Any], camera: Any, scale: float) -> Any:
    """Vertices of the TSDF mesh fused from ``frames`` with their depth replaced by ``depths``."""
    posed = [replace(f, depth=d) for f, d in zip(frames, depths, strict=True)]
    mesh = fuse(posed, camera, scale, depth_max=DEPTH_MAX, block_count=40_000)
    return np.asarray(mesh.vertices)


def chamfer(a: Any, b: Any) -> tuple[float, float, float]:
    """Mean, 95th percentile and largest nearest-vertex distance over both directions, in m."""
    import open3d as o3d

    pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a))
    pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(b))
    ab = np.asarray(pa.compute_point_cloud_distance(pb))
    ba = np.asarray(pb.compute_point_cloud_distance(pa))
    d = np.concatenate([ab, ba])
    return float(d.mean()), float(np.percentile(d, 95)), float(d.max())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=30, help="frames per sequence")
    parser.add_argument("--d1-frames", type=int, default=3, help="frames for the D1 RMSE")
    parser.add_argument("--tsdf-frames", type=int, default=60, help="frames fused per mesh")
    parser.add_argument("--spec", action="append", help="depth codec spec (repeatable)")
    parser.add_argument("--no-tsdf", action="store_true", help="skip the meshes")
    args = parser.parse_args()
    specs = args.spec or DEFAULT_SPECS
    print(
        "| sequence | codec | ratio | max rel. error | max error mm "
        "| point error RMSE / p95 / max mm | D1 RMSE mm | mesh Chamfer mean / p95 / max mm |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, seq in SEQUENCES.items():
        if not seq.present:
            continue
        frames, camera, scale = frames_of(name, max(args.frames, args.tsdf_frames))
        sample = frames[:: max(1, len(frames) // args.frames)][: args.frames]
        projector = pcdcodec.Projector(camera, depth_scale=scale)
        posed = [f for f in frames if f.pose is not None][: args.tsdf_frames]
        reference_mesh = None
        if posed and not args.no_tsdf:
            reference_mesh = mesh_vertices(posed, [f.depth for f in posed], camera, scale)
            if len(reference_mesh) == 0:  # too few posed frames to close a surface
                reference_mesh = None
        for spec in specs:
            codec = parse_codec_spec(spec, "depth")
            raw = packed = 0
            max_rel = max_abs = 0.0
            errors = []
            d1 = []
            for i, frame in enumerate(sample):
                data = codec.encode(frame.depth)
                decoded = codec.decode(data)
                raw += frame.depth.nbytes
                packed += len(data)
                valid = frame.depth > 0
                if not np.array_equal(decoded > 0, valid):
                    raise SystemExit(f"{name} {spec}: holes changed in frame {i}")
                ref = frame.depth[valid].astype(np.float64)
                diff = np.abs(decoded[valid].astype(np.float64) - ref)
                max_rel = max(max_rel, float((diff / ref).max(initial=0.0)))
                max_abs = max(max_abs, float(diff.max(initial=0.0)) / scale * 1000)
                a = points(projector, frame.depth, valid)
                b = points(projector, decoded, valid)
                errors.append(np.linalg.norm(a - b, axis=1))
                if i < args.d1_frames:
                    d1.append(point_to_point(a, b).rmse if diff.any() else 0.0)
            err = np.concatenate(errors) * 1000
            mesh = "—"
            if reference_mesh is not None:
                decoded_depths = [codec.decode(codec.encode(f.depth)) for f in posed]
                test_mesh = mesh_vertices(posed, decoded_depths, camera, scale)
                if len(test_mesh) == 0:
                    mesh = "no surface"
                else:
                    mean, p95, worst = chamfer(reference_mesh, test_mesh)
                    mesh = f"{mean * 1000:.2f} / {p95 * 1000:.2f} / {worst * 1000:.1f}"
            rmse = float(np.sqrt(np.mean(err**2)))
            print(
                f"| {name} | `{spec}` | {raw / packed:.1f} | {max_rel * 100:.3f} % | {max_abs:.1f} "
                f"| {rmse:.2f} / {np.percentile(err, 95):.2f} / {err.max():.1f} "
                f"| {np.mean(d1) * 1000:.2f} | {mesh} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
