"""Open3D RGBDImage sequences into a recording and back, legacy and tensor.

Run: python examples/open3d_rgbd.py [out.pcdc]
"""

from __future__ import annotations

import sys

import numpy as np
import open3d as o3d

import pcdcodec

path = sys.argv[1] if len(sys.argv) > 1 else "rgbd.pcdc"
seq = pcdcodec.load_sample(max_frames=5)  # TUM: 5000 depth units per metre

# Legacy images, made as Open3D users make them; Open3D stores depth / depth_scale in metres.
images = [
    o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.geometry.Image(f.color),
        o3d.geometry.Image(f.depth),
        depth_scale=5000.0,
        depth_trunc=1000.0,  # keep every depth (Open3D's default drops what is beyond 3 m)
        convert_rgb_to_intensity=False,
    )
    for f in seq
]
stamps = [f.timestamp_ns for f in seq]

with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0, overwrite=True) as w:
    # Say which depth_scale the images were made with: a mismatch is an error, not a rescale.
    w.write_frames(zip(images, stamps, strict=True), rgbd_depth_scale=5000.0)

with pcdcodec.open(path) as rec:
    legacy = rec[0].to_open3d_rgbd()  # open3d.geometry.RGBDImage, depth in metres
    tensor = rec[0].to_open3d_rgbd(tensor=True)  # open3d.t.geometry.RGBDImage, uint16 units
    same = np.array_equal(np.asarray(legacy.depth), np.asarray(images[0].depth))
    print(f"legacy depth equal to the written image: {same}")
    # Tensor images keep depth units; Open3D's tensor functions take the scale beside them.
    k = o3d.core.Tensor(rec.intrinsics.K)
    cloud = o3d.t.geometry.PointCloud.create_from_rgbd_image(
        tensor, k, depth_scale=rec.depth_scale, depth_max=10.0
    )
    print(f"tensor point cloud: {cloud.point.positions.shape[0]} points")
    print(rec[0])
