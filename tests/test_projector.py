"""Projector: depth to points (checked against Open3D on real TUM frames) and points to depth."""

from __future__ import annotations

import gc
import pickle
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import imagecodecs
import numpy as np
import numpy.typing as npt
import open3d as o3d
import pytest

from pcdcodec.errors import InputError, InputTypeError
from pcdcodec.geometry.camera import CameraIntrinsics
from pcdcodec.geometry.projector import Projector, Reprojection

TUM_DIR = Path(__file__).resolve().parents[1] / "pcdcodec" / "data" / "tum_fr1_rpy"
TUM_SCALE = 5000.0
TUM = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
FRAMES = (0, 7, 14)

Frame = tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]


def _read_png(path: Path) -> npt.NDArray[Any]:
    return np.asarray(imagecodecs.png_decode(path.read_bytes()))


def _load_tum(index: int) -> Frame:
    lines = (TUM_DIR / "associations.txt").read_text().split("\n")
    _, rgb, _, depth = lines[index].split()
    color = _read_png(TUM_DIR / rgb)
    depth_img = _read_png(TUM_DIR / depth)
    assert color.dtype == np.uint8
    assert color.shape == (480, 640, 3)
    assert depth_img.dtype == np.uint16
    assert depth_img.shape == (480, 640)
    return color, depth_img


@pytest.fixture(scope="module", params=FRAMES, ids=[f"frame{i}" for i in FRAMES])
def frame(request: pytest.FixtureRequest) -> Frame:
    return _load_tum(request.param)


@pytest.fixture(scope="module")
def frame0() -> Frame:
    return _load_tum(0)


@pytest.fixture(scope="module")
def projector() -> Projector:
    return Projector(TUM, depth_scale=TUM_SCALE)


def _o3d_legacy(color: Any, depth: Any, depth_trunc: float = 1000.0, **kw: Any) -> Any:
    rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
        o3d.geometry.Image(np.ascontiguousarray(color)),
        o3d.geometry.Image(np.ascontiguousarray(depth)),
        depth_scale=TUM_SCALE,
        depth_trunc=depth_trunc,
        convert_rgb_to_intensity=kw.get("convert_rgb_to_intensity", False),
    )
    return rgbd


def _o3d_legacy_cloud(color: Any, depth: Any, depth_trunc: float = 1000.0) -> Any:
    rgbd = _o3d_legacy(color, depth, depth_trunc)
    return o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, TUM.to_open3d())


def _pixel_order(points: npt.NDArray[Any]) -> npt.NDArray[np.intp]:
    """Sort order of points by the pixel they project to (row-major)."""
    u = np.rint(points[:, 0] * TUM.fx / points[:, 2] + TUM.cx).astype(np.intp)
    v = np.rint(points[:, 1] * TUM.fy / points[:, 2] + TUM.cy).astype(np.intp)
    return np.argsort(v * TUM.width + u, kind="stable")


# -- against Open3D -------------------------------------------------------------------------


def test_to_points_matches_open3d_legacy(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    points, colors = projector.to_points(depth, color)
    ref = _o3d_legacy_cloud(color, depth)
    ref_points, ref_colors = np.asarray(ref.points), np.asarray(ref.colors)
    assert points.dtype == np.float32
    assert points.shape == (np.count_nonzero(depth), 3)
    assert colors is not None
    assert colors.dtype == np.uint8
    assert points.shape == ref_points.shape
    np.testing.assert_allclose(points, ref_points, rtol=0, atol=1e-6)
    # z is bit-identical: both compute float32(depth / 5000).
    np.testing.assert_array_equal(points[:, 2], ref_points[:, 2].astype(np.float32))
    np.testing.assert_array_equal(colors / 255.0, ref_colors)


def test_to_point_cloud_legacy_matches_open3d_legacy(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    pcd = projector.to_point_cloud(depth, color)
    ref = _o3d_legacy_cloud(color, depth)
    assert isinstance(pcd, o3d.geometry.PointCloud)
    np.testing.assert_allclose(np.asarray(pcd.points), np.asarray(ref.points), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(pcd.colors), np.asarray(ref.colors))
    # Exactly the float32 points of to_points, widened.
    points, _ = projector.to_points(depth)
    np.testing.assert_array_equal(np.asarray(pcd.points), points.astype(np.float64))


def test_to_point_cloud_tensor_matches_open3d_legacy(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    pcd = projector.to_point_cloud(depth, color, tensor=True)
    ref = _o3d_legacy_cloud(color, depth)
    assert isinstance(pcd, o3d.t.geometry.PointCloud)
    positions = pcd.point.positions.numpy()
    colors = pcd.point.colors.numpy()
    assert positions.dtype == np.float32
    assert colors.dtype == np.float32
    np.testing.assert_allclose(positions, np.asarray(ref.points), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(colors, np.asarray(ref.colors).astype(np.float32))


def test_matches_open3d_tensor_api(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    rgbd = o3d.t.geometry.RGBDImage(o3d.t.geometry.Image(color), o3d.t.geometry.Image(depth))
    ref = o3d.t.geometry.PointCloud.create_from_rgbd_image(
        rgbd, o3d.core.Tensor(TUM.K), depth_scale=TUM_SCALE, depth_max=1000.0
    )
    ref_pos, ref_col = ref.point.positions.numpy(), ref.point.colors.numpy()
    # The tensor API fills its output in parallel: compare in pixel order.
    order = _pixel_order(ref_pos)
    ref_pos, ref_col = ref_pos[order], ref_col[order]
    points, colors = projector.to_points(depth, color)
    assert colors is not None
    np.testing.assert_allclose(points, ref_pos, rtol=0, atol=1e-6)
    np.testing.assert_allclose(colors / 255.0, ref_col, rtol=0, atol=1e-6)
    pcd = projector.to_point_cloud(depth, color, tensor=True)
    np.testing.assert_allclose(pcd.point.positions.numpy(), ref_pos, rtol=0, atol=1e-6)
    np.testing.assert_allclose(pcd.point.colors.numpy(), ref_col, rtol=0, atol=1e-6)


def test_points_are_row_major(projector: Projector, frame0: Frame) -> None:
    _, depth = frame0
    points, colors = projector.to_points(depth)
    assert colors is None
    assert np.array_equal(_pixel_order(points), np.arange(len(points)))


def test_depth_trunc_matches_open3d(frame0: Frame) -> None:
    color, depth = frame0
    trunc = 1.23456  # between two depth steps of 1/5000 m: Open3D's ">=" and our "<=" agree
    proj = Projector(TUM, depth_scale=TUM_SCALE, depth_trunc=trunc)
    points, _colors = proj.to_points(depth, color)
    z_all = depth / TUM_SCALE
    expected = np.count_nonzero((depth > 0) & (z_all <= trunc))
    assert 0 < expected < np.count_nonzero(depth)
    assert len(points) == expected
    assert points[:, 2].max() <= trunc
    ref = _o3d_legacy_cloud(color, depth, depth_trunc=trunc)
    np.testing.assert_allclose(points, np.asarray(ref.points), rtol=0, atol=1e-6)
    pcd = proj.to_point_cloud(depth, color)
    assert len(pcd.points) == expected
    tpcd = proj.to_point_cloud(depth, color, tensor=True)
    assert tpcd.point.positions.shape[0] == expected
    organized = proj.to_organized(depth)
    assert np.count_nonzero(~np.isnan(organized[..., 2])) == expected


def test_depth_trunc_keeps_depth_equal_to_it() -> None:
    depth = np.zeros((480, 640), np.uint16)
    depth[10, 20], depth[10, 21], depth[10, 22] = 4999, 5000, 5001
    points, _ = Projector(TUM, depth_scale=TUM_SCALE, depth_trunc=1.0).to_points(depth)
    np.testing.assert_array_equal(points[:, 2], np.array([0.9998, 1.0], np.float32))
    f = depth.astype(np.float32) / np.float32(TUM_SCALE)
    points, _ = Projector(TUM, depth_scale=1.0, depth_trunc=1.0).to_points(f)
    np.testing.assert_array_equal(points[:, 2], np.array([0.9998, 1.0], np.float32))


def test_float32_depth_in_metres_matches_uint16(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    metres = (depth / TUM_SCALE).astype(np.float32)
    metres[depth == 0] = np.nan
    metres[0, :5] = [-1.0, 0.0, np.inf, -np.inf, np.nan]  # never valid
    valid = np.isfinite(metres) & (metres > 0)
    expected, expected_colors = projector.to_points(np.where(valid, depth, 0), color)
    points, colors = Projector(TUM, depth_scale=1.0).to_points(metres, color)
    np.testing.assert_array_equal(points, expected)
    assert colors is not None
    assert expected_colors is not None
    np.testing.assert_array_equal(colors, expected_colors)
    # float32 depth in depth units is divided by depth_scale too.
    units = depth.astype(np.float32)
    np.testing.assert_array_equal(projector.to_points(units)[0], projector.to_points(depth)[0])


# -- RGBDImage input ------------------------------------------------------------------------


def test_legacy_rgbd_image_input(frame0: Frame) -> None:
    color, depth = frame0
    rgbd = _o3d_legacy(color, depth)
    # Open3D already divided by 5000: this projector's depth_scale must not be applied again.
    proj = Projector(TUM, depth_scale=1000.0)
    expected, expected_colors = Projector(TUM, depth_scale=TUM_SCALE).to_points(depth, color)
    points, colors = proj.to_points(rgbd)
    np.testing.assert_array_equal(points, expected)
    assert colors is not None
    assert expected_colors is not None
    np.testing.assert_array_equal(colors, expected_colors)
    pcd = proj.to_point_cloud(rgbd)
    ref = o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, TUM.to_open3d())
    np.testing.assert_allclose(np.asarray(pcd.points), np.asarray(ref.points), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(pcd.colors), np.asarray(ref.colors))
    tpcd = proj.to_point_cloud(rgbd, tensor=True)
    np.testing.assert_array_equal(tpcd.point.positions.numpy(), expected)
    organized = proj.to_organized(rgbd)
    np.testing.assert_array_equal(organized[depth > 0], expected)


def test_legacy_rgbd_image_depth_trunc_applies_on_top(frame0: Frame) -> None:
    color, depth = frame0
    rgbd = _o3d_legacy(color, depth)
    points, _ = Projector(TUM, depth_trunc=1.5).to_points(rgbd)
    assert len(points) == np.count_nonzero((depth > 0) & (depth / TUM_SCALE <= 1.5))


def test_intensity_rgbd_image_gives_gray(frame0: Frame) -> None:
    color, depth = frame0
    rgbd = _o3d_legacy(color, depth, convert_rgb_to_intensity=True)
    intensity = np.asarray(rgbd.color)
    assert intensity.dtype == np.float32
    assert intensity.ndim == 2
    points, colors = Projector(TUM).to_points(rgbd)
    assert colors is not None
    assert len(colors) == len(points) == np.count_nonzero(depth)
    gray = np.rint(intensity[depth > 0] * 255).astype(np.uint8)
    for channel in range(3):
        np.testing.assert_array_equal(colors[:, channel], gray)


def test_tensor_rgbd_image_input(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    rgbd = o3d.t.geometry.RGBDImage(o3d.t.geometry.Image(color), o3d.t.geometry.Image(depth))
    expected, expected_colors = projector.to_points(depth, color)
    points, colors = projector.to_points(rgbd)
    np.testing.assert_array_equal(points, expected)
    assert colors is not None
    assert expected_colors is not None
    np.testing.assert_array_equal(colors, expected_colors)


def test_rgbd_image_with_color_argument_is_an_error(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    with pytest.raises(InputError, match="color must be None when depth is an RGBDImage"):
        projector.to_points(_o3d_legacy(color, depth), color)


# -- organized clouds and the round trip ----------------------------------------------------


def test_to_organized_matches_to_points(projector: Projector, frame: Frame) -> None:
    _, depth = frame
    organized = projector.to_organized(depth)
    assert organized.dtype == np.float32
    assert organized.shape == (480, 640, 3)
    valid = depth > 0
    assert np.isnan(organized[~valid]).all()
    assert not np.isnan(organized[valid]).any()
    np.testing.assert_array_equal(organized[valid], projector.to_points(depth)[0])


def test_organized_round_trip_uint16_is_bit_exact(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    result = projector.to_rgbd_arrays(projector.to_organized(depth), color)
    back_color, back = result
    assert back is not None
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, depth)
    np.testing.assert_array_equal(back_color, color)
    assert result.dropped == 0


# 1000 / 0.3 is not a float32: metres then come from a float64 division, as in Open3D.
@pytest.mark.parametrize("scale", [TUM_SCALE, 1000.0, 4095.875, 1000 / 0.3])
def test_organized_round_trip_every_uint16_value(scale: float) -> None:
    intr = CameraIntrinsics(256, 256, 200.0, 200.0, 128.0, 128.0)
    depth = np.arange(65536, dtype=np.uint16).reshape(256, 256)
    proj = Projector(intr, depth_scale=scale)
    organized = proj.to_organized(depth)
    expected_z = (np.arange(1, 65536) / scale).astype(np.float32)  # Open3D: float(d) / scale
    np.testing.assert_array_equal(organized[..., 2].ravel()[1:], expected_z)
    np.testing.assert_array_equal(proj.to_points(depth)[0][:, 2], expected_z)
    color, back = proj.to_rgbd_arrays(organized)
    assert color is None
    np.testing.assert_array_equal(back, depth)
    # Unorganized, in reverse order.
    np.testing.assert_array_equal(proj.to_rgbd_arrays(proj.to_points(depth)[0][::-1]).depth, depth)


def test_organized_round_trip_float32_is_bit_exact(frame: Frame) -> None:
    _, depth = frame
    metres = (depth / TUM_SCALE).astype(np.float32)
    metres[depth == 0] = np.nan
    proj = Projector(TUM, depth_scale=1.0)
    result = proj.to_rgbd_arrays(proj.to_organized(metres), dtype="float32")
    assert result.depth.dtype == np.float32
    assert np.array_equal(np.isnan(result.depth), depth == 0)
    np.testing.assert_array_equal(result.depth.view(np.uint32), metres.view(np.uint32))
    assert result.dropped == 0


def test_organized_counts_invalid_z(projector: Projector) -> None:
    organized = np.full((480, 640, 3), np.nan, np.float32)
    organized[0, 0, 2] = 1.0
    organized[0, 1, 2] = -1.0  # behind
    organized[0, 2, 2] = 0.0  # behind
    organized[0, 3, 2] = np.inf  # not finite
    organized[0, 4, 2] = 100.0  # 500000 units: does not fit uint16
    organized[0, 5, 2] = 1e-5  # rounds to 0 units
    result = projector.to_rgbd_arrays(organized)
    assert (result.behind_camera, result.out_of_range, result.outside_image) == (3, 2, 0)
    assert np.count_nonzero(result.depth) == 1
    assert result.depth[0, 0] == 5000
    as_float = projector.to_rgbd_arrays(organized, dtype=np.float32)
    assert (as_float.behind_camera, as_float.out_of_range) == (3, 0)
    tiny = float(np.float32(1e-5)) * TUM_SCALE
    expected = np.array([5000.0, np.nan, np.nan, np.nan, 5e5, tiny], np.float32)
    np.testing.assert_array_equal(as_float.depth[0, :6], expected)


# -- unorganized clouds ---------------------------------------------------------------------


def test_unorganized_round_trip_shuffled(projector: Projector, frame: Frame) -> None:
    color, depth = frame
    points, colors = projector.to_points(depth, color)
    assert colors is not None
    perm = np.random.default_rng(1).permutation(len(points))
    result = projector.to_rgbd_arrays(points[perm], colors[perm])
    np.testing.assert_array_equal(result.depth, depth)
    assert result.color is not None
    valid = depth > 0
    np.testing.assert_array_equal(result.color[valid], color[valid])
    assert not result.color[~valid].any()
    assert result.dropped == 0
    # float64 points, float32 output in metres.
    proj = Projector(TUM, depth_scale=1.0)
    back = proj.to_rgbd_arrays(points[perm].astype(np.float64), dtype="float32").depth
    np.testing.assert_array_equal(back[valid], points[:, 2])
    assert np.isnan(back[~valid]).all()


def test_unorganized_drops_are_counted(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    points, colors = projector.to_points(depth, color)
    assert colors is not None
    row = int(np.flatnonzero(depth.ravel())[1000])
    p = points[1000].astype(np.float64)
    extra = np.array(
        [
            [0.0, 0.0, -1.0],  # behind the camera
            [0.0, 0.0, 0.0],  # at the camera
            [np.nan, 0.0, 1.0],  # not finite
            [0.0, 0.0, np.inf],  # not finite
            [-5.0, 0.0, 1.0],  # left of the image
            [0.0, 5.0, 1.0],  # below the image
            [0.0, 0.0, 20.0],  # 100000 units > 65535
            p * 1.5,  # same pixel as point 1000, farther: hidden
            p * 2.0,  # hidden as well
        ]
    )
    extra_colors = np.full((len(extra), 3), 7, np.uint8)
    result = projector.to_rgbd_arrays(
        np.concatenate([points, extra]), np.concatenate([colors, extra_colors])
    )
    assert isinstance(result, Reprojection)
    assert result.behind_camera == 4
    assert result.outside_image == 2
    assert result.out_of_range == 1
    assert result.hidden == 2
    assert result.dropped == 9
    np.testing.assert_array_equal(result.depth, depth)
    assert result.color is not None
    assert tuple(result.color.reshape(-1, 3)[row]) == tuple(color.reshape(-1, 3)[row])
    # A nearer point on the same pixel wins, and the one it covers is counted as hidden.
    nearer = projector.to_rgbd_arrays(np.concatenate([points, [p * 0.5]]))
    assert nearer.hidden == 1
    assert nearer.depth.ravel()[row] == np.rint(p[2] * 0.5 * TUM_SCALE)


def test_unorganized_equal_depth_first_point_wins(projector: Projector) -> None:
    pts = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], np.float32)
    cols = np.array([[10, 20, 30], [40, 50, 60], [70, 80, 90]], np.uint8)
    color, depth = projector.to_rgbd_arrays(pts, cols)
    assert color is not None
    center = (int(TUM.cy + 0.5), int(TUM.cx + 0.5))  # (240, 320): round half up
    assert depth[center] == 5000
    assert np.count_nonzero(depth) == 1
    assert tuple(color[center]) == (10, 20, 30)
    assert projector.to_rgbd_arrays(pts, cols).hidden == 2


def test_unorganized_depth_trunc(frame0: Frame) -> None:
    _, depth = frame0
    proj = Projector(TUM, depth_scale=TUM_SCALE, depth_trunc=1.5)
    points, _ = Projector(TUM, depth_scale=TUM_SCALE).to_points(depth)
    result = proj.to_rgbd_arrays(points)
    far = (depth / TUM_SCALE > 1.5) & (depth > 0)
    assert result.out_of_range == np.count_nonzero(far) > 0
    np.testing.assert_array_equal(result.depth, np.where(far, 0, depth))


def test_empty_point_cloud(projector: Projector) -> None:
    empty = np.empty((0, 3), np.float32)
    color, depth = projector.to_rgbd_arrays(empty, np.empty((0, 3), np.uint8))
    assert depth.shape == (480, 640)
    assert not depth.any()
    assert color is not None
    assert not color.any()
    no_depth, black = np.zeros((480, 640), np.uint16), np.zeros((480, 640, 3), np.uint8)
    points, colors = projector.to_points(no_depth, black)
    assert points.shape == (0, 3)
    assert colors is not None
    assert colors.shape == (0, 3)
    assert len(projector.to_point_cloud(np.zeros((480, 640), np.uint16)).points) == 0


def test_reprojection_unpacks() -> None:
    proj = Projector(CameraIntrinsics(4, 3, 2.0, 2.0, 2.0, 1.5), depth_scale=1000.0)
    result = proj.to_rgbd_arrays(np.array([[0.0, 0.0, 1.0]]))
    color, depth = result
    assert color is None
    assert depth is result.depth
    assert depth.tolist() == [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1000, 0]]


# -- memory layouts -------------------------------------------------------------------------


def _layouts(color: npt.NDArray[np.uint8], depth: npt.NDArray[np.uint16]) -> Iterator[Frame]:
    big_d = np.zeros((480, 700), np.uint16)
    big_d[:, :640] = depth
    big_c = np.zeros((480, 640, 4), np.uint8)
    big_c[..., :3] = color
    yield big_c[..., :3], big_d[:, :640]  # strided views
    yield np.asfortranarray(color), np.asfortranarray(depth)
    yield color, depth.astype(">u2")  # big-endian
    yield color[::-1].copy()[::-1], depth[::-1].copy()[::-1]  # negative strides, same pixels


def test_views_and_layouts(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    expected, expected_colors = projector.to_points(depth, color)
    assert expected_colors is not None
    organized = projector.to_organized(depth)
    legacy = np.asarray(projector.to_point_cloud(depth, color).points)
    for c, d in _layouts(color, depth):
        assert not (c.flags.c_contiguous and d.flags.c_contiguous and d.dtype.isnative)
        points, colors = projector.to_points(d, c)
        np.testing.assert_array_equal(points, expected)
        assert colors is not None
        np.testing.assert_array_equal(colors, expected_colors)
        np.testing.assert_array_equal(projector.to_organized(d), organized)
        pcd = projector.to_point_cloud(d, c)
        np.testing.assert_array_equal(np.asarray(pcd.points), legacy)
    # Non-contiguous points and colors for to_rgbd_arrays.
    wide = np.zeros((len(expected), 5), np.float64)
    wide[:, 1:4] = expected
    rgba = np.zeros((len(expected), 4), np.uint8)
    rgba[:, :3] = expected_colors
    _color_back, depth_back = projector.to_rgbd_arrays(wide[:, 1:4], rgba[:, :3])
    np.testing.assert_array_equal(depth_back, depth)
    fortran = np.asfortranarray(organized)
    np.testing.assert_array_equal(projector.to_rgbd_arrays(fortran).depth, depth)


def test_float_depth_is_not_modified(frame0: Frame) -> None:
    _, depth = frame0
    metres = (depth / TUM_SCALE).astype(np.float32)
    metres[depth == 0] = np.nan
    before = metres.copy()
    proj = Projector(TUM, depth_scale=1.0, depth_trunc=1.0)
    proj.to_organized(metres)
    proj.to_points(metres)
    np.testing.assert_array_equal(metres, before)


# -- reuse, threads, pickling ----------------------------------------------------------------


def test_results_are_not_overwritten_by_later_calls(projector: Projector) -> None:
    (c0, d0), (c1, d1) = _load_tum(0), _load_tum(1)
    points, colors = projector.to_points(d0, c0)
    kept = points.copy(), None if colors is None else colors.copy()
    tensor = projector.to_point_cloud(d0, c0, tensor=True)
    tensor_positions = tensor.point.positions.numpy().copy()
    projector.to_points(d1, c1)
    projector.to_point_cloud(d1, c1)
    projector.to_point_cloud(d1, c1, tensor=True)
    gc.collect()
    np.testing.assert_array_equal(points, kept[0])
    np.testing.assert_array_equal(colors, kept[1])
    np.testing.assert_array_equal(tensor.point.positions.numpy(), tensor_positions)


def test_tensor_cloud_owns_its_memory(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    expected = projector.to_points(depth, color)[0]
    pcd = projector.to_point_cloud(depth, color, tensor=True)
    gc.collect()
    _ = [np.full(len(expected) * 3, 123.0, np.float32) for _ in range(8)]
    np.testing.assert_array_equal(pcd.point.positions.numpy(), expected)


def test_threads_share_a_projector(projector: Projector) -> None:
    frames = [_load_tum(i) for i in range(6)]
    expected = [projector.to_points(d, c)[0] for c, d in frames]

    def work(i: int) -> bool:
        c, d = frames[i % len(frames)]
        return bool(np.array_equal(projector.to_points(d, c)[0], expected[i % len(frames)]))

    with ThreadPoolExecutor(4) as pool:
        assert all(pool.map(work, range(48)))


def test_pickle(projector: Projector, frame0: Frame) -> None:
    _, depth = frame0
    projector.to_points(depth)  # make scratch buffers
    clone = pickle.loads(pickle.dumps(projector))
    assert (clone.intrinsics, clone.depth_scale, clone.depth_trunc) == (TUM, TUM_SCALE, None)
    np.testing.assert_array_equal(clone.to_points(depth)[0], projector.to_points(depth)[0])
    assert "depth_scale=5000.0" in repr(clone)


# -- errors ---------------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", ["int64", "uint8", "float64", "int16", "uint32", "bool"])
def test_depth_dtype_errors(projector: Projector, dtype: str) -> None:
    depth = np.ones((480, 640), dtype=dtype)
    for method in (projector.to_points, projector.to_organized, projector.to_point_cloud):
        with pytest.raises(InputTypeError, match=f"depth must be uint16 or float32, got {dtype}"):
            method(depth)


@pytest.mark.parametrize(
    ("shape", "fragment"),
    [
        ((480, 640, 1), "got shape (480, 640, 1)"),
        ((2, 480, 640), "got shape (2, 480, 640)"),
        ((0, 640), "must not be empty, got shape (0, 640)"),
        ((640,), "got shape (640,)"),
    ],
)
def test_depth_shape_errors(projector: Projector, shape: tuple[int, ...], fragment: str) -> None:
    with pytest.raises(InputError) as info:
        projector.to_points(np.ones(shape, np.uint16))
    assert fragment in str(info.value)


def test_depth_size_differs_from_intrinsics(projector: Projector) -> None:
    for method in (projector.to_points, projector.to_organized, projector.to_point_cloud):
        with pytest.raises(InputError, match=r"depth size 320x240 differs .* size 640x480"):
            method(np.ones((240, 320), np.uint16))


def test_color_errors(projector: Projector, frame0: Frame) -> None:
    color, depth = frame0
    with pytest.raises(InputError, match=r"color size 320x240 differs from the depth size 640x480"):
        projector.to_points(depth, color[::2, ::2])
    with pytest.raises(InputTypeError, match="color must be uint8, got float32"):
        projector.to_point_cloud(depth, color.astype(np.float32))
    with pytest.raises(InputError, match=r"RGBA is not accepted"):
        projector.to_points(depth, np.zeros((480, 640, 4), np.uint8))


@pytest.mark.parametrize(
    ("kwargs", "error", "fragment"),
    [
        ({"depth_scale": 0}, InputError, "depth_scale must be positive and finite, got 0.0"),
        ({"depth_scale": -5000}, InputError, "got -5000.0"),
        ({"depth_scale": float("nan")}, InputError, "got nan"),
        ({"depth_scale": float("inf")}, InputError, "got inf"),
        ({"depth_scale": "5000"}, InputTypeError, "depth_scale must be a number, got str '5000'"),
        ({"depth_trunc": 0.0}, InputError, "depth_trunc must be positive, got 0.0"),
        ({"depth_trunc": -1}, InputError, "got -1.0"),
        ({"depth_trunc": float("nan")}, InputError, "got nan"),
        ({"depth_trunc": True}, InputTypeError, "depth_trunc must be a number, got bool"),
    ],
)
def test_projector_argument_errors(
    kwargs: dict[str, Any], error: type[Exception], fragment: str
) -> None:
    with pytest.raises(error) as info:
        Projector(TUM, **kwargs)
    assert fragment in str(info.value)


def test_projector_needs_camera_intrinsics() -> None:
    with pytest.raises(InputTypeError, match="CameraIntrinsics, got PinholeCameraIntrinsic"):
        Projector(TUM.to_open3d())
    assert Projector(TUM, depth_trunc=float("inf")).depth_trunc is None


def test_to_rgbd_arrays_errors(projector: Projector) -> None:
    pts = np.zeros((10, 3), np.float32)
    with pytest.raises(InputError, match="dtype must be 'uint16' or 'float32', got 'int32'"):
        projector.to_rgbd_arrays(pts, dtype="int32")
    with pytest.raises(InputError, match="got 'metres'"):
        projector.to_rgbd_arrays(pts, dtype="metres")
    with pytest.raises(InputTypeError, match=r"points must be float32 or float64 .* got int64"):
        projector.to_rgbd_arrays(np.zeros((10, 3), np.int64))
    with pytest.raises(InputError, match=r"points must have shape \(N, 3\) .* got \(10, 2\)"):
        projector.to_rgbd_arrays(np.zeros((10, 2), np.float32))
    with pytest.raises(InputError, match=r"organized points size 320x240 differs .* 640x480"):
        projector.to_rgbd_arrays(np.zeros((240, 320, 3), np.float32))
    with pytest.raises(InputTypeError, match="colors must be uint8, got float64"):
        projector.to_rgbd_arrays(pts, np.zeros((10, 3)))
    with pytest.raises(InputError, match=r"shape of the points \(10, 3\), got \(9, 3\)"):
        projector.to_rgbd_arrays(pts, np.zeros((9, 3), np.uint8))
    with pytest.raises(InputError, match="colors size 320x240 differs"):
        projector.to_rgbd_arrays(np.zeros((480, 640, 3)), np.zeros((240, 320, 3), np.uint8))
