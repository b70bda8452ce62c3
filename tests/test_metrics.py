"""Tests of pcdcodec.metrics: each metric against hand-computed values, plus real frames."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import imagecodecs
import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from pcdcodec.errors import InputError, InputTypeError
from pcdcodec.metrics import DepthError, depth_error, mse, point_to_point, psnr, ssim

SAMPLE = Path(__file__).resolve().parents[1] / "pcdcodec" / "data" / "tum_fr1_rpy"
C1 = (0.01 * 255) ** 2  # 6.5025
C2 = (0.03 * 255) ** 2  # 58.5225


def _read_png(path: Path) -> np.ndarray[Any, Any]:
    return np.asarray(imagecodecs.png_decode(path.read_bytes()))


@pytest.fixture(scope="module")
def rgb() -> np.ndarray[Any, Any]:
    return _read_png(sorted((SAMPLE / "rgb").glob("*.png"))[0])


@pytest.fixture(scope="module")
def depth() -> np.ndarray[Any, Any]:
    return _read_png(sorted((SAMPLE / "depth").glob("*.png"))[0])


def _jpeg(image: np.ndarray[Any, Any], quality: int) -> np.ndarray[Any, Any]:
    return np.asarray(imagecodecs.jpeg8_decode(imagecodecs.jpeg8_encode(image, level=quality)))


# -- MSE and PSNR ----------------------------------------------------------------------------


def test_mse_psnr_2x2_one_pixel() -> None:
    ref = np.array([[10, 20], [30, 40]], dtype=np.uint8)
    test = ref.copy()
    test[1, 0] = 34  # one error of 4 over 4 pixels: MSE = 4**2 / 4 = 4
    assert mse(ref, test) == 4.0
    # PSNR = 10 log10(255**2 / 4) = 10 log10(16256.25) = 42.1102 dB
    assert psnr(ref, test) == pytest.approx(42.1102, abs=1e-4)
    assert psnr(test, ref) == psnr(ref, test)


def test_mse_psnr_rgb_one_channel_of_one_pixel() -> None:
    ref = np.full((2, 2, 3), 200, dtype=np.uint8)
    test = ref.copy()
    test[0, 1, 2] = 194  # error 6 over 2*2*3 = 12 values: MSE = 36 / 12 = 3
    assert mse(ref, test) == 3.0
    # PSNR = 10 log10(65025 / 3) = 10 log10(21675) = 43.3596 dB
    assert psnr(ref, test) == pytest.approx(43.3596, abs=1e-4)


def test_mse_does_not_wrap_uint8() -> None:
    ref = np.zeros((1, 2), dtype=np.uint8)
    test = np.array([[255, 0]], dtype=np.uint8)  # 0 - 255 would wrap to 1 in uint8
    assert mse(ref, test) == 255.0**2 / 2


def test_psnr_identical_is_inf_and_peak_is_used() -> None:
    img = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert psnr(img, img.copy()) == math.inf
    assert mse(img, img) == 0.0
    ref = np.array([0.0, 0.5, 1.0, 0.25])
    test = np.array([0.0, 0.5, 0.9, 0.25])  # MSE = 0.01 / 4 = 0.0025
    # peak 1: PSNR = 10 log10(1 / 0.0025) = 10 log10(400) = 26.0206 dB
    assert psnr(ref, test, peak=1.0) == pytest.approx(26.0206, abs=1e-4)
    # 16-bit peak: the same error reads 20 log10(65535) dB higher.
    assert psnr(ref, test, peak=65535.0) == pytest.approx(26.0206 + 96.3295, abs=1e-4)


@pytest.mark.parametrize(
    ("ref", "test", "error", "match"),
    [
        (np.zeros((2, 2), np.uint8), np.zeros((2, 3), np.uint8), InputError, r"\(2, 2\).*\(2, 3\)"),
        (
            np.zeros((2, 2), np.uint8),
            np.zeros((2, 2), np.float32),
            InputTypeError,
            "uint8.*float32",
        ),
        (np.zeros((0, 2), np.uint8), np.zeros((0, 2), np.uint8), InputError, "empty"),
        (np.zeros((2, 2), bool), np.zeros((2, 2), bool), InputTypeError, "bool"),
        (np.array([1.0, np.nan]), np.array([1.0, 2.0]), InputError, "reference has NaN"),
        (np.array(["a"]), np.array(["b"]), InputTypeError, "<U1"),
    ],
)
def test_psnr_mse_bad_inputs(ref: Any, test: Any, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        psnr(ref, test)
    with pytest.raises(error, match=match):
        mse(ref, test)


@pytest.mark.parametrize(
    ("peak", "error"),
    [(0, InputError), (-1.0, InputError), (math.inf, InputError), ("255", InputTypeError)],
)
def test_psnr_bad_peak(peak: Any, error: type[Exception]) -> None:
    img = np.zeros((2, 2), np.uint8)
    with pytest.raises(error, match="peak"):
        psnr(img, img, peak=peak)


# -- SSIM ----------------------------------------------------------------------------------


def _ssim_direct(ref: np.ndarray[Any, Any], test: np.ndarray[Any, Any]) -> float:
    """Slow, direct SSIM: every 11 × 11 window explicitly, 2-D Gaussian weights, and the
    variances as weighted means of squared deviations (not E[x²] - mu²)."""
    x = ref.astype(np.float64)
    y = test.astype(np.float64)
    i = np.arange(11) - 5.0
    w = np.exp(-(i[:, None] ** 2 + i[None, :] ** 2) / (2 * 1.5**2))
    w /= w.sum()
    xw = sliding_window_view(x, (11, 11), axis=(0, 1))  # (H-10, W-10, C, 11, 11)
    yw = sliding_window_view(y, (11, 11), axis=(0, 1))
    mx = np.einsum("ijckl,kl->ijc", xw, w)
    my = np.einsum("ijckl,kl->ijc", yw, w)
    dx = xw - mx[..., None, None]
    dy = yw - my[..., None, None]
    vx = np.einsum("ijckl,kl->ijc", dx * dx, w)
    vy = np.einsum("ijckl,kl->ijc", dy * dy, w)
    cxy = np.einsum("ijckl,kl->ijc", dx * dy, w)
    smap = ((2 * mx * my + C1) * (2 * cxy + C2)) / ((mx**2 + my**2 + C1) * (vx + vy + C2))
    return float(smap.mean(axis=(0, 1)).mean())


def test_ssim_identical_is_one(rgb: np.ndarray[Any, Any]) -> None:
    assert ssim(rgb, rgb.copy()) == pytest.approx(1.0, abs=1e-12)
    gray = rgb[:, :, 1]
    assert ssim(gray, gray) == pytest.approx(1.0, abs=1e-12)


def test_ssim_constant_images_by_hand() -> None:
    # Flat images have sigma = 0 everywhere, so only the luminance term remains:
    # (2*100*110 + C1) / (100**2 + 110**2 + C1) = 22006.5025 / 22106.5025 = 0.9954764
    a = np.full((16, 16), 100, np.uint8)
    b = np.full((16, 16), 110, np.uint8)
    assert ssim(a, b) == pytest.approx(22006.5025 / 22106.5025, rel=1e-12)
    assert ssim(a, b) == pytest.approx(0.9954764, abs=1e-7)


def test_ssim_is_symmetric_and_below_one(rgb: np.ndarray[Any, Any]) -> None:
    degraded = _jpeg(rgb, 30)
    forward = ssim(rgb, degraded)
    assert forward < 0.99
    assert ssim(degraded, rgb) == pytest.approx(forward, rel=1e-12)


def test_ssim_of_inverted_image_is_low(rgb: np.ndarray[Any, Any]) -> None:
    # Inversion flips the sign of every covariance: the structure term goes negative where
    # there is texture, and the luminance term is small wherever the image is not mid-gray.
    assert abs(ssim(rgb, 255 - rgb)) < 0.1


def test_ssim_matches_direct_implementation(rgb: np.ndarray[Any, Any]) -> None:
    degraded = _jpeg(rgb, 30)
    crop = (slice(200, 240), slice(300, 348))  # 40 × 48 × 3 of a real frame
    ref, test = rgb[crop], degraded[crop]
    expected = _ssim_direct(ref, test)
    assert 0.3 < expected < 0.99  # a real difference, not a trivial case
    assert ssim(ref, test) == pytest.approx(expected, abs=1e-10)
    # Gray images (H × W) go through the same path.
    assert ssim(ref[:, :, 0], test[:, :, 0]) == pytest.approx(
        _ssim_direct(ref[:, :, :1], test[:, :, :1]), abs=1e-10
    )


def test_ssim_rgb_is_mean_of_channels(rgb: np.ndarray[Any, Any]) -> None:
    degraded = _jpeg(rgb, 30)
    per_channel = [ssim(rgb[:, :, c], degraded[:, :, c]) for c in range(3)]
    assert max(per_channel) - min(per_channel) > 1e-4  # the channels really differ
    assert ssim(rgb, degraded) == pytest.approx(sum(per_channel) / 3, rel=1e-12)


def test_ssim_decreases_with_noise(rgb: np.ndarray[Any, Any]) -> None:
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 1.0, rgb.shape)
    values = [
        ssim(rgb, np.clip(rgb + sigma * noise, 0, 255).round().astype(np.uint8))
        for sigma in (2.0, 8.0, 32.0)
    ]
    assert 1.0 > values[0] > values[1] > values[2] > 0.0


@pytest.mark.parametrize(
    ("ref", "test", "error", "match"),
    [
        (np.zeros((20, 20), np.float32), np.zeros((20, 20), np.float32), InputTypeError, "float32"),
        (np.zeros((20, 20), np.uint8), np.zeros((20, 21), np.uint8), InputError, r"\(20, 21\)"),
        (np.zeros((10, 40), np.uint8), np.zeros((10, 40), np.uint8), InputError, "11 × 11"),
        (np.zeros((20,), np.uint8), np.zeros((20,), np.uint8), InputError, r"\(20,\)"),
    ],
)
def test_ssim_bad_inputs(ref: Any, test: Any, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        ssim(ref, test)


# -- depth ---------------------------------------------------------------------------------

# A 1000 | 2000 step (a 100 % jump) between columns 1 and 2, and a hole at the bottom left.
REF_DEPTH = np.array(
    [
        [1000, 1000, 2000, 2000],
        [1000, 1000, 2000, 2000],
        [1000, 1000, 2000, 2000],
        [0, 1000, 2000, 2000],
    ],
    dtype=np.uint16,
)
# Edge pixels: columns 1 and 2 (the step, 8 pixels) and (2, 0), next to the hole; (3, 1) is in
# column 1 anyway. Interior: (0, 0), (1, 0) and column 3 (6 pixels). 15 valid pixels in all.
EXPECTED_EDGE = np.array([[0, 1, 1, 0], [0, 1, 1, 0], [1, 1, 1, 0], [0, 1, 1, 0]], dtype=bool)


def _test_depth() -> np.ndarray[Any, Any]:
    test = REF_DEPTH.copy()
    test[0, 0] = 1003  # interior, error 3
    test[1, 2] = 1990  # edge, error 10
    test[2, 1] = 1004  # edge, error 4
    test[0, 3] = 0  # interior pixel lost: a hole created
    test[3, 0] = 1000  # the hole filled
    return test


def _check_hand_example(result: DepthError, unit: float, rel: float) -> None:
    assert result.valid_pixels == 15
    assert result.exact_pixels == 11  # 15 - 3 wrong - 1 lost
    assert result.exact_fraction == pytest.approx(11 / 15)
    assert result.compared_pixels == 14
    assert result.holes_created == 1
    assert result.holes_filled == 1
    # Over the 14 compared pixels: errors 3, 10, 4 and eleven zeros.
    assert result.max_abs_error == pytest.approx(10 * unit, rel=rel)
    assert result.rmse == pytest.approx(math.sqrt((9 + 100 + 16) / 14) * unit, rel=rel)
    assert result.mean_abs_error == pytest.approx(17 / 14 * unit, rel=rel)
    assert result.edge_pixels == 9
    assert result.interior_pixels == 6
    # Edge: 9 pixels, errors 10 and 4. Interior: 5 compared (one lost), error 3.
    assert result.edge_rmse == pytest.approx(math.sqrt(116 / 9) * unit, rel=rel)
    assert result.edge_max_abs_error == pytest.approx(10 * unit, rel=rel)
    assert result.interior_rmse == pytest.approx(math.sqrt(9 / 5) * unit, rel=rel)
    assert result.interior_max_abs_error == pytest.approx(3 * unit, rel=rel)


def test_depth_error_uint16_hand_example() -> None:
    result = depth_error(REF_DEPTH, _test_depth())
    _check_hand_example(result, 1.0, 1e-12)
    assert result.depth_scale is None
    assert result.rmse_m is None


def test_depth_error_metres_from_depth_scale() -> None:
    result = depth_error(REF_DEPTH, _test_depth(), depth_scale=5000)
    assert result.rmse_m == pytest.approx(math.sqrt(125 / 14) / 5000)
    assert result.max_abs_error_m == pytest.approx(10 / 5000)
    assert result.edge_max_abs_error_m == pytest.approx(10 / 5000)
    assert result.interior_rmse_m == pytest.approx(math.sqrt(9 / 5) / 5000)


def test_depth_error_float32_metres_with_nan_and_zero_holes() -> None:
    ref = (REF_DEPTH / 5000.0).astype(np.float32)
    ref[REF_DEPTH == 0] = np.nan
    test = (_test_depth() / 5000.0).astype(np.float32)
    test[0, 3] = 0.0  # 0 is a hole for float depth too
    result = depth_error(ref, test)
    # float32 rounding of the metres leaves errors within ~1e-4 relative of the exact ones.
    _check_hand_example(result, 1 / 5000, 1e-4)
    assert result.depth_scale == 1.0
    assert result.rmse_m == result.rmse


def test_depth_edge_definition() -> None:
    ref = REF_DEPTH.copy()
    test = np.where(REF_DEPTH > 0, REF_DEPTH + 1, 0).astype(np.uint16)  # error 1 everywhere
    result = depth_error(ref, test)
    assert result.edge_pixels == int(EXPECTED_EDGE.sum()) == 9
    # A 200 % threshold ignores the step: only the 3 neighbours of the hole remain.
    assert depth_error(ref, test, edge_threshold=2.0).edge_pixels == 3
    # A 1000 → 1040 change is a 4 % jump: an edge at 3 %, not at the default 5 %.
    gentle = np.full((3, 6), 1000, np.uint16)
    gentle[:, 3:] = 1040
    assert depth_error(gentle, gentle).edge_pixels == 0
    assert depth_error(gentle, gentle, edge_threshold=0.03).edge_pixels == 6
    # Diagonal neighbours count: a single far pixel makes all its 8 neighbours edges.
    spike = np.full((5, 5), 1000, np.uint16)
    spike[2, 2] = 3000
    assert depth_error(spike, spike).edge_pixels == 9
    # The image border is not a hole.
    assert (
        depth_error(np.full((3, 3), 500, np.uint16), np.full((3, 3), 500, np.uint16)).edge_pixels
        == 0
    )


def test_depth_error_no_valid_pixels_gives_nan() -> None:
    ref = np.zeros((2, 2), np.uint16)
    test = np.array([[0, 7], [0, 0]], np.uint16)
    result = depth_error(ref, test)
    assert result.valid_pixels == 0
    assert result.holes_filled == 1
    assert math.isnan(result.rmse)
    assert math.isnan(result.exact_fraction)


def test_depth_error_is_frozen() -> None:
    result = depth_error(REF_DEPTH, REF_DEPTH)
    with pytest.raises(AttributeError):
        result.rmse = 1.0  # type: ignore[misc]


def test_depth_error_real_frame(depth: np.ndarray[Any, Any]) -> None:
    same = depth_error(depth, depth.copy(), depth_scale=5000)
    assert same.exact_fraction == 1.0
    assert same.rmse == 0.0
    assert 0 < same.edge_pixels < same.valid_pixels
    # Quantising to steps of 8 units (0.8 mm... 1.6 mm at TUM's 5000 units/m) as a lossy codec
    # might: every error is in -3..4 units, and no hole is created.
    lossy = np.where(depth > 0, depth // 8 * 8 + 4, 0).astype(np.uint16)
    result = depth_error(depth, lossy, depth_scale=5000)
    assert result.max_abs_error == 4.0
    assert result.holes_created == 0
    assert result.holes_filled == 0
    assert 0.0 < result.exact_fraction < 0.25
    assert 1.0 < result.rmse < 4.0
    assert result.max_abs_error_m == pytest.approx(4 / 5000)


@pytest.mark.parametrize(
    ("ref", "test", "kwargs", "error", "match"),
    [
        (REF_DEPTH, REF_DEPTH.astype(np.float32), {}, InputTypeError, "uint16 and float32"),
        (REF_DEPTH, REF_DEPTH[:3], {}, InputError, r"\(4, 4\) and \(3, 4\)"),
        (REF_DEPTH.astype(np.int64), REF_DEPTH, {}, InputTypeError, "reference must be"),
        (REF_DEPTH, REF_DEPTH[None], {}, InputError, "test must be a 2-D"),
        (REF_DEPTH, REF_DEPTH, {"depth_scale": 0}, InputError, "depth_scale"),
        (REF_DEPTH, REF_DEPTH, {"edge_threshold": -0.1}, InputError, "edge_threshold"),
        (REF_DEPTH, REF_DEPTH, {"edge_threshold": "5%"}, InputTypeError, "edge_threshold"),
        (
            np.full((2, 2), 1.0, np.float32),
            np.array([[1.0, -1.0], [1.0, 1.0]], np.float32),
            {},
            InputError,
            r"test has -1.0 at \(row, col\) \(0, 1\)",
        ),
        (
            np.array([[1.0, np.inf], [1.0, 1.0]], np.float32),
            np.full((2, 2), 1.0, np.float32),
            {},
            InputError,
            "reference has inf",
        ),
    ],
)
def test_depth_error_bad_inputs(
    ref: Any, test: Any, kwargs: dict[str, Any], error: type[Exception], match: str
) -> None:
    with pytest.raises(error, match=match):
        depth_error(ref, test, **kwargs)


# -- point clouds --------------------------------------------------------------------------

TRIANGLE = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]])


def test_point_to_point_shift() -> None:
    shift = np.array([0.3, 0.4, 0.0])  # length 0.5, far below the 10 m spacing
    result = point_to_point(TRIANGLE, TRIANGLE + shift)
    assert result.rmse_reference_to_test == pytest.approx(0.5)
    assert result.rmse_test_to_reference == pytest.approx(0.5)
    assert result.rmse == pytest.approx(0.5)
    assert result.hausdorff == pytest.approx(0.5)
    assert result.mse == pytest.approx(0.25)
    # peak = bounding-box diagonal = sqrt(10² + 10² + 0²) = sqrt(200)
    # D1 PSNR = 10 log10(200 / 0.25) = 10 log10(800) = 29.0309 dB
    assert result.peak == pytest.approx(math.sqrt(200))
    assert result.d1_psnr == pytest.approx(29.0309, abs=1e-4)
    # With peak 1: 10 log10(1 / 0.25) = 6.0206 dB
    assert point_to_point(TRIANGLE, TRIANGLE + shift, peak=1.0).d1_psnr == pytest.approx(
        6.0206, abs=1e-4
    )
    assert (result.reference_points, result.test_points) == (3, 3)


def test_point_to_point_outlier_and_hausdorff() -> None:
    test = np.vstack([TRIANGLE, [[0.0, 0.0, 7.0]]])  # one extra point 7 above the origin
    result = point_to_point(TRIANGLE, test)
    assert result.rmse_reference_to_test == 0.0  # every reference point is in the test
    # test -> reference: distances 0, 0, 0, 7: RMSE = sqrt(49 / 4) = 3.5
    assert result.rmse_test_to_reference == pytest.approx(3.5)
    assert result.rmse == pytest.approx(3.5)  # the larger direction
    assert result.hausdorff == pytest.approx(7.0)
    # Swapping the roles swaps the directions but keeps the symmetric values.
    swapped = point_to_point(test, TRIANGLE, peak=result.peak)
    assert swapped.rmse_reference_to_test == pytest.approx(3.5)
    assert swapped.rmse == pytest.approx(result.rmse)
    assert swapped.d1_psnr == pytest.approx(result.d1_psnr)


def test_point_to_point_identical_is_inf() -> None:
    result = point_to_point(TRIANGLE, TRIANGLE[::-1].copy())
    assert result.rmse == 0.0
    assert result.hausdorff == 0.0
    assert result.d1_psnr == math.inf


def test_point_to_point_accepts_open3d_clouds() -> None:
    import open3d as o3d

    legacy = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(TRIANGLE))
    tensor = o3d.t.geometry.PointCloud(
        o3d.core.Tensor((TRIANGLE + np.array([0.0, 0.0, 0.2])).astype(np.float32))
    )
    result = point_to_point(legacy, tensor)
    assert result.rmse == pytest.approx(0.2, rel=1e-6)
    assert result.hausdorff == pytest.approx(0.2, rel=1e-6)


def test_point_to_point_real_frame(depth: np.ndarray[Any, Any]) -> None:
    from pcdcodec.geometry.camera import CameraIntrinsics
    from pcdcodec.geometry.projector import Projector

    cam = json.loads((SAMPLE / "camera.json").read_text())
    keys = ("width", "height", "fx", "fy", "cx", "cy")
    projector = Projector(CameraIntrinsics(**{k: cam[k] for k in keys}), cam["depth_scale"])
    ref = projector.to_points(depth)[0][::4]
    # One depth unit farther: each point moves 1/5000 m along its ray, at most 1.3 × that
    # at the image corners, so no nearest neighbour is farther than that.
    test = projector.to_points(np.where(depth > 0, depth + 1, 0).astype(np.uint16))[0][::4]
    result = point_to_point(ref, test)
    assert 0.0 < result.rmse <= 1.3 / 5000
    assert result.hausdorff <= 1.3 / 5000
    assert 60.0 < result.d1_psnr < 100.0


@pytest.mark.parametrize(
    ("points", "error", "match"),
    [
        (np.zeros((3, 2)), InputError, r"test_points must have shape \(N, 3\), got \(3, 2\)"),
        (np.zeros((0, 3)), InputError, "test_points must not be empty"),
        (np.array([[0.0, np.nan, 0.0]]), InputError, "NaN or infinite.*index 0"),
        (np.array([["a", "b", "c"]]), InputTypeError, "test_points must be"),
        ("points", InputTypeError, "test_points must be"),
    ],
)
def test_point_to_point_bad_inputs(points: Any, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        point_to_point(TRIANGLE, points)


def test_point_to_point_bad_peak_and_degenerate_reference() -> None:
    with pytest.raises(InputError, match="peak"):
        point_to_point(TRIANGLE, TRIANGLE, peak=0.0)
    with pytest.raises(InputError, match="pass peak"):
        point_to_point(np.ones((4, 3)), TRIANGLE)
    # An explicit peak makes a single-point reference usable.
    assert point_to_point(np.ones((1, 3)), np.ones((1, 3)), peak=1.0).d1_psnr == math.inf


# -- real frames ---------------------------------------------------------------------------


def test_psnr_ssim_of_jpeg_recompressed_frame(rgb: np.ndarray[Any, Any]) -> None:
    assert rgb.shape == (480, 640, 3)
    assert rgb.dtype == np.uint8
    q90, q30 = _jpeg(rgb, 90), _jpeg(rgb, 30)
    psnr90, psnr30 = psnr(rgb, q90), psnr(rgb, q30)
    assert 30.0 < psnr90 < 50.0
    assert 25.0 < psnr30 < psnr90 - 1.0
    ssim90, ssim30 = ssim(rgb, q90), ssim(rgb, q30)
    assert 0.8 < ssim30 < ssim90 < 1.0
