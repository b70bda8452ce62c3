"""Depth and color from two cameras: distortion, coloring by projection, registration, format."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics, InputError, Projector
from pcdcodec.geometry.transform import as_rigid, rigid_from_quaternion

DEPTH_CAM = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
# A wider color camera with its own lens, a little to the side and turned.
COLOR_CAM = CameraIntrinsics(
    800,
    600,
    610.0,
    612.0,
    401.2,
    298.7,
    "rational_polynomial",
    (0.33, -2.49, -1.6e-4, -1.3e-4, 1.45, 0.21, -2.30, 1.38),
)
D2C = rigid_from_quaternion([-0.032, -0.0022, 0.0039], [0.043, 0.0002, -0.0006, 0.999])

MODELS = {
    "plumb_bob": (0.12, -0.25, 0.001, -0.002, 0.08),
    "rational_polynomial": (0.55, -0.02, -7e-5, 2e-5, -0.003, 0.89, 0.086, -0.014),
    "equidistant": (0.1, -0.05, 0.01, -0.002),
}


def _sample_depth() -> np.ndarray[Any, Any]:
    return pcdcodec.load_sample(max_frames=1)[0].depth


def _cv_project(points: np.ndarray[Any, Any], cam: CameraIntrinsics) -> np.ndarray[Any, Any]:
    """OpenCV's projection of N × 3 points, as an independent reference."""
    import cv2

    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 1, 3)
    zero = np.zeros(3)
    d = np.asarray(cam.distortion, dtype=np.float64)
    if cam.distortion_model == "equidistant":
        uv, _ = cv2.fisheye.projectPoints(pts, zero, zero, cam.K, d)
    else:
        uv, _ = cv2.projectPoints(pts, zero, zero, cam.K, d if d.size else None)
    return np.asarray(uv).reshape(-1, 2)


@pytest.mark.parametrize("model", sorted(MODELS))
def test_projection_matches_opencv_and_inverts(model: str) -> None:
    cam = CameraIntrinsics(640, 480, 500.0, 502.0, 320.5, 241.0, model, MODELS[model])
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-0.5, 0.5, (500, 2)), rng.uniform(0.5, 3.0, 500)])
    u, v, front = cam.project(pts)
    assert front.all()
    np.testing.assert_allclose(np.column_stack([u, v]), _cv_project(pts, cam), atol=1e-6)
    # rays() inverts project(): every pixel's ray lands back on that pixel.
    rx, ry = cam.rays()
    ok = np.isfinite(rx)
    assert ok.mean() > 0.99
    uu, vv, _ = cam.project(np.column_stack([rx[ok], ry[ok], np.ones(int(ok.sum()))]))
    grid_v, grid_u = np.nonzero(ok)
    assert np.abs(uu - grid_u).max() < 1e-5
    assert np.abs(vv - grid_v).max() < 1e-5


def test_intrinsics_distortion_dict_and_camera_info_round_trip() -> None:
    assert COLOR_CAM.has_distortion
    d = json.loads(json.dumps(COLOR_CAM.to_dict()))
    assert d["distortion_model"] == "rational_polynomial"
    assert CameraIntrinsics.from_dict(d) == COLOR_CAM
    assert CameraIntrinsics.from_camera_info(COLOR_CAM.to_camera_info()) == COLOR_CAM
    # librealsense names, and Brown-Conrady zeros mean no distortion.
    info = {**DEPTH_CAM.to_camera_info(), "distortion_model": "Brown Conrady"}
    assert CameraIntrinsics.from_camera_info(info) == DEPTH_CAM
    assert "distortion" not in DEPTH_CAM.to_dict()
    with pytest.raises(InputError, match=r"no distortion.*rational_polynomial"):
        COLOR_CAM.to_open3d()


def test_distorted_depth_camera_round_trips_bit_exact() -> None:
    cam = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5, "plumb_bob", MODELS["plumb_bob"])
    depth = _sample_depth()
    proj = Projector(cam, 5000.0)
    points, _ = proj.to_points(depth)
    # Points are on the undistorted rays: their projection is their pixel.
    idx = np.flatnonzero(depth.reshape(-1) > 0)
    u, v, _ = cam.project(points.astype(np.float64))
    assert np.abs(u - idx % 640).max() < 1e-3
    assert np.abs(v - idx // 640).max() < 1e-3
    back = proj.to_rgbd_arrays(points).depth
    assert np.array_equal(back, depth)


def test_colors_come_from_the_projection_into_the_color_camera() -> None:
    depth = _sample_depth()
    rng = np.random.default_rng(2)
    color = rng.integers(0, 256, (600, 800, 3), dtype=np.uint8)
    proj = Projector(DEPTH_CAM, 5000.0, color_intrinsics=COLOR_CAM, depth_to_color=D2C)
    points, colors = proj.to_points(depth, color)
    assert colors is not None
    # Reference: OpenCV projection of the points moved into the color frame, nearest pixel.
    moved = points.astype(np.float64) @ D2C[:3, :3].T + D2C[:3, 3]
    uv = np.floor(_cv_project(moved, COLOR_CAM) + 0.5).astype(int)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < 800) & (uv[:, 1] >= 0) & (uv[:, 1] < 600)
    assert inside.mean() > 0.9
    expected = np.zeros_like(colors)
    expected[inside] = color[uv[inside, 1], uv[inside, 0]]
    assert (colors == expected).all(axis=1).mean() > 0.999  # ties at .5 may round apart
    # The same through Open3D and the color image aligned with depth.
    pcd = proj.to_point_cloud(depth, color)
    assert np.array_equal(np.asarray(pcd.colors), colors / 255.0)
    aligned = proj.color_for_depth(depth, color)
    assert np.array_equal(aligned.reshape(-1, 3)[depth.reshape(-1) > 0], colors)


def test_identity_color_camera_is_the_registered_case() -> None:
    depth = _sample_depth()
    color = pcdcodec.load_sample(max_frames=1)[0].color
    same = Projector(DEPTH_CAM, 5000.0, color_intrinsics=DEPTH_CAM, depth_to_color=np.eye(4))
    plain = Projector(DEPTH_CAM, 5000.0)
    a, ca = same.to_points(depth, color)
    b, cb = plain.to_points(depth, color)
    assert np.array_equal(a, b)
    assert ca is not None
    assert cb is not None
    assert np.array_equal(ca, cb)
    assert np.array_equal(same.register_depth(depth), depth)
    assert np.array_equal(plain.register_depth(depth), depth)


def _slow_register(depth: np.ndarray[Any, Any], scale: float) -> np.ndarray[Any, Any]:
    """Registration one pixel at a time, written as plainly as possible."""
    out = np.zeros(COLOR_CAM.shape, dtype=np.float64)
    for v in range(depth.shape[0]):
        for u in range(depth.shape[1]):
            d = float(depth[v, u])
            if d == 0:
                continue
            z = d / scale
            p = np.array(
                [(u - DEPTH_CAM.cx) / DEPTH_CAM.fx * z, (v - DEPTH_CAM.cy) / DEPTH_CAM.fy * z, z]
            )
            q = D2C[:3, :3] @ p + D2C[:3, 3]
            uv = _cv_project(q[None], COLOR_CAM)[0]
            cu, cv = int(np.floor(uv[0] + 0.5)), int(np.floor(uv[1] + 0.5))
            if 0 <= cu < COLOR_CAM.width and 0 <= cv < COLOR_CAM.height:
                value = q[2] * scale
                if out[cv, cu] == 0 or value < out[cv, cu]:
                    out[cv, cu] = value
    return out


def test_register_depth_matches_a_plain_loop() -> None:
    depth = _sample_depth()[::8, ::8].copy()  # 80 x 60: the loop stays fast
    cam = CameraIntrinsics(80, 60, 525.0 / 8, 525.0 / 8, 319.5 / 8, 239.5 / 8)
    global DEPTH_CAM
    saved, DEPTH_CAM = DEPTH_CAM, cam
    try:
        proj = Projector(cam, 5000.0, color_intrinsics=COLOR_CAM, depth_to_color=D2C)
        got = proj.register_depth(depth, dtype="float32")
        ref = _slow_register(depth, 5000.0)
    finally:
        DEPTH_CAM = saved
    filled = np.isfinite(got)
    assert filled.sum() > 3000
    assert np.array_equal(filled, ref > 0)
    np.testing.assert_allclose(got[filled], ref[filled], rtol=1e-6)


def test_register_depth_matches_open3d() -> None:
    import open3d as o3d

    depth = _sample_depth()
    color_cam = CameraIntrinsics(640, 480, 600.0, 601.0, 322.0, 238.0)
    proj = Projector(DEPTH_CAM, 5000.0, color_intrinsics=color_cam, depth_to_color=D2C)
    got = proj.register_depth(depth, dtype="float32")
    points, _ = Projector(DEPTH_CAM, 5000.0).to_points(depth)
    cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(points))
    image = cloud.project_to_depth_image(
        640, 480, o3d.core.Tensor(color_cam.K), o3d.core.Tensor(D2C), 5000.0, 100.0
    )
    ref = image.as_tensor().numpy()[..., 0]
    mine, theirs = np.isfinite(got), ref > 0
    assert theirs.sum() > 100_000
    assert (mine != theirs).sum() <= 50  # rounding ties at half pixels (of ~200,000)
    both = mine & theirs
    assert np.abs(got[both] - ref[both]).max() < 0.01  # float32 depth units
    # Footprints fill the holes that single points leave where color is finer than depth.
    filled = proj.register_depth(depth, footprint=True)
    assert (filled > 0).sum() > 1.1 * mine.sum()


def test_bad_extrinsics_and_sizes(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="depth_to_color was given without color_intrinsics"):
        Projector(DEPTH_CAM, depth_to_color=np.eye(4))
    shear = np.eye(4)
    shear[0, 1] = 0.2
    with pytest.raises(InputError, match="depth_to_color is not a rigid transform"):
        Projector(DEPTH_CAM, color_intrinsics=COLOR_CAM, depth_to_color=shear)
    mm = D2C.copy()
    mm[:3, 3] *= 1000
    with pytest.raises(InputError, match=r"moves the camera by 32\.31 m.*millimetres"):
        Projector(DEPTH_CAM, color_intrinsics=COLOR_CAM, depth_to_color=mm)
    with pytest.raises(InputError, match=r"must have shape \(4, 4\), got \(3, 4\)|shape \(3, 4\)"):
        as_rigid(np.eye(4)[:3], "depth_to_color")
    proj = Projector(DEPTH_CAM, color_intrinsics=COLOR_CAM, depth_to_color=D2C)
    with pytest.raises(InputError, match=r"640x480 differs from the color camera's size 800x600"):
        proj.to_points(_sample_depth(), np.zeros((480, 640, 3), np.uint8))


def test_recording_with_two_cameras(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=3)
    rng = np.random.default_rng(3)
    colors = [rng.integers(0, 256, (600, 800, 3), dtype=np.uint8) for _ in range(3)]
    path = tmp_path / "two.pcdc"
    with pcdcodec.open(
        path,
        "w",
        intrinsics=DEPTH_CAM,
        depth_scale=5000.0,
        color="ffv1",
        color_intrinsics=COLOR_CAM,
        depth_to_color=D2C,
    ) as rec:
        for f, c in zip(seq, colors, strict=True):
            rec.write(c, f.depth, f.timestamp_ns)
        with pytest.raises(InputError, match="color"):
            rec.write(seq[0].color, seq[0].depth, 2 * 10**18)
    with pcdcodec.open(path) as r:
        assert r.format_version == 2
        assert r.color_intrinsics == COLOR_CAM
        assert r.depth_to_color is not None
        np.testing.assert_allclose(r.depth_to_color, D2C, atol=1e-15)
        assert len(r) == 3
        for i, frame in enumerate(r):
            assert np.array_equal(frame.depth, seq[i].depth)
            assert frame.color is not None
            assert np.array_equal(frame.color, colors[i])  # ffv1 is lossless
        frame = r[1]
        direct = Projector(
            DEPTH_CAM, 5000.0, color_intrinsics=COLOR_CAM, depth_to_color=D2C
        ).to_points(seq[1].depth, colors[1])
        got = frame.to_points()
        assert np.array_equal(got[0], direct[0])
        assert got[1] is not None
        assert direct[1] is not None
        assert np.array_equal(got[1], direct[1])
        assert frame.registered_depth().shape == (600, 800)
        rgbd = frame.to_open3d_rgbd(tensor=True)
        aligned = rgbd.color.as_tensor().numpy()
        assert aligned.shape == (480, 640, 3)  # the depth camera's image
        valid = seq[1].depth.reshape(-1) > 0
        assert np.array_equal(aligned.reshape(-1, 3)[valid], direct[1])
        topics = {c.topic for c in r.index.channels.values()}
        assert {"/camera/color/calibration", "/camera/extrinsics"} <= topics


def test_registered_recording_stays_version_1(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=2)
    path = tmp_path / "one.pcdc"
    with pcdcodec.open(path, "w", intrinsics=DEPTH_CAM, depth_scale=5000.0, color="ffv1") as rec:
        rec.write_frames(seq)
    with pcdcodec.open(path) as r:
        assert r.format_version == 1
        assert r.color_intrinsics is None
        topics = {c.topic for c in r.index.channels.values()}
        assert "/camera/extrinsics" not in topics
