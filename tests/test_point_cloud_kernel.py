"""The compiled tensor point cloud gives exactly the points and colors of the numpy path.

``Projector.to_point_cloud(tensor=True)`` makes uint16 depth at the projector's scale in one
compiled pass (``pcdcodec/geometry/_cloud_kernels.py``); :meth:`Projector.to_points` is the
numpy path it replaced (positions, and colors as uint8 that were divided by 255 in float32).
"""

from __future__ import annotations

import importlib
import sys
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest

from pcdcodec.datasets import load_sample
from pcdcodec.geometry import _cloud_kernels
from pcdcodec.geometry._cloud_kernels import SHADES, cloud_arrays, metres_table
from pcdcodec.geometry.camera import CameraIntrinsics
from pcdcodec.geometry.projector import Projector

SAMPLE = load_sample()
CAMERA = SAMPLE.intrinsics
assert CAMERA is not None
DISTORTED = CameraIntrinsics(
    640, 480, 525.0, 525.0, 319.5, 239.5, "plumb_bob", (0.1, -0.05, 0.001, 0.002, 0.01)
)


def numpy_cloud(
    projector: Projector, depth: Any, color: Any
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32] | None]:
    """The tensor cloud's arrays as the numpy path made them."""
    points, rgb = projector.to_points(depth, color)
    colors = None if rgb is None else np.divide(rgb, np.float32(255.0), dtype=np.float32)
    return points, colors


def assert_same_cloud(projector: Projector, depth: Any, color: Any) -> None:
    pcd = projector.to_point_cloud(depth, color, tensor=True)
    points, colors = numpy_cloud(projector, depth, color)
    positions = pcd.point.positions.numpy()
    assert positions.dtype == np.float32
    assert positions.shape == points.shape
    assert positions.tobytes() == points.tobytes()  # bit for bit, NaN-free
    if colors is None:
        assert "colors" not in pcd.point
    else:
        got = pcd.point.colors.numpy()
        assert got.dtype == np.float32
        assert got.tobytes() == colors.tobytes()


@pytest.mark.parametrize("scale", [5000.0, 1000.0, 4095.875, 1000 / 0.3, 1.0])
@pytest.mark.parametrize("trunc", [None, 0.9, 2.5])
def test_sample_frames_every_scale_and_trunc(scale: float, trunc: float | None) -> None:
    projector = Projector(CAMERA, depth_scale=scale, depth_trunc=trunc)
    for frame in SAMPLE.frames[::7]:
        assert_same_cloud(projector, frame.depth, frame.color)
        assert_same_cloud(projector, frame.depth, None)


@pytest.mark.parametrize("scale", [5000.0, 1000.0, 4095.875, 1000 / 0.3])
def test_every_uint16_value(scale: float) -> None:
    camera = CameraIntrinsics(256, 256, 200.0, 210.0, 127.5, 120.25)
    depth = np.arange(65536, dtype=np.uint16).reshape(256, 256)
    color = np.random.default_rng(1).integers(0, 256, (256, 256, 3), dtype=np.uint8)
    for trunc in (None, 5.0):
        assert_same_cloud(Projector(camera, depth_scale=scale, depth_trunc=trunc), depth, color)


def test_distorted_camera_and_layouts() -> None:
    frame = SAMPLE.frames[3]
    projector = Projector(DISTORTED, depth_scale=SAMPLE.depth_scale)
    assert_same_cloud(projector, frame.depth, frame.color)
    plain = Projector(CAMERA, depth_scale=SAMPLE.depth_scale)
    wide_depth = np.zeros((480, 1280), np.uint16)
    wide_depth[:, ::2] = frame.depth
    wide_color = np.zeros((480, 1280, 3), np.uint8)
    wide_color[:, ::2] = frame.color
    for depth, color in (
        (wide_depth[:, ::2], wide_color[:, ::2]),  # strided views
        (np.asfortranarray(frame.depth), np.asfortranarray(frame.color)),
        (frame.depth.astype(">u2"), frame.color),  # big-endian: the numpy path
    ):
        assert_same_cloud(plain, depth, color)


def test_pixels_without_a_ray_are_left_out() -> None:
    rng = np.random.default_rng(2)
    depth = rng.integers(0, 3000, (48, 64)).astype(np.uint16)
    depth[rng.random(depth.shape) < 0.3] = 0
    color = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    ok = rng.random(depth.size) < 0.8
    ray_x = rng.standard_normal(depth.size).astype(np.float32)
    ray_y = rng.standard_normal(depth.size).astype(np.float32)
    metres = metres_table(np.zeros(65536, np.float32), 1000.0)
    positions, colors = cloud_arrays(depth, 2500, ok, metres, ray_x, ray_y, color)
    keep = np.flatnonzero((depth.reshape(-1) > 0) & (depth.reshape(-1) <= 2500) & ok)
    z = depth.reshape(-1)[keep] / np.float32(1000.0)
    assert positions.tobytes() == np.stack([ray_x[keep] * z, ray_y[keep] * z, z], 1).tobytes()
    assert colors is not None
    assert colors.tobytes() == SHADES[color.reshape(-1, 3)[keep]].tobytes()


def test_no_valid_pixel_and_separate_results() -> None:
    projector = Projector(CAMERA, depth_scale=SAMPLE.depth_scale)
    frame = SAMPLE.frames[0]
    empty = projector.to_point_cloud(np.zeros_like(frame.depth), frame.color, tensor=True)
    assert empty.point.positions.shape == (0, 3)
    assert empty.point.colors.shape == (0, 3)
    first = projector.to_point_cloud(frame.depth, frame.color, tensor=True)
    kept = first.point.positions.numpy().copy()
    projector.to_point_cloud(SAMPLE.frames[1].depth, SAMPLE.frames[1].color, tensor=True)
    assert np.array_equal(first.point.positions.numpy(), kept)  # no buffer is shared


def test_shades_are_the_division() -> None:
    values = np.arange(256, dtype=np.uint8)
    assert SHADES.dtype == np.float32
    assert SHADES.tobytes() == (values / np.float32(255.0)).astype(np.float32).tobytes()


def _address(cloud: Any) -> int:
    """Where the cloud's positions are in memory."""
    return int(cloud.point.positions.numpy().__array_interface__["data"][0])


def test_arrays_are_reused_only_when_nothing_holds_them() -> None:
    projector = Projector(CAMERA, depth_scale=SAMPLE.depth_scale)
    a, b = SAMPLE.frames[0], SAMPLE.frames[1]
    first = projector.to_point_cloud(a.depth, a.color, tensor=True)
    address = _address(first)
    del first
    again = projector.to_point_cloud(b.depth, b.color, tensor=True)
    assert _address(again) == address  # no cloud held it: reused
    assert_same_cloud(projector, b.depth, b.color)
    # A cloud, or only a numpy view of its arrays, keeps them from reuse.
    view = again.point.positions.numpy()
    colors = again.point.colors.numpy()
    kept_view, kept_colors = view.copy(), colors.copy()
    del again
    other = projector.to_point_cloud(a.depth, a.color, tensor=True)
    assert _address(other) != address
    assert np.array_equal(view, kept_view)
    assert np.array_equal(colors, kept_colors)
    held = [projector.to_point_cloud(f.depth, f.color, tensor=True) for f in SAMPLE.frames[:4]]
    for f, cloud in zip(SAMPLE.frames[:4], held, strict=True):
        points, shades = numpy_cloud(projector, f.depth, f.color)
        assert cloud.point.positions.numpy().tobytes() == points.tobytes()
        assert shades is not None
        assert cloud.point.colors.numpy().tobytes() == shades.tobytes()


def test_clouds_kept_across_frames_and_views_of_dropped_clouds_keep_their_points() -> None:
    projector = Projector(CAMERA, depth_scale=SAMPLE.depth_scale)
    frames = SAMPLE.frames[:6]
    expected = [numpy_cloud(projector, f.depth, f.color) for f in frames]
    kept, views = [], []
    for k, f in enumerate(frames * 3):
        cloud = projector.to_point_cloud(f.depth, f.color if k % 2 else None, tensor=True)
        if k < len(frames):
            kept.append(cloud)  # whole clouds of the first pass
        elif k % 3 == 0:
            views.append((k % len(frames), cloud.point.positions.numpy()))  # views only
        del cloud
    for (points, _), cloud in zip(expected, kept, strict=True):
        assert cloud.point.positions.numpy().tobytes() == points.tobytes()
    for i, view in views:
        assert view.tobytes() == expected[i][0].tobytes()


def test_clouds_made_on_threads_keep_their_points() -> None:
    projector = Projector(CAMERA, depth_scale=SAMPLE.depth_scale)
    frames = SAMPLE.frames[:4]
    expected = [numpy_cloud(projector, f.depth, f.color)[0].tobytes() for f in frames]

    def make(k: int) -> list[tuple[int, Any]]:
        out = []
        for j in range(12):
            i = (k + j) % len(frames)
            cloud = projector.to_point_cloud(frames[i].depth, frames[i].color, tensor=True)
            if j % 2:
                out.append((i, cloud))
        return out

    with ThreadPoolExecutor(3) as pool:
        made = [c for part in pool.map(make, range(6)) for c in part]
    for i, cloud in made:
        assert cloud.point.positions.numpy().tobytes() == expected[i]


def test_reuse_holds_where_getrefcount_counts_fewer_references(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Pythons whose interpreter borrows references to locals (3.14) count fewer of them; the
    # count of a free array must be measured, or an array still in use is handed out again.
    real = sys.getrefcount
    monkeypatch.setattr(sys, "getrefcount", lambda obj: real(obj) - 2)
    kernels = importlib.reload(_cloud_kernels)
    try:
        camera = CameraIntrinsics(64, 48, 60.0, 60.0, 31.5, 23.5)
        rng = np.random.default_rng(3)
        projector = Projector(camera, depth_scale=1000.0)
        depths = [rng.integers(1, 4000, (48, 64)).astype(np.uint16) for _ in range(3)]
        held = [projector.to_point_cloud(d, tensor=True) for d in depths]
        views = [c.point.positions.numpy() for c in held]
        del held
        for d, view in zip(depths, views, strict=True):
            assert view.tobytes() == projector.to_points(d)[0].tobytes()
        pool: dict[str, Any] = {}
        metres = kernels.metres_table(np.zeros(65536, np.float32), 1000.0)
        ray = np.ones(depths[0].size, np.float32)
        first, _ = kernels.cloud_arrays(depths[0], 65535, None, metres, ray, ray, None, pool)
        kept = first.copy()
        kernels.cloud_arrays(depths[1], 65535, None, metres, ray, ray, None, pool)
        assert first.tobytes() == kept.tobytes()
    finally:
        monkeypatch.undo()
        importlib.reload(_cloud_kernels)
