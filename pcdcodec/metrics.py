"""Quality metrics for judging what a codec gave back against what went in.

* Color (lossy video): :func:`mse`, :func:`psnr` and :func:`ssim` on 8-bit images.
* Depth (lossless or lossy): :func:`depth_error` compares two depth images pixel by pixel and
  reports exactness, error statistics split into depth edges and smooth interior, and holes
  created or filled, as a :class:`DepthError`.
* Point clouds: :func:`point_to_point` gives nearest-neighbour (D1) distances both ways, the
  Hausdorff distance and an MPEG-style D1 PSNR, as a :class:`PointToPoint`.

Every statistic is accumulated in float64. OpenCV is imported only by :func:`ssim` and Open3D
only by :func:`point_to_point`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ._validate import check_depth, check_real
from .errors import InputError, InputTypeError

__all__ = [
    "DepthError",
    "PointToPoint",
    "depth_error",
    "mse",
    "point_to_point",
    "psnr",
    "ssim",
]

# SSIM constants of Wang et al. 2004 (and of their reference code ssim_index.m).
_SSIM_WINDOW = 11
_SSIM_SIGMA = 1.5
_SSIM_K1 = 0.01
_SSIM_K2 = 0.03
_SSIM_L = 255.0


# -- shared checks -----------------------------------------------------------------------


def _image_pair(reference: Any, test: Any) -> tuple[npt.NDArray[Any], npt.NDArray[Any]]:
    """Two non-empty real arrays of one shape and one dtype, finite when floating point."""
    arrays = []
    for name, value in (("reference", reference), ("test", test)):
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
        if arr.dtype.kind not in "iuf":
            raise InputTypeError(
                f"{name} must be an array of real numbers (uint8 for 8-bit images), "
                f"got dtype {arr.dtype}"
            )
        if arr.size == 0:
            raise InputError(f"{name} must not be empty, got shape {arr.shape}")
        arrays.append(arr)
    ref, tst = arrays
    if ref.shape != tst.shape:
        raise InputError(
            f"reference and test must have the same shape, got {ref.shape} and {tst.shape}"
        )
    if ref.dtype != tst.dtype:
        raise InputTypeError(
            f"reference and test must have the same dtype, got {ref.dtype} and {tst.dtype} "
            "(convert one with .astype so that both use the same value range)"
        )
    if ref.dtype.kind == "f":
        for name, arr in (("reference", ref), ("test", tst)):
            if not np.isfinite(arr).all():
                raise InputError(f"{name} has NaN or infinite values; images must be finite")
    return ref, tst


# -- color ---------------------------------------------------------------------------------


def mse(reference: Any, test: Any) -> float:
    """Mean squared error between two images (or any two arrays) of one shape and dtype.

    The mean runs over every element, so for an H × W × 3 image it is the mean over all
    pixels and channels, in squared input units (squared 8-bit levels for uint8). Differences
    are taken and summed in float64, so uint8 inputs do not wrap around.

    Raises :class:`~pcdcodec.InputTypeError` for a non-numeric or boolean array or for two
    different dtypes, and :class:`~pcdcodec.InputError` for different shapes, empty arrays or
    NaN/infinite values.
    """
    ref, tst = _image_pair(reference, test)
    return _mse(ref, tst)


def _mse(ref: npt.NDArray[Any], tst: npt.NDArray[Any]) -> float:
    diff: npt.NDArray[np.float64] = np.subtract(ref, tst, dtype=np.float64).ravel()
    return float(np.dot(diff, diff)) / diff.size


def psnr(reference: Any, test: Any, peak: float = 255.0) -> float:
    """Peak signal-to-noise ratio in dB: ``10 * log10(peak**2 / mse(reference, test))``.

    ``peak`` is the largest possible value (255 for uint8 images, 65535 for 16-bit, 1.0 for
    float images in [0, 1]). Works on any two arrays of one shape and dtype (H × W, H × W × 3,
    ...); the MSE is averaged over all elements (channels included) in float64. Returns
    ``math.inf`` for identical inputs.

    Raises :class:`~pcdcodec.InputTypeError` for a non-numeric or boolean array, two different
    dtypes or a non-numeric ``peak``, and :class:`~pcdcodec.InputError` for different shapes,
    empty arrays, NaN/infinite values or a ``peak`` that is not positive and finite.
    """
    p = check_real(peak, "peak", minimum=0.0, inclusive=False, unit="the largest pixel value")
    ref, tst = _image_pair(reference, test)
    err = _mse(ref, tst)
    if err == 0.0:
        return math.inf
    return 10.0 * math.log10(p * p / err)


def _gaussian_window() -> npt.NDArray[np.float64]:
    """The 1-D factor of the 11 × 11, sigma 1.5 Gaussian window; it sums to 1."""
    half = _SSIM_WINDOW // 2
    offsets = np.arange(-half, half + 1, dtype=np.float64)
    g = np.exp(-(offsets**2) / (2.0 * _SSIM_SIGMA**2))
    out: npt.NDArray[np.float64] = g / g.sum()
    return out


def ssim(reference: Any, test: Any) -> float:
    """Mean structural similarity (SSIM, Wang et al. 2004) of two 8-bit images; 1.0 if equal.

    ``reference`` and ``test`` are uint8 arrays of one shape, H × W (gray) or H × W × C (RGB:
    C = 3), with H and W at least 11. What is computed, exactly:

    * Each channel is treated on its own, as is: RGB is *not* converted to luma (Y). For each
      channel, with ``x`` the reference and ``y`` the test channel as float64, and ``w`` the
      11 × 11 Gaussian window with sigma 1.5 normalised to sum 1 (``*`` = weighted mean over
      the window)::

          mu_x = w * x            sigma_x² = w * x² - mu_x²       sigma_xy = w * (x y) - mu_x mu_y
          SSIM map = ((2 mu_x mu_y + C1) (2 sigma_xy + C2))
                     / ((mu_x² + mu_y² + C1) (sigma_x² + sigma_y² + C2))

      with ``C1 = (0.01 L)²``, ``C2 = (0.03 L)²`` and ``L = 255``.
    * The map is evaluated only where the window fits entirely inside the image (the 'valid'
      region: (H - 10) × (W - 10) positions), so no border handling enters the result; the
      channel's SSIM is the mean of its map.
    * The result is the plain mean of the per-channel SSIMs. No down-sampling is applied (the
      original ``ssim_index.m`` of the authors does none either).

    The result lies in [-1, 1]; it is symmetric in its two arguments. The window filtering uses
    OpenCV's separable filter on float64 data, about ten times faster than numpy here.

    Raises :class:`~pcdcodec.InputTypeError` when an image is not uint8, and
    :class:`~pcdcodec.InputError` for shapes that differ, are not 2-D or 3-D, or are smaller
    than 11 × 11.
    """
    arrays = []
    for name, value in (("reference", reference), ("test", test)):
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
        if arr.dtype != np.uint8:
            raise InputTypeError(
                f"{name} must be uint8 (SSIM is computed with L = 255), got {arr.dtype}"
            )
        if arr.ndim not in (2, 3):
            raise InputError(f"{name} must be H × W or H × W × C (e.g. RGB), got shape {arr.shape}")
        arrays.append(arr)
    ref, tst = arrays
    if ref.shape != tst.shape:
        raise InputError(
            f"reference and test must have the same shape, got {ref.shape} and {tst.shape}"
        )
    h, w = ref.shape[:2]
    if h < _SSIM_WINDOW or w < _SSIM_WINDOW or (ref.ndim == 3 and ref.shape[2] == 0):
        raise InputError(
            f"SSIM needs images of at least {_SSIM_WINDOW} × {_SSIM_WINDOW} pixels (its window) "
            f"with at least one channel, got shape {ref.shape}"
        )
    if ref.ndim == 2:
        ref, tst = ref[:, :, None], tst[:, :, None]
    channels = int(ref.shape[2])
    return sum(_ssim_channel(ref[:, :, c], tst[:, :, c]) for c in range(channels)) / channels


def _ssim_channel(x8: npt.NDArray[np.uint8], y8: npt.NDArray[np.uint8]) -> float:
    import cv2

    g = _gaussian_window()
    h, w = x8.shape
    half = _SSIM_WINDOW // 2

    def window_mean(a: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        # The border mode only affects positions that the 'valid' crop throws away.
        out = cv2.sepFilter2D(a, cv2.CV_64F, g, g, borderType=cv2.BORDER_REFLECT_101)
        valid = np.asarray(out, dtype=np.float64)[half : h - half, half : w - half]
        return valid

    x = x8.astype(np.float64)
    y = y8.astype(np.float64)
    mu_x = window_mean(x)
    mu_y = window_mean(y)
    e_xx = window_mean(x * x)
    e_yy = window_mean(y * y)
    e_xy = window_mean(np.multiply(x, y, out=x))
    c1 = (_SSIM_K1 * _SSIM_L) ** 2
    c2 = (_SSIM_K2 * _SSIM_L) ** 2
    # In-place arithmetic: fresh image-sized temporaries cost more than the math here.
    num = mu_x * mu_y
    e_xy -= num  # sigma_xy
    e_xy *= 2.0
    e_xy += c2
    num *= 2.0
    num += c1
    num *= e_xy  # (2 mu_x mu_y + C1)(2 sigma_xy + C2)
    np.square(mu_x, out=mu_x)
    np.square(mu_y, out=mu_y)
    e_xx -= mu_x  # sigma_x²
    e_yy -= mu_y  # sigma_y²
    e_xx += e_yy
    e_xx += c2
    mu_x += mu_y
    mu_x += c1
    mu_x *= e_xx  # (mu_x² + mu_y² + C1)(sigma_x² + sigma_y² + C2)
    num /= mu_x
    return float(num.mean())


# -- depth ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class DepthError:
    """How a decoded depth image differs from its reference; returned by :func:`depth_error`.

    A pixel is *valid* when it holds a depth (uint16: not 0; float32: not NaN and not 0) and a
    *hole* otherwise. Errors are ``|test - reference|`` in the units of the input arrays
    (depth units for uint16, normally metres for float32); the ``*_m`` properties give them in
    metres when ``depth_scale`` is known. Statistics over an empty set of pixels are NaN.
    """

    #: Pixels valid in the reference; every statistic below is about these pixels.
    valid_pixels: int
    #: Valid reference pixels that the test reproduces exactly (bit-exact value).
    exact_pixels: int
    #: ``exact_pixels / valid_pixels`` (1.0 for a lossless round trip).
    exact_fraction: float
    #: Valid reference pixels that are also valid in the test: the pixels the errors cover.
    #: The others are :attr:`holes_created` and count as not exact.
    compared_pixels: int
    #: Largest absolute error, input units.
    max_abs_error: float
    #: Root mean squared error, input units.
    rmse: float
    #: Mean absolute error, input units.
    mean_abs_error: float
    #: Valid reference pixels on a depth edge (see :func:`depth_error`).
    edge_pixels: int
    #: RMSE over the compared edge pixels, input units.
    edge_rmse: float
    #: Largest absolute error over the compared edge pixels, input units.
    edge_max_abs_error: float
    #: Valid reference pixels that are not edge pixels (``valid_pixels - edge_pixels``).
    interior_pixels: int
    #: RMSE over the compared interior pixels, input units.
    interior_rmse: float
    #: Largest absolute error over the compared interior pixels, input units.
    interior_max_abs_error: float
    #: Pixels valid in the reference and holes (0 or NaN) in the test.
    holes_created: int
    #: Pixels that are holes in the reference and valid in the test.
    holes_filled: int
    #: Depth units per metre used by the ``*_m`` properties, or ``None`` when unknown.
    depth_scale: float | None

    def _metres(self, value: float) -> float | None:
        return None if self.depth_scale is None else value / self.depth_scale

    @property
    def max_abs_error_m(self) -> float | None:
        """:attr:`max_abs_error` in metres, or ``None`` without a depth scale."""
        return self._metres(self.max_abs_error)

    @property
    def rmse_m(self) -> float | None:
        """:attr:`rmse` in metres, or ``None`` without a depth scale."""
        return self._metres(self.rmse)

    @property
    def mean_abs_error_m(self) -> float | None:
        """:attr:`mean_abs_error` in metres, or ``None`` without a depth scale."""
        return self._metres(self.mean_abs_error)

    @property
    def edge_rmse_m(self) -> float | None:
        """:attr:`edge_rmse` in metres, or ``None`` without a depth scale."""
        return self._metres(self.edge_rmse)

    @property
    def edge_max_abs_error_m(self) -> float | None:
        """:attr:`edge_max_abs_error` in metres, or ``None`` without a depth scale."""
        return self._metres(self.edge_max_abs_error)

    @property
    def interior_rmse_m(self) -> float | None:
        """:attr:`interior_rmse` in metres, or ``None`` without a depth scale."""
        return self._metres(self.interior_rmse)

    @property
    def interior_max_abs_error_m(self) -> float | None:
        """:attr:`interior_max_abs_error` in metres, or ``None`` without a depth scale."""
        return self._metres(self.interior_max_abs_error)


def depth_error(
    reference: Any,
    test: Any,
    *,
    depth_scale: float | None = None,
    edge_threshold: float = 0.05,
) -> DepthError:
    """Compare a (decoded) depth image with its reference, pixel by pixel.

    ``reference`` and ``test`` are H × W arrays of one dtype: uint16 depth units with 0 for
    no depth, or float32 (normally metres) with NaN, or 0, for no depth. Errors are reported
    in those units; with ``depth_scale`` (depth units per metre, e.g. 5000 for TUM, 1000 for
    millimetres) the result's ``*_m`` properties also give them in metres. For float32 input
    without ``depth_scale`` the values are taken to be metres (scale 1).

    Statistics run over the pixels valid in the reference (see :class:`DepthError`): the
    count and fraction of exact pixels, and max, RMSE and mean of the absolute error over
    those that the test also holds (the rest are counted as :attr:`DepthError.holes_created`).
    Pixels that are holes in the reference but not in the test are
    :attr:`DepthError.holes_filled`.

    **Edges.** A valid reference pixel is an *edge pixel* when any of its 8 neighbours (3 × 3
    neighbourhood; pixels outside the image are ignored) is a hole, or differs from it by more
    than ``edge_threshold`` times the smaller of the two depths (a relative jump: the default
    0.05 is 5 cm at 1 m; being relative it needs no units and grows with distance, as sensor
    noise does). The relation is symmetric, so both sides of a discontinuity are edge pixels.
    Every other valid reference pixel is *interior*. Edges are found on the reference only,
    with whole-image shifted comparisons (no per-pixel loop). Codecs often fail differently
    at edges (ringing, smoothed jumps, lost silhouette pixels), hence the separate statistics.

    Raises :class:`~pcdcodec.InputTypeError` for a dtype other than uint16 or float32, two
    different dtypes, or a non-numeric option, and :class:`~pcdcodec.InputError` for arrays
    that are not 2-D, are empty or differ in shape, float32 depth that is negative or
    infinite, a ``depth_scale`` that is not positive and finite, or a negative
    ``edge_threshold``.
    """
    scale = (
        None
        if depth_scale is None
        else check_real(
            depth_scale, "depth_scale", minimum=0.0, inclusive=False, unit="units/metre"
        )
    )
    threshold = check_real(
        edge_threshold, "edge_threshold", minimum=0.0, inclusive=True, unit="relative jump"
    )
    ref = check_depth(reference, name="reference")
    tst = check_depth(test, name="test")
    if ref.dtype != tst.dtype:
        raise InputTypeError(
            f"reference and test must have the same dtype, got {ref.dtype.name} and "
            f"{tst.dtype.name}"
        )
    if ref.shape != tst.shape:
        raise InputError(
            f"reference and test must have the same shape, got {ref.shape} and {tst.shape}"
        )
    if ref.dtype.kind == "f":
        for name, arr in (("reference", ref), ("test", tst)):
            bad = np.isinf(arr) | (arr < 0)
            if bad.any():
                idx = np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)
                raise InputError(
                    f"{name} has {arr[idx].item()!r} at (row, col) "
                    f"{tuple(int(i) for i in idx)}; float depth must be >= 0 or NaN (no depth)"
                )
        if scale is None:
            scale = 1.0

    # NaN > 0 is False, so this is "not a hole" for both dtypes.
    ref_valid = ref > 0
    tst_valid = tst > 0
    both = ref_valid & tst_valid
    valid_pixels = int(np.count_nonzero(ref_valid))
    exact_pixels = int(np.count_nonzero(ref_valid & (ref == tst)))

    ref64 = ref.astype(np.float64)
    ref64[~ref_valid] = np.nan
    edge = _edge_mask(ref64, threshold)
    edge_pixels = int(np.count_nonzero(edge & ref_valid))

    abs_err = np.abs(tst[both].astype(np.float64) - ref64[both])
    on_edge = edge[both]
    rmse, max_err, mean_err = _error_stats(abs_err)
    edge_rmse, edge_max, _ = _error_stats(abs_err[on_edge])
    interior_rmse, interior_max, _ = _error_stats(abs_err[~on_edge])

    return DepthError(
        valid_pixels=valid_pixels,
        exact_pixels=exact_pixels,
        exact_fraction=exact_pixels / valid_pixels if valid_pixels else math.nan,
        compared_pixels=int(abs_err.size),
        max_abs_error=max_err,
        rmse=rmse,
        mean_abs_error=mean_err,
        edge_pixels=edge_pixels,
        edge_rmse=edge_rmse,
        edge_max_abs_error=edge_max,
        interior_pixels=valid_pixels - edge_pixels,
        interior_rmse=interior_rmse,
        interior_max_abs_error=interior_max,
        holes_created=int(np.count_nonzero(ref_valid & ~tst_valid)),
        holes_filled=int(np.count_nonzero(~ref_valid & tst_valid)),
        depth_scale=scale,
    )


# The four neighbour directions (right, down, down-right, down-left) as pairs of slices that
# put each pixel next to its neighbour; the edge relation is symmetric, so these cover all 8.
_NEIGHBOUR_PAIRS: tuple[tuple[tuple[slice, slice], tuple[slice, slice]], ...] = (
    ((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
    ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
    ((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None))),
    ((slice(None, -1), slice(1, None)), (slice(1, None), slice(None, -1))),
)


def _edge_mask(depth: npt.NDArray[np.float64], threshold: float) -> npt.NDArray[np.bool_]:
    """Pixels with a hole (NaN) or a relative jump above ``threshold`` among their 8 neighbours.

    Neighbours outside the image are simply absent. Holes themselves may be marked too;
    callers intersect the result with the valid pixels.
    """
    hole = np.isnan(depth)
    # 3 × 3 dilation of the holes, separably: along rows, then along columns.
    near_row = hole.copy()
    near_row[:, 1:] |= hole[:, :-1]
    near_row[:, :-1] |= hole[:, 1:]
    edge: npt.NDArray[np.bool_] = near_row.copy()
    edge[1:] |= near_row[:-1]
    edge[:-1] |= near_row[1:]
    # For positive a, b: |a - b| > t * min(a, b)  <=>  a > (1 + t) b  or  b > (1 + t) a.
    # Comparisons with NaN are False, so holes add nothing here (they were handled above).
    scaled = depth * (1.0 + threshold)
    for a, b in _NEIGHBOUR_PAIRS:
        jump = (depth[a] > scaled[b]) | (depth[b] > scaled[a])
        edge[a] |= jump
        edge[b] |= jump
    return edge


def _error_stats(abs_err: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    """(RMSE, max, mean) of absolute errors; NaN for none."""
    if abs_err.size == 0:
        return math.nan, math.nan, math.nan
    rmse = math.sqrt(float(np.dot(abs_err, abs_err)) / abs_err.size)
    return rmse, float(abs_err.max()), float(abs_err.mean())


# -- point clouds --------------------------------------------------------------------------


@dataclass(frozen=True)
class PointToPoint:
    """Point-to-point (D1) geometry distortion; returned by :func:`point_to_point`.

    Distances are in the units of the points (metres for pcdcodec's clouds). For each point
    of one cloud, its distance to the nearest point of the other cloud is taken; the two
    directions give two sets of distances.
    """

    #: Symmetric RMSE: the larger of the two one-directional RMSEs.
    rmse: float
    #: RMSE of the distances from each reference point to its nearest test point.
    rmse_reference_to_test: float
    #: RMSE of the distances from each test point to its nearest reference point.
    rmse_test_to_reference: float
    #: Symmetric Hausdorff distance: the largest nearest-neighbour distance, both directions.
    hausdorff: float
    #: Symmetric MSE, ``rmse ** 2`` (squared units), the MSE of :attr:`d1_psnr`.
    mse: float
    #: Peak value ``p`` used by :attr:`d1_psnr` (units of the points).
    peak: float
    #: ``10 * log10(peak**2 / mse)`` in dB; ``math.inf`` when ``mse`` is 0.
    d1_psnr: float
    #: Number of reference points.
    reference_points: int
    #: Number of test points.
    test_points: int


def point_to_point(
    reference_points: Any, test_points: Any, *, peak: float | None = None
) -> PointToPoint:
    """Point-to-point (D1) distortion between two point clouds, both ways.

    ``reference_points`` and ``test_points`` are N × 3 arrays (any real dtype; computed in
    float64), or Open3D point clouds (legacy ``open3d.geometry.PointCloud`` or tensor
    ``open3d.t.geometry.PointCloud``), in the same units (metres for pcdcodec's clouds). Only
    the positions count; colors and normals are ignored. The clouds may differ in size.

    Nearest neighbours come from Open3D's KD-tree through
    ``PointCloud.compute_point_cloud_distance`` (vectorised, multi-threaded C++). Measured
    interleaved on a 2-core machine with two ~218k-point clouds of a TUM frame, it took
    0.48 s against 0.69 s for ``open3d.core.nns`` knn search with k = 1 (both directions),
    and 2.0 s against 3.2 s for two different frames; a per-point ``KDTreeFlann`` loop in
    Python would take about 1.5 s on the first pair.

    The result holds the one-directional RMSEs, their maximum as the symmetric RMSE (as MPEG's
    ``pc_error`` takes the larger of the two directions), the symmetric Hausdorff distance,
    and ``d1_psnr = 10 * log10(p**2 / MSE)`` with MSE the symmetric mean squared distance
    (``rmse ** 2``) and ``p`` the peak: ``peak`` when given, else the diagonal of the
    reference's axis-aligned bounding box. MPEG evaluates voxelised clouds with ``p`` set by
    the voxel grid, so a D1 PSNR is comparable with another tool's only when both use the same
    ``p`` and definition.

    Raises :class:`~pcdcodec.InputTypeError` for an input that is neither a numeric array nor
    an Open3D point cloud, or a non-numeric ``peak``, and :class:`~pcdcodec.InputError` for an
    array that is not N × 3, an empty cloud, NaN or infinite coordinates, a ``peak`` that is
    not positive and finite, or (without ``peak``) a reference whose points all coincide.
    """
    import open3d as o3d

    p = (
        None
        if peak is None
        else check_real(peak, "peak", minimum=0.0, inclusive=False, unit="units of the points")
    )
    ref = _points(reference_points, "reference_points", o3d)
    tst = _points(test_points, "test_points", o3d)
    if p is None:
        p = float(np.linalg.norm(ref.max(axis=0) - ref.min(axis=0)))
        if p == 0.0:
            raise InputError(
                "the reference points all coincide, so their bounding-box diagonal (the default "
                "D1 PSNR peak) is 0; pass peak=... explicitly"
            )
    ref_pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(ref))
    tst_pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(tst))
    d_rt = np.asarray(ref_pc.compute_point_cloud_distance(tst_pc), dtype=np.float64)
    d_tr = np.asarray(tst_pc.compute_point_cloud_distance(ref_pc), dtype=np.float64)
    mse_rt = float(np.dot(d_rt, d_rt)) / d_rt.size
    mse_tr = float(np.dot(d_tr, d_tr)) / d_tr.size
    sym_mse = max(mse_rt, mse_tr)
    return PointToPoint(
        rmse=math.sqrt(sym_mse),
        rmse_reference_to_test=math.sqrt(mse_rt),
        rmse_test_to_reference=math.sqrt(mse_tr),
        hausdorff=max(float(d_rt.max()), float(d_tr.max())),
        mse=sym_mse,
        peak=p,
        d1_psnr=math.inf if sym_mse == 0.0 else 10.0 * math.log10(p * p / sym_mse),
        reference_points=int(ref.shape[0]),
        test_points=int(tst.shape[0]),
    )


def _points(value: Any, name: str, o3d: Any) -> npt.NDArray[np.float64]:
    """N × 3 finite float64 positions from an array or an Open3D point cloud."""
    if isinstance(value, o3d.geometry.PointCloud):
        arr: npt.NDArray[Any] = np.asarray(value.points)
    elif isinstance(value, o3d.t.geometry.PointCloud):
        if "positions" not in value.point:
            raise InputError(f"{name} is an Open3D tensor PointCloud without positions (empty)")
        arr = value.point.positions.cpu().numpy()
    else:
        try:
            arr = value if isinstance(value, np.ndarray) else np.asarray(value)
        except (TypeError, ValueError) as exc:
            raise InputTypeError(
                f"{name} must be an N × 3 array or an Open3D PointCloud, got {type(value).__name__}"
            ) from exc
        if arr.dtype.kind not in "iuf":
            raise InputTypeError(
                f"{name} must be an N × 3 array of numbers or an Open3D PointCloud, got "
                f"{type(value).__name__} of dtype {arr.dtype}"
            )
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (N, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        raise InputError(f"{name} must not be empty, got shape {arr.shape}")
    out = np.ascontiguousarray(arr, dtype=np.float64)
    finite = np.isfinite(out).all(axis=1)
    if not finite.all():
        first = int(np.flatnonzero(~finite)[0])
        raise InputError(
            f"{name} has {int((~finite).sum())} points with NaN or infinite coordinates "
            f"(first at index {first}); drop them with points[np.isfinite(points).all(axis=1)]"
        )
    return out
