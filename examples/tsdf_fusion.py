"""Fuse a decoded recording into an Open3D TSDF volume with its stored poses.

The bundled TUM sample (or any RGB-D folder with poses: TUM ``groundtruth.txt``, 7-Scenes
``pose/``) is recorded with the default codecs (lossy H.264 color, lossless depth) and its
camera poses. The recording is read back and every frame is integrated into an
``open3d.t.geometry.VoxelBlockGrid`` at the pose stored with it; the same is done with the
original frames, and the two meshes are compared: the geometry is the same because depth is
lossless, and colors differ only by the video coding.

Run: ``python examples/tsdf_fusion.py [RGBD_FOLDER [MAX_FRAMES]]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.datasets import open_folder, sample_dir

VOXEL = 0.01  # metres
DEPTH_MAX = 3.0  # metres


def fuse(
    frames: Any,
    intrinsics: pcdcodec.CameraIntrinsics,
    depth_scale: float,
    *,
    depth_max: float = DEPTH_MAX,
    block_count: int = 20_000,
) -> Any:
    """A colored triangle mesh from frames that carry a pose (camera-to-world).

    ``depth_max`` (metres) is the range integrated; ``block_count`` bounds the voxel blocks.
    """
    import open3d as o3d

    core: Any = o3d.core
    geometry: Any = o3d.t.geometry
    device = core.Device("CPU:0")
    grid = geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight", "color"),
        attr_dtypes=(core.float32, core.float32, core.float32),
        attr_channels=((1), (1), (3)),
        voxel_size=VOXEL,
        block_resolution=16,
        block_count=block_count,
        device=device,
    )
    k = core.Tensor(intrinsics.K, core.float64)
    for frame in frames:
        if frame.pose is None:
            continue
        extrinsic = core.Tensor(np.linalg.inv(frame.pose), core.float64)  # world -> camera
        rgbd = frame.to_open3d_rgbd(tensor=True, depth_scale=depth_scale)
        depth, color = rgbd.depth.to(device), rgbd.color.to(device)  # uint16 and uint8
        blocks = grid.compute_unique_block_coordinates(depth, k, extrinsic, depth_scale, depth_max)
        grid.integrate(blocks, depth, color, k, k, extrinsic, depth_scale, depth_max)
    return grid.extract_triangle_mesh().to_legacy()


def main() -> int:
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else sample_dir()
    max_frames = int(sys.argv[2]) if len(sys.argv) > 2 else None
    source = open_folder(folder, max_frames=max_frames)
    if source.intrinsics is None or source.poses is None:
        print(f"error: {folder} needs intrinsics (camera.json) and poses", file=sys.stderr)
        return 1
    frames = list(source)
    out = Path(tempfile.mkdtemp()) / "posed.pcdc"
    with pcdcodec.open(
        out, "w", intrinsics=source.intrinsics, depth_scale=source.depth_scale
    ) as rec:
        rec.write_frames(frames)  # the frames' poses go along
    print(f"recorded {len(frames)} frames with poses into {out} ({out.stat().st_size >> 10} KiB)")

    with pcdcodec.open(out) as rec:
        decoded = list(rec)
        posed = sum(f.pose is not None for f in decoded)
        print(f"read back {len(decoded)} frames, {posed} with a pose")
        mesh_decoded = fuse(decoded, rec.intrinsics, rec.depth_scale)
    mesh_original = fuse(frames, source.intrinsics, source.depth_scale)

    import open3d as o3d

    a, b = np.asarray(mesh_decoded.vertices), np.asarray(mesh_original.vertices)
    print(f"mesh from the recording: {len(a):,} vertices; from the original frames: {len(b):,}")
    pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(a))
    pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(b))
    d = np.maximum(
        np.asarray(pa.compute_point_cloud_distance(pb)).max(initial=0.0),
        np.asarray(pb.compute_point_cloud_distance(pa)).max(initial=0.0),
    )
    print(f"largest vertex distance between the meshes: {d * 1000:.3f} mm")
    if len(a) == len(b):
        # Same vertices, perhaps listed in another order: match them by sorting.
        oa, ob = np.lexsort(a.T), np.lexsort(b.T)
        if np.array_equal(a[oa], b[ob]):
            ca = np.asarray(mesh_decoded.vertex_colors)[oa]
            cb = np.asarray(mesh_original.vertex_colors)[ob]
            diff = np.abs(ca - cb) * 255
            print(f"vertex color difference (0-255): mean {diff.mean():.2f}, max {diff.max():.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
