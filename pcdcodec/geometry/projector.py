"""Depth images to points and back, with a pinhole camera.

:class:`Projector` turns a depth image (and optionally an RGB image) into 3-D points in the
camera frame, the same points Open3D's ``create_from_rgbd_image`` makes, and turns points back
into a depth and a color image with :meth:`Projector.to_rgbd_arrays`.

The camera frame is Open3D's and OpenCV's: x to the right, y down, z forward, in metres. A pixel
``(u, v)`` (column, row) with depth ``d`` is the point::

    z = d / depth_scale,    x = (u - cx) * z / fx,    y = (v - cy) * z / fy

The per-pixel factors ``(u - cx) / fx`` and ``(v - cy) / fy`` are computed once per projector,
so a frame costs a few vectorised numpy passes. A camera with lens distortion gets the
undistorted factors of each pixel instead (see :meth:`CameraIntrinsics.rays`).

Depth and color may come from two cameras (RealSense, Azure Kinect): give the projector the
color camera's intrinsics and the rigid ``depth_to_color`` transform, and each point takes the
color of the pixel it projects to in the color image, distortion included.
:meth:`Projector.register_depth` makes depth registered to the color image. Open3D is imported
only by the methods that return or accept Open3D objects; RGBDImages are read by
:mod:`pcdcodec.geometry.open3d`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import check_color, check_depth, check_output_dtype, check_positive
from ..errors import InputError, InputTypeError
from .camera import CameraIntrinsics

# Served from here too, their home before: pcdcodec.geometry.projector.check_color_camera.
from .transform import MAX_BASELINE as MAX_BASELINE
from .transform import check_color_camera as check_color_camera

__all__ = ["Projector", "Reprojection"]

_F32_MAX = np.float32(np.finfo(np.float32).max)


@dataclass(frozen=True, eq=False)
class Reprojection:
    """What :meth:`Projector.to_rgbd_arrays` returns: two numpy images and the points left out.

    Unpacks as ``color, depth = projector.to_rgbd_arrays(points)``. ``color`` is an H × W × 3
    uint8 image (black where no point landed), or ``None`` when no colors were given; ``depth`` is
    H × W uint16 (depth units, 0 = no depth) or float32 (depth units, NaN = no depth).
    """

    color: npt.NDArray[np.uint8] | None
    depth: npt.NDArray[Any]
    #: Points with z <= 0 or a non-finite coordinate. In an organized cloud only z counts, and a
    #: NaN z is a pixel without depth, which is not counted.
    behind_camera: int = 0
    #: Points whose nearest pixel is outside the image.
    outside_image: int = 0
    #: Points farther than ``depth_trunc`` or whose depth does not fit the output dtype
    #: (uint16: rounds to 0 or to more than 65535 depth units).
    out_of_range: int = 0
    #: Points that landed on a pixel already taken by a nearer point (or, at equal depth, by an
    #: earlier one).
    hidden: int = 0

    def __iter__(self) -> Iterator[Any]:
        # Any, not ``NDArray | None``: type checkers cannot tell the two items apart, and
        # ``depth`` is never None. Use the attributes for precise types.
        yield self.color
        yield self.depth

    @property
    def dropped(self) -> int:
        """All points that are not in ``depth``: the sum of the four counts."""
        return self.behind_camera + self.outside_image + self.out_of_range + self.hidden

    def __repr__(self) -> str:
        color = "None" if self.color is None else "x".join(map(str, self.color.shape))
        h, w = self.depth.shape[:2]
        return (
            f"Reprojection(color={color}, depth={w}x{h} {self.depth.dtype}, "
            f"valid={int(np.count_nonzero(self.depth > 0))}, behind_camera={self.behind_camera}, "
            f"outside_image={self.outside_image}, out_of_range={self.out_of_range}, "
            f"hidden={self.hidden})"
        )


class Projector:
    """Back-projects depth images to points with fixed intrinsics, and projects points back.

    ``depth_scale`` is the number of depth units per metre (5000 for TUM, 1000 for millimetres,
    1.0 for float depth already in metres); it divides uint16 and float32 depth alike.
    ``depth_trunc`` (metres, optional) drops points farther than it and keeps depth equal to it
    (Open3D's ``depth_trunc`` and ``depth_max`` drop that too); ``None`` keeps all.

    A projector is safe to share between threads. It keeps per-pixel ray factors (8 bytes per
    pixel) and, per thread that uses it, scratch buffers of up to 80 bytes per pixel (25 MB at
    640 × 480: tensor clouds reuse arrays no cloud holds any more), not to page-fault anew.

    ``color_intrinsics`` and ``depth_to_color`` (keyword-only) describe a color camera apart
    from the depth camera: its intrinsics (with its own size and distortion) and the rigid 4 × 4
    transform taking points from the depth camera's frame into the color camera's frame
    (metres). Color images are then of the color camera's size, and each point takes the color
    of the color pixel nearest to its projection (black where it falls outside the color image
    or behind the color camera). Without them, color is registered to depth, pixel for pixel.

    Raises :class:`~pcdcodec.InputTypeError` when ``intrinsics`` is not a
    :class:`~pcdcodec.CameraIntrinsics` or a number is not a number, and
    :class:`~pcdcodec.InputError` when ``depth_scale`` is not positive and finite,
    ``depth_trunc`` is not positive, or ``depth_to_color`` is not a rigid transform, comes
    without ``color_intrinsics``, or moves the camera more than 5 m (not metres, likely).
    """

    __slots__ = (
        "_color",
        "_d2c",
        "_depth_scale",
        "_depth_trunc",
        "_f32_max",
        "_intrinsics",
        "_local",
        "_metres_u16",
        "_ray_ok",
        "_ray_x",
        "_ray_y",
        "_u16_lut",
        "_u16_max",
    )

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        depth_scale: float = 1000.0,
        depth_trunc: float | None = None,
        *,
        color_intrinsics: CameraIntrinsics | None = None,
        depth_to_color: Any = None,
    ) -> None:
        if not isinstance(intrinsics, CameraIntrinsics):
            raise InputTypeError(
                f"intrinsics must be a pcdcodec.CameraIntrinsics, got {type(intrinsics).__name__}"
                " (CameraIntrinsics.from_open3d converts an Open3D PinholeCameraIntrinsic)"
            )
        self._intrinsics = intrinsics
        self._color, self._d2c = check_color_camera(color_intrinsics, depth_to_color)
        self._depth_scale = check_positive(depth_scale, "depth_scale", finite=True)
        trunc = (
            None
            if depth_trunc is None
            else check_positive(depth_trunc, "depth_trunc", finite=False)
        )
        self._depth_trunc = None if trunc == math.inf else trunc
        h, w = intrinsics.shape
        self._ray_ok: npt.NDArray[np.bool_] | None = None
        if intrinsics.has_distortion:
            rx2, ry2 = intrinsics.rays()
            ok = np.isfinite(rx2) & np.isfinite(ry2)
            self._ray_x = np.where(ok, rx2, 0.0).astype(np.float32).reshape(-1)
            self._ray_y = np.where(ok, ry2, 0.0).astype(np.float32).reshape(-1)
            if not ok.all():
                self._ray_ok = ok.reshape(-1)
        else:
            rx = ((np.arange(w, dtype=np.float64) - intrinsics.cx) / intrinsics.fx).astype(
                np.float32
            )
            ry = ((np.arange(h, dtype=np.float64) - intrinsics.cy) / intrinsics.fy).astype(
                np.float32
            )
            # Flat H*W factors, so a gather by flat pixel index needs no index arithmetic.
            self._ray_x = np.tile(rx, h)
            self._ray_y = np.repeat(ry, w)
        # The largest float32 that is <= depth_trunc: comparing float32 metres with it in
        # float32 gives the same answer as comparing them with depth_trunc exactly.
        self._f32_max = _F32_MAX
        if self._depth_trunc is not None:
            t32 = np.float32(self._depth_trunc)
            if float(t32) > self._depth_trunc:
                t32 = np.nextafter(t32, np.float32(0))
            self._f32_max = t32
        # Metres for every uint16 value, and the largest value within depth_trunc.
        lut = (np.arange(65536, dtype=np.float64) / self._depth_scale).astype(np.float32)
        self._u16_max = int(np.searchsorted(lut, self._f32_max, side="right")) - 1
        lut[0] = np.nan
        lut[self._u16_max + 1 :] = np.nan
        self._u16_lut: npt.NDArray[np.float32] = lut
        self._metres_u16: npt.NDArray[np.float32] | None = None  # made on first use
        self._local = threading.local()

    # -- attributes --------------------------------------------------------------------

    @property
    def intrinsics(self) -> CameraIntrinsics:
        """The camera intrinsics (pixels)."""
        return self._intrinsics

    @property
    def depth_scale(self) -> float:
        """Depth units per metre."""
        return self._depth_scale

    @property
    def depth_trunc(self) -> float | None:
        """Points farther than this many metres are dropped; ``None`` keeps all."""
        return self._depth_trunc

    @property
    def color_intrinsics(self) -> CameraIntrinsics | None:
        """The color camera, or ``None`` when color is registered to depth."""
        return self._color

    @property
    def depth_to_color(self) -> npt.NDArray[np.float64] | None:
        """The rigid transform from the depth to the color camera frame (a copy), or ``None``."""
        return None if self._d2c is None else self._d2c.copy()

    @property
    def color_shape(self) -> tuple[int, int]:
        """``(height, width)`` of the color images this projector takes."""
        return (self._color or self._intrinsics).shape

    def __repr__(self) -> str:
        extra = ""
        if self._color is not None:
            extra = f", color_intrinsics={self._color!r}, depth_to_color=<4x4>"
        return (
            f"Projector({self._intrinsics!r}, depth_scale={self._depth_scale!r}, "
            f"depth_trunc={self._depth_trunc!r}{extra})"
        )

    def __reduce__(self) -> tuple[Any, ...]:
        # Scratch buffers and thread-locals are rebuilt, not pickled.
        if self._color is not None:
            return (
                _rebuild,
                (self._intrinsics, self._depth_scale, self._depth_trunc, self._color, self._d2c),
            )
        return (type(self), (self._intrinsics, self._depth_scale, self._depth_trunc))

    # -- depth to points ---------------------------------------------------------------

    def to_points(
        self, depth: Any, color: Any = None
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8] | None]:
        """Back-project the valid pixels of a depth image to points.

        ``depth`` is H × W uint16 or float32 in depth units (both divided by ``depth_scale``;
        float32 NaN means no depth) of the intrinsics size, or an Open3D ``RGBDImage`` (see
        :meth:`to_point_cloud`). ``color`` is an optional H × W × 3 uint8 RGB image of the same
        size. Any memory layout works (views, Fortran order, big-endian).

        Returns ``(points, colors)``: N × 3 float32 points in metres and N × 3 uint8 colors (or
        ``None`` without color) of the pixels whose depth is positive, finite and not beyond
        ``depth_trunc``, in row-major pixel order (the order of Open3D's legacy
        ``PointCloud.create_from_rgbd_image``).

        Raises :class:`~pcdcodec.InputTypeError` for a depth dtype other than uint16 or float32
        or a color that is not uint8, and :class:`~pcdcodec.InputError` for a depth that is not
        2-D, is empty or differs in size from the intrinsics, or a color of another size.
        """
        return self._points(*self._inputs(depth, color))

    def _points(self, depth2d: Any, scale: float, color3: Any) -> tuple[Any, Any]:
        idx, z = self._valid(depth2d, scale)
        points = np.empty((idx.size, 3), dtype=np.float32)
        self._fill_xyz(points, idx, z)
        if color3 is None:
            return points, None
        return points, self._point_colors(points, idx, color3, np.empty_like(points, np.uint8))

    def to_organized(self, depth: Any) -> npt.NDArray[np.float32]:
        """Back-project every pixel: an H × W × 3 float32 organized cloud in metres.

        ``depth`` is as for :meth:`to_points`. Pixels without valid depth (0, NaN, not positive,
        or beyond ``depth_trunc``) are ``(NaN, NaN, NaN)``. Raises as :meth:`to_points`.
        """
        depth2d, scale, _ = self._inputs(depth, None)
        flat = depth2d.reshape(-1)
        z = self._buf("metres", flat.shape, np.float32)
        if flat.dtype == np.uint16 and scale == self._depth_scale:
            # One table lookup: metres, NaN for 0 and beyond depth_trunc.
            _gather(self._u16_lut, flat, z)
        else:
            self._metres(flat, scale, z)
            bad = self._buf("mask", flat.shape, np.bool_)
            with np.errstate(invalid="ignore"):
                np.greater(z, 0, out=bad)
                bad &= z <= self._f32_max
            np.logical_not(bad, out=bad)
            z[bad] = np.nan
        if self._ray_ok is not None:
            z[~self._ray_ok] = np.nan
        out = np.empty((*depth2d.shape, 3), dtype=np.float32)
        rows = out.reshape(-1, 3)
        np.multiply(self._ray_x, z, out=rows[:, 0])
        np.multiply(self._ray_y, z, out=rows[:, 1])
        rows[:, 2] = z
        return out

    def to_point_cloud(self, depth: Any, color: Any = None, *, tensor: bool = False) -> Any:
        """Back-project a depth image to an Open3D point cloud (imports open3d).

        Same points, order and validity as :meth:`to_points`. Returns an
        ``open3d.geometry.PointCloud``, or with ``tensor=True`` an ``open3d.t.geometry.PointCloud``
        on the CPU. The legacy cloud has float64 points in metres, the float32 values of
        :meth:`to_points` widened (they differ from Open3D's double-precision ones by float32
        rounding only, at most 1.2e-7 relative), and float64 colors in [0, 1] equal to
        ``uint8 / 255``. The tensor cloud has float32 ``positions`` in metres and float32
        ``colors`` in [0, 1]. Colors are set only when there is a color image.

        ``depth`` may be an ``open3d.geometry.RGBDImage``; ``color`` must then be ``None``.
        Open3D keeps its depth as float32 metres, already divided by the depth scale given to
        ``create_from_color_and_depth`` and with depth at or beyond that call's ``depth_trunc``
        set to 0 (no depth). It is therefore used as metres (scale 1: this projector's
        ``depth_scale`` is not applied) and this projector's ``depth_trunc`` still applies on
        top. Its color is used when it is H × W × 3 uint8 RGB (``convert_rgb_to_intensity=False``);
        a float32 intensity image (``convert_rgb_to_intensity=True``, Open3D's default) gives
        gray colors, the intensity rounded to 8 bits. An ``open3d.t.geometry.RGBDImage`` is read
        the same way, except that its depth is raw depth units, scaled by ``depth_scale``.

        Raises as :meth:`to_points`.
        """
        depth2d, scale, color3 = self._inputs(depth, color)
        if tensor:
            from .open3d import tensor_point_cloud

            return tensor_point_cloud(*self._tensor_arrays(depth2d, scale, color3))
        import open3d as o3d

        idx, z = self._valid(depth2d, scale)
        n = idx.size

        # The float32 points of to_points, widened: computing in float32 and casting once is
        # faster than float64 arithmetic, and Vector3dVector copies fastest from C-contiguous
        # float64. Both live in scratch buffers; Open3D copies them into the cloud.
        points32 = self._buf("points32", (self._ray_x.size, 3), np.float32)[:n]
        self._fill_xyz(points32, idx, z)
        points64 = self._buf("points64", (self._ray_x.size, 3), np.float64)[:n]
        np.copyto(points64, points32)
        legacy = o3d.geometry.PointCloud()
        legacy.points = o3d.utility.Vector3dVector(points64)
        if color3 is not None:
            # Let Open3D size the color vector, then fill it in place: saves a copy.
            legacy.paint_uniform_color((0.0, 0.0, 0.0))
            rgb = self._point_colors(points32, idx, color3, self._rgb_buf()[:n])
            np.divide(rgb, 255.0, out=np.asarray(legacy.colors))
        return legacy

    # -- points to depth ---------------------------------------------------------------

    def to_rgbd_arrays(
        self, points: Any, colors: Any = None, dtype: Any = "uint16"
    ) -> Reprojection:
        """Project points (metres, camera frame) to a depth image and a color image.

        ``points`` is an organized H × W × 3 cloud of the intrinsics size, as made by
        :meth:`to_organized` (each pixel takes the z of its own point; x and y are not used; NaN
        z = no depth), or an unorganized N × 3 cloud; float32 or float64. Each unorganized point
        goes to its nearest pixel ``(u, v) = (round(x * fx / z + cx), round(y * fy / z + cy))``
        and each pixel keeps its nearest point. ``colors`` are optional uint8 RGB shaped like
        the points (H × W × 3 or N × 3).

        ``dtype`` is ``"uint16"`` (depth units ``round(z * depth_scale)``, 0 = no depth) or
        ``"float32"`` (``z * depth_scale``, NaN = no depth). For an organized cloud the round
        trip ``to_rgbd_arrays(to_organized(depth))`` gives ``depth`` back bit-exact, for uint16
        depth and for float32 depth with ``depth_scale`` 1.0, when no depth lies beyond
        ``depth_trunc``. The same holds for the points of :meth:`to_points` in any order.

        Returns a :class:`Reprojection` that unpacks as ``color, depth`` and counts the points
        left out: behind the camera (z <= 0 or non-finite), outside the image, out of range
        (beyond ``depth_trunc``, or not representable in ``dtype``) and hidden by a nearer point.
        For an organized cloud the colors are returned as given (a copy), and only z counts.

        Raises :class:`~pcdcodec.InputTypeError` for points that are not floating point or
        colors that are not uint8, and :class:`~pcdcodec.InputError` for an unknown ``dtype``,
        points that are neither H × W × 3 nor N × 3, or colors that do not match the points.
        """
        out_dtype = check_output_dtype(dtype)
        pts = points if isinstance(points, np.ndarray) else np.asarray(points)
        if pts.dtype.kind != "f":
            raise InputTypeError(f"points must be float32 or float64 (metres), got {pts.dtype}")
        h, w = self._intrinsics.shape
        if pts.ndim == 3 and pts.shape[2] == 3:
            if pts.shape[:2] != (h, w):
                raise InputError(
                    f"organized points size {pts.shape[1]}x{pts.shape[0]} differs from the "
                    f"intrinsics size {w}x{h} (width x height)"
                )
            color_img = None if colors is None else check_color(colors, (h, w), name="colors")
            return self._rgbd_organized(pts, color_img, out_dtype)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InputError(
                f"points must have shape (N, 3) or (height, width, 3) = ({h}, {w}, 3), "
                f"got {pts.shape}"
            )
        rows = None
        if colors is not None:
            rows = colors if isinstance(colors, np.ndarray) else np.asarray(colors)
            if rows.dtype != np.uint8:
                raise InputTypeError(f"colors must be uint8, got {rows.dtype}")
            if rows.shape != pts.shape:
                raise InputError(
                    f"colors must have the shape of the points {pts.shape}, got {rows.shape}"
                )
        return self._rgbd_unorganized(pts, rows, out_dtype)

    # -- two cameras -------------------------------------------------------------------

    def register_depth(
        self,
        depth: Any,
        *,
        dtype: Any = "uint16",
        footprint: bool = False,
        values: str = "color",
    ) -> npt.NDArray[Any]:
        """Depth registered to the color image: what the color camera would see as depth.

        Each valid depth pixel is back-projected, moved into the color camera's frame with
        ``depth_to_color`` and projected with the color camera's intrinsics and distortion; a
        color pixel keeps the nearest point that lands on it. The value is the point's ``z`` in
        the color camera's frame, in depth units (``dtype`` ``"uint16"``: rounded, 0 = none;
        ``"float32"``: NaN = none). With ``footprint=True`` each depth pixel covers the color
        pixels between the projections of its top-left and bottom-right corners, as
        librealsense's align does, which leaves no holes where the color image is finer than
        the depth image; the default puts each point on its nearest pixel only, as Open3D's
        ``PointCloud.project_to_depth_image`` does. ``values="depth"`` keeps each point's
        depth as the depth camera measured it (librealsense's choice) instead of its ``z`` in
        the color camera's frame; nearer still means smaller value.

        Without a color camera (registered input) this is the depth itself, converted to
        ``dtype``. Raises as :meth:`to_points`.
        """
        out_dtype = check_output_dtype(dtype)
        if values not in ("color", "depth"):
            raise InputError(f"values must be 'color' or 'depth', got {values!r}")
        depth2d, scale, _ = self._inputs(depth, None)
        if self._color is None or self._d2c is None:
            return self._rgbd_organized(self.to_organized(depth), None, out_dtype).depth
        idx, z = self._valid(depth2d, scale)
        color = self._color
        ch, cw = color.shape
        empty: Any = 65536 if out_dtype == np.uint16 else np.inf
        best = np.full(ch * cw, empty, dtype=np.int32 if out_dtype == np.uint16 else np.float32)
        if idx.size == 0:
            return self._finish_registered(best, empty, out_dtype)
        rot, trans = self._d2c[:3, :3], self._d2c[:3, 3]
        z64 = z.astype(np.float64)
        if not footprint:
            rx = self._ray_x[idx].astype(np.float64)
            ry = self._ray_y[idx].astype(np.float64)
            pts = np.stack([rx * z64, ry * z64, z64], axis=1) @ rot.T + trans
            u, v, front = color.project(pts)
            zz, fits = self._depth_values(pts[:, 2] if values == "color" else z64, out_dtype)
            with np.errstate(invalid="ignore"):
                ui = np.floor(u + 0.5)
                vi = np.floor(v + 0.5)
                ok = front & fits & (ui >= 0) & (ui < cw) & (vi >= 0) & (vi < ch)
            pixel = vi[ok].astype(np.intp) * cw + ui[ok].astype(np.intp)
            np.minimum.at(best, pixel, zz[ok].astype(best.dtype, copy=False))
            return self._finish_registered(best, empty, out_dtype)
        # Footprint: project the two corners of each depth pixel, fill the rectangle between.
        intr = self._intrinsics
        w = intr.width
        du = (idx % w).astype(np.float64)
        dv = (idx // w).astype(np.float64)
        corners = []
        for off in (-0.5, 0.5):
            x, y = intr.undistort((du + off - intr.cx) / intr.fx, (dv + off - intr.cy) / intr.fy)
            pts = np.stack([x * z64, y * z64, z64], axis=1) @ rot.T + trans
            u, v, front = color.project(pts)
            with np.errstate(invalid="ignore"):
                # Truncation toward zero, as librealsense casts: -0.4 still lands on pixel 0.
                corners.append((np.trunc(u + 0.5), np.trunc(v + 0.5), front))
        (u0, v0, f0), (u1, v1, f1) = corners
        centre = np.stack([self._ray_x[idx] * z64, self._ray_y[idx] * z64, z64], axis=1)
        zc = (centre @ rot.T + trans)[:, 2] if values == "color" else z64
        zz, fits = self._depth_values(zc, out_dtype)
        with np.errstate(invalid="ignore"):
            x0, x1 = np.minimum(u0, u1), np.maximum(u0, u1)
            y0, y1 = np.minimum(v0, v1), np.maximum(v0, v1)
            ok = f0 & f1 & fits & (x0 >= 0) & (y0 >= 0) & (x1 < cw) & (y1 < ch)
            # A footprint larger than 8 pixels is an edge between distant surfaces: skip it.
            ok &= (x1 - x0 < 8) & (y1 - y0 < 8)
        sel = np.flatnonzero(ok)
        x0i, x1i = x0[sel].astype(np.intp), x1[sel].astype(np.intp)
        y0i, y1i = y0[sel].astype(np.intp), y1[sel].astype(np.intp)
        vals = zz[sel].astype(best.dtype, copy=False)
        span_x = int((x1i - x0i).max(initial=0)) + 1
        span_y = int((y1i - y0i).max(initial=0)) + 1
        for dy in range(span_y):
            for dx in range(span_x):
                m = (x0i + dx <= x1i) & (y0i + dy <= y1i)
                pixel = (y0i[m] + dy) * cw + (x0i[m] + dx)
                np.minimum.at(best, pixel, vals[m])
        return self._finish_registered(best, empty, out_dtype)

    def color_for_depth(self, depth: Any, color: Any) -> npt.NDArray[np.uint8]:
        """An H × W × 3 color image aligned with the depth image: each depth pixel with valid
        depth takes the color its point has in :meth:`to_points`; other pixels are black.

        For registered input this is ``color`` itself (a copy). Raises as :meth:`to_points`.
        """
        depth2d, scale, color3 = self._inputs(depth, color)
        assert color3 is not None
        if self._color is None:
            return np.array(color3, dtype=np.uint8, copy=True)
        idx, z = self._valid(depth2d, scale)
        points = np.empty((idx.size, 3), dtype=np.float32)
        self._fill_xyz(points, idx, z)
        out = np.zeros((depth2d.size, 3), dtype=np.uint8)
        out[idx] = self._point_colors(points, idx, color3, np.empty((idx.size, 3), np.uint8))
        return out.reshape(*depth2d.shape, 3)

    def _point_colors(
        self,
        points: npt.NDArray[np.float32],
        idx: npt.NDArray[np.intp],
        color3: npt.NDArray[np.uint8],
        out: npt.NDArray[np.uint8],
    ) -> npt.NDArray[np.uint8]:
        """The colors of the points of the depth pixels ``idx`` (N × 3 in ``out``)."""
        if self._color is None or self._d2c is None:
            return _gather(color3.reshape(-1, 3), idx, out)
        color = self._color
        ch, cw = color.shape
        pts = points.astype(np.float64) @ self._d2c[:3, :3].T + self._d2c[:3, 3]
        u, v, front = color.project(pts)
        with np.errstate(invalid="ignore"):
            ui = np.floor(u + 0.5)
            vi = np.floor(v + 0.5)
            inside = front & (ui >= 0) & (ui < cw) & (vi >= 0) & (vi < ch)
        out[...] = 0
        pixel = vi[inside].astype(np.intp) * cw + ui[inside].astype(np.intp)
        out[inside] = color3.reshape(-1, 3)[pixel]
        return out

    def _finish_registered(
        self, best: npt.NDArray[Any], empty: Any, out_dtype: np.dtype[Any]
    ) -> npt.NDArray[Any]:
        ch, cw = self.color_shape
        filled = best != empty
        if out_dtype == np.uint16:
            return np.where(filled, best, 0).astype(np.uint16).reshape(ch, cw)
        best[~filled] = np.nan
        return best.reshape(ch, cw)

    # -- internals ---------------------------------------------------------------------

    def to_rgbd(self, points: Any, colors: Any = None, dtype: Any = "uint16") -> Reprojection:
        """Deprecated name of :meth:`to_rgbd_arrays` (numpy images, not an Open3D RGBDImage)."""
        import warnings

        warnings.warn(
            "Projector.to_rgbd is deprecated; use Projector.to_rgbd_arrays",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.to_rgbd_arrays(points, colors, dtype)

    def _buf(self, name: str, shape: tuple[int, ...], dtype: Any) -> npt.NDArray[Any]:
        """A per-thread scratch array, made on first use and reused afterwards."""
        bufs: dict[str, npt.NDArray[Any]] = self._local.__dict__
        buf = bufs.get(name)
        if buf is None:
            buf = bufs[name] = np.empty(shape, dtype=dtype)
        return buf

    def _rgb_buf(self) -> npt.NDArray[np.uint8]:
        return self._buf("rgb", (self._ray_x.size, 3), np.uint8)

    def _inputs(
        self, depth: Any, color: Any
    ) -> tuple[npt.NDArray[Any], float, npt.NDArray[np.uint8] | None]:
        """Validated (depth, its depth units per metre, color) from arrays or an RGBDImage."""
        scale = self._depth_scale
        kind = None
        if not isinstance(depth, np.ndarray):
            # Only a non-array can be an Open3D image: arrays never load the conversions.
            from .open3d import open3d_rgbd_kind, split_rgbd

            kind = open3d_rgbd_kind(depth)
            if kind is not None:
                if color is not None:
                    raise InputError(
                        "color must be None when depth is an RGBDImage (it has a color)"
                    )
                depth, scale, color = split_rgbd(depth, kind, scale)
        if kind is None:
            depth = check_depth(depth)
        h, w = self._intrinsics.shape
        if depth.shape != (h, w):
            raise InputError(
                f"depth size {depth.shape[1]}x{depth.shape[0]} differs from the intrinsics size "
                f"{w}x{h} (width x height)"
            )
        what = "the depth size" if self._color is None else "the color camera's size"
        color3 = None if color is None else check_color(color, self.color_shape, expected=what)
        return depth, scale, color3

    def _tensor_arrays(self, depth2d: Any, scale: float, color3: Any) -> tuple[Any, Any]:
        """The tensor cloud's float32 positions and colors (``uint8 / 255``, or ``None``)."""
        if depth2d.dtype == np.uint16 and scale == self._depth_scale and self._color is None:
            from ._cloud_kernels import cloud_arrays, metres_table  # one compiled pass

            if self._metres_u16 is None:
                self._metres_u16 = metres_table(self._u16_lut, scale)
            args = (self._u16_max, self._ray_ok, self._metres_u16, self._ray_x, self._ray_y)
            return cloud_arrays(depth2d, *args, color3, self._local.__dict__)
        positions, rgb = self._points(depth2d, scale, color3)
        colors = None if rgb is None else np.divide(rgb, np.float32(255), dtype=np.float32)
        return positions, colors

    def _metres(self, flat: npt.NDArray[Any], scale: float, out: npt.NDArray[np.float32]) -> None:
        """Write ``flat / scale`` into the float32 ``out``."""
        if scale == 1.0:
            np.copyto(out, flat, casting="unsafe")
        else:
            with np.errstate(over="ignore"):
                np.divide(flat, scale, out=out, dtype=np.float32, casting="unsafe")

    def _valid(
        self, depth2d: npt.NDArray[Any], scale: float
    ) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float32]]:
        """Flat indices of the valid pixels (row-major) and their depth in metres (scratch)."""
        flat = depth2d.reshape(-1)
        mask = self._buf("mask", flat.shape, np.bool_)
        z_buf = self._buf("z", flat.shape, np.float32)
        if flat.dtype == np.uint16 and scale == self._depth_scale:
            np.not_equal(flat, 0, out=mask)
            if self._u16_max < 65535:
                mask &= flat <= self._u16_max
            if self._ray_ok is not None:
                mask &= self._ray_ok
            idx = np.flatnonzero(mask)
            n = idx.size
            values = _gather(flat, idx, self._buf("u16", flat.shape, np.uint16)[:n])
            z = z_buf[:n]
            s32 = np.float32(scale)
            if float(s32) == scale:
                # float32 division rounds exactly like Open3D's float(d) / (double)scale.
                np.divide(values, s32, out=z)
            else:
                _gather(self._u16_lut, values, z)
            return idx, z
        if scale == 1.0 and flat.dtype == np.float32:
            metres = flat
        else:
            metres = self._buf("metres", flat.shape, np.float32)
            self._metres(flat, scale, metres)
        with np.errstate(invalid="ignore"):
            np.greater(metres, 0, out=mask)
            mask &= metres <= self._f32_max
        if self._ray_ok is not None:
            mask &= self._ray_ok
        idx = np.flatnonzero(mask)
        return idx, _gather(metres, idx, z_buf[: idx.size])

    def _fill_xyz(
        self, out: npt.NDArray[np.float32], idx: npt.NDArray[np.intp], z: npt.NDArray[np.float32]
    ) -> None:
        """Write x, y, z (metres) of the pixels ``idx`` with depth ``z`` into N × 3 ``out``."""
        tmp = self._buf("tmp", self._ray_x.shape, np.float32)[: idx.size]
        # Column by column into the interleaved output: fewer passes than building rows.
        _gather(self._ray_x, idx, tmp)
        np.multiply(tmp, z, out=out[:, 0])
        _gather(self._ray_y, idx, tmp)
        np.multiply(tmp, z, out=out[:, 1])
        out[:, 2] = z

    def _depth_values(
        self, z: npt.NDArray[np.float64], out_dtype: np.dtype[Any]
    ) -> tuple[npt.NDArray[Any], npt.NDArray[np.bool_]]:
        """Depth in output units for ``z`` metres, and where it is in range and representable."""
        trunc = math.inf if self._depth_trunc is None else self._depth_trunc
        with np.errstate(invalid="ignore", over="ignore"):
            scaled = z * self._depth_scale
            in_trunc = z <= trunc
            if out_dtype == np.uint16:
                units = np.rint(scaled)
                fits = in_trunc & (units >= 1) & (units <= 65535)
                return np.where(fits, units, 0).astype(np.uint16), fits
            depth = scaled.astype(np.float32)
            fits = in_trunc & (depth > 0) & (depth <= _F32_MAX)
            return depth, fits

    def _rgbd_organized(
        self,
        pts: npt.NDArray[Any],
        color_img: npt.NDArray[np.uint8] | None,
        out_dtype: np.dtype[Any],
    ) -> Reprojection:
        z = np.asarray(pts[..., 2], dtype=np.float64)
        with np.errstate(invalid="ignore"):
            front = (z > 0) & (z < math.inf)
        behind = int(np.count_nonzero(~front)) - int(np.count_nonzero(np.isnan(z)))
        depth, fits = self._depth_values(z, out_dtype)
        fits &= front
        depth[~fits] = 0 if out_dtype == np.uint16 else np.nan
        return Reprojection(
            None if color_img is None else color_img.copy(),
            depth,
            behind_camera=behind,
            out_of_range=int(np.count_nonzero(front)) - int(np.count_nonzero(fits)),
        )

    def _rgbd_unorganized(
        self,
        pts: npt.NDArray[Any],
        rows: npt.NDArray[np.uint8] | None,
        out_dtype: np.dtype[Any],
    ) -> Reprojection:
        intr = self._intrinsics
        h, w = intr.shape
        n_points = pts.shape[0]
        x, y, z = (np.asarray(pts[:, i], dtype=np.float64) for i in range(3))
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            front = np.isfinite(x) & np.isfinite(y) & (z > 0) & (z < math.inf)
            keep = np.flatnonzero(front)
            x, y, z = x[keep], y[keep], z[keep]
            if intr.has_distortion:
                xd, yd = intr.distort(x / z, y / z)
                u = np.floor(xd * intr.fx + (intr.cx + 0.5))
                v = np.floor(yd * intr.fy + (intr.cy + 0.5))
            else:
                u = np.floor(x * intr.fx / z + (intr.cx + 0.5))
                v = np.floor(y * intr.fy / z + (intr.cy + 0.5))
            inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        n_front = keep.size
        sel = np.flatnonzero(inside)
        keep, z = keep[sel], z[sel]
        pixel = v[sel].astype(np.intp) * w + u[sel].astype(np.intp)
        n_inside = keep.size
        values, fits = self._depth_values(z, out_dtype)
        sel = np.flatnonzero(fits)
        keep, pixel, values = keep[sel], pixel[sel], values[sel]
        n_fits = keep.size

        # Nearest point per pixel: an unbuffered minimum per pixel, no sort needed.
        if out_dtype == np.uint16:
            empty: Any = 65536
            best = np.full(h * w, empty, dtype=np.int32)
        else:
            empty = np.inf
            best = np.full(h * w, empty, dtype=np.float32)
        # Same dtypes on both sides keep ufunc.at on its fast path.
        np.minimum.at(best, pixel, values.astype(best.dtype, copy=False))
        filled = best != empty
        n_filled = int(np.count_nonzero(filled))
        depth: npt.NDArray[Any]
        if out_dtype == np.uint16:
            depth = np.where(filled, best, 0).astype(np.uint16)
        else:
            depth = best
            depth[~filled] = np.nan

        color = None
        if rows is not None:
            won = np.flatnonzero(values == best[pixel])
            if won.size > n_filled:
                # Several points at the same nearest depth: the first one given wins.
                first = np.full(h * w, n_fits, dtype=np.intp)
                np.minimum.at(first, pixel[won], won)
                won = first[first < n_fits]
            color_flat = np.zeros((h * w, 3), dtype=np.uint8)
            picked = np.take(rows, keep[won], axis=0)
            # Move whole 3-byte pixels: far faster than fancy-indexing (N, 3) rows.
            color_flat.view("V3")[pixel[won], 0] = picked.view("V3")[:, 0]
            color = color_flat.reshape(h, w, 3)
        return Reprojection(
            color,
            depth.reshape(h, w),
            behind_camera=n_points - n_front,
            outside_image=n_front - n_inside,
            out_of_range=n_inside - n_fits,
            hidden=n_fits - n_filled,
        )


def _rebuild(*args: Any) -> Projector:
    intrinsics, depth_scale, depth_trunc, color, d2c = args
    return Projector(
        intrinsics, depth_scale, depth_trunc, color_intrinsics=color, depth_to_color=d2c
    )


def _gather(
    table: npt.NDArray[Any], idx: npt.NDArray[Any], out: npt.NDArray[Any]
) -> npt.NDArray[Any]:
    """``out[i] = table[idx[i]]`` (rows when ``table`` is 2-D) for indices known to be valid.

    ``mode="clip"`` matters: with the default ``"raise"``, ``np.take`` fills a temporary and
    copies it into ``out``, which makes the gather about three times slower.
    """
    return np.take(table, idx, axis=0, out=out, mode="clip")
