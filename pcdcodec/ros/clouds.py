"""Organized ``sensor_msgs/PointCloud2`` clouds, both ways: a cloud's layout read from its
fields, its points as depth (z) and color, a pinhole camera fitted to it, the depth units its z
values are whole steps of, and the PCL XYZRGB layout clouds are written in.

A cloud is read by field name, offset and datatype, never by position, and checked against its
data before any array is built from it; every function takes the topic name for its errors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import Projector

__all__ = [
    "CLOUD_DTYPE",
    "CloudLayout",
    "DepthUnits",
    "LayoutCache",
    "cloud_array",
    "cloud_layout",
    "cloud_points",
    "cloud_to_rgbd",
    "find_units",
    "fit_intrinsics",
]

# sensor_msgs/PointField datatype names, for errors
_FIELD_NAMES = {1: "INT8", 2: "UINT8", 3: "INT16", 4: "UINT16", 5: "INT32", 6: "UINT32"}
_FIELD_NAMES.update({7: "FLOAT32", 8: "FLOAT64"})
#: the PointCloud2 fields read: each may appear once, with one value per point
_CLOUD_FIELDS = ("x", "y", "z", "rgb", "rgba")


@dataclass(frozen=True)
class CloudLayout:
    """Where x, y, z and the color sit in each point of an organized PointCloud2."""

    width: int
    height: int
    point_step: int
    row_step: int
    dtype: np.dtype[Any]  # structured: x, y, z and optionally rgb (uint32)
    color: str | None  # "rgb" or "rgba" (the field name) or None


def cloud_layout(msg: Any, topic: str) -> CloudLayout:
    """Read a PointCloud2's fields by name, offset and datatype (never by position)."""
    h, w = int(msg.height), int(msg.width)
    if h <= 1:
        raise InputError(
            f"cloud topic {topic!r} is not organized (height {h}, width {w}); pcdcodec needs "
            "an organized cloud, one point per pixel"
        )
    order = ">" if msg.is_bigendian else "<"
    fields: dict[str, Any] = {}
    for f in msg.fields:
        name = str(f.name)
        if name in _CLOUD_FIELDS and name in fields:
            # PCL reads the first, other readers the last: neither is safe to guess.
            raise InputError(
                f"cloud topic {topic!r} has the field {name!r} twice (byte offsets "
                f"{int(fields[name].offset)} and {int(f.offset)}); expected each of "
                f"{', '.join(_CLOUD_FIELDS)} at most once"
            )
        fields[name] = f
    if "rgb" in fields and "rgba" in fields:
        raise InputError(
            f"cloud topic {topic!r} has both an 'rgb' and an 'rgba' field; expected one color field"
        )
    for name in _CLOUD_FIELDS:
        if name in fields and int(fields[name].count) != 1:
            raise InputError(
                f"cloud topic {topic!r}: field {name!r} has count {int(fields[name].count)}, "
                "expected 1 (one value per point)"
            )
    names: list[str] = []
    formats: list[str] = []
    offsets: list[int] = []
    for axis in ("x", "y", "z"):
        f = fields.get(axis)
        if f is None:
            raise InputError(
                f"cloud topic {topic!r} has no {axis!r} field (fields: {sorted(fields)})"
            )
        if int(f.datatype) != 7:
            raise InputError(
                f"cloud topic {topic!r}: field {axis!r} is "
                f"{_FIELD_NAMES.get(int(f.datatype), int(f.datatype))}, expected FLOAT32"
            )
        names.append(axis)
        formats.append(order + "f4")
        offsets.append(int(f.offset))
    color = next((n for n in ("rgb", "rgba") if n in fields), None)
    if color is not None:
        f = fields[color]
        if int(f.datatype) not in (5, 6, 7):
            raise InputError(
                f"cloud topic {topic!r}: field {color!r} is "
                f"{_FIELD_NAMES.get(int(f.datatype), int(f.datatype))}, expected FLOAT32 or "
                "UINT32 packed color"
            )
        names.append("rgb")
        formats.append(order + "u4")  # the float's bits are the packed color
        offsets.append(int(f.offset))
    step, row = int(msg.point_step), int(msg.row_step)
    size = len(msg.data)
    # The steps against the data before any dtype is built from them (numpy's item size is a
    # C int): a damaged point_step or row_step is an error, whatever its size.
    if row < w * step:
        raise InputError(
            f"cloud topic {topic!r}: row_step {row} is shorter than width {w} x point_step {step}"
        )
    if row * h > size:
        raise DecodeError(
            f"cloud topic {topic!r}: data is {size} bytes, expected row_step {row} x height {h} "
            f"= {row * h}"
        )
    for n, o in zip(names, offsets, strict=True):
        if o + 4 > step:
            raise InputError(
                f"cloud topic {topic!r}: field {n!r} at byte offset {o} runs past point_step {step}"
            )
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    return CloudLayout(w, h, step, row, dtype, color)


class LayoutCache:
    """Layouts of the clouds of one topic, read from each message itself and kept by its whole
    description (fields, steps, byte order, size), so a cloud that changes any of them gets its
    own; at most a few are kept."""

    def __init__(self) -> None:
        self._layouts: dict[Any, CloudLayout] = {}

    def get(self, msg: Any, topic: str) -> CloudLayout:
        """The layout of the cloud ``msg`` (:func:`cloud_layout`)."""
        key = (
            tuple((str(f.name), int(f.offset), int(f.datatype), int(f.count)) for f in msg.fields),
            int(msg.point_step),
            int(msg.row_step),
            bool(msg.is_bigendian),
            int(msg.width),
            int(msg.height),
        )
        layout = self._layouts.get(key)
        if layout is None:
            layout = cloud_layout(msg, topic)
            if len(self._layouts) >= 8:
                self._layouts.clear()
            self._layouts[key] = layout
        return layout


def cloud_points(msg: Any, layout: CloudLayout, topic: str) -> npt.NDArray[Any]:
    """The cloud's points as an H×W structured array (a view where possible)."""
    data = msg.data if isinstance(msg.data, np.ndarray) else np.frombuffer(msg.data, np.uint8)
    h, w, step, row = layout.height, layout.width, layout.point_step, layout.row_step
    if row < w * step:
        raise InputError(
            f"cloud topic {topic!r}: row_step {row} is shorter than width {w} x point_step {step}"
        )
    if data.size < row * h:
        raise DecodeError(
            f"cloud topic {topic!r}: data is {data.size} bytes, expected row_step {row} x "
            f"height {h} = {row * h}"
        )
    rows = data[: row * h].reshape(h, row)[:, : w * step]
    if row != w * step:
        rows = np.ascontiguousarray(rows)
    return rows.reshape(-1).view(layout.dtype).reshape(h, w)


def cloud_to_rgbd(
    msg: Any, layout: CloudLayout, topic: str
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8] | None, npt.NDArray[Any]]:
    """An organized cloud as (z in float32 metres, RGB, the structured points).

    z is copied bit for bit; NaN (or non-finite) z stays NaN: a hole.
    """
    pts = cloud_points(msg, layout, topic)
    z = pts["z"].astype(np.float32)  # native byte order, same bits
    rgb = None
    if layout.color is not None:
        packed = pts["rgb"].astype(np.uint32)
        rgb = np.empty((layout.height, layout.width, 3), np.uint8)
        rgb[..., 0] = packed >> 16
        rgb[..., 1] = packed >> 8
        rgb[..., 2] = packed
    return z, rgb, pts


def fit_intrinsics(pts: npt.NDArray[Any], topic: str) -> tuple[Any, float]:
    """Fit fx, cx from x/z against u and fy, cy from y/z against v on an organized cloud.

    Returns the intrinsics and the fit residual: the largest distance, in pixels, between a
    valid point's pixel and where the fitted camera projects it.
    """
    h, w = pts.shape
    x = pts["x"].astype(np.float64)
    y = pts["y"].astype(np.float64)
    z = pts["z"].astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        valid = np.isfinite(x) & np.isfinite(y) & np.isfinite(z) & (z > 0)
    v, u = np.nonzero(valid)
    if u.size < 2 or np.ptp(u) == 0 or np.ptp(v) == 0:
        raise InputError(
            f"cloud topic {topic!r}: too few valid points ({u.size}) to fit intrinsics; pass "
            "intrinsics or an info topic"
        )
    a = x[valid] / z[valid]
    b = y[valid] / z[valid]
    # u = fx * a + cx, v = fy * b + cy
    fx, cx = np.polyfit(a, u.astype(np.float64), 1)
    fy, cy = np.polyfit(b, v.astype(np.float64), 1)
    residual = float(
        max(np.abs(fx * a + cx - u).max(initial=0.0), np.abs(fy * b + cy - v).max(initial=0.0))
    )
    try:
        intr = CameraIntrinsics(w, h, float(fx), float(fy), float(cx), float(cy))
    except InputError as exc:
        raise InputError(
            f"cloud topic {topic!r}: the fitted camera is not valid ({exc}); the cloud may not "
            "come from a pinhole camera: pass intrinsics or an info topic"
        ) from None
    return intr, residual


class DepthUnits:
    """Depth units of ``1/scale`` m for ``width`` × ``height`` clouds: :meth:`of` gives a cloud's
    z as uint16 units when they rebuild every z bit for bit (through the projector a recording
    of them reads back with), else ``None``."""

    def __init__(self, width: int, height: int, scale: float) -> None:
        self.scale = scale
        self.projector = Projector(
            CameraIntrinsics(width, height, 1.0, 1.0, width / 2, height / 2), depth_scale=scale
        )

    def of(self, z: npt.NDArray[np.float32]) -> npt.NDArray[np.uint16] | None:
        """``z`` as uint16 units when they give back every z bit for bit, else ``None``."""
        with np.errstate(invalid="ignore", over="ignore"):
            scaled = np.rint(z.astype(np.float64) * self.scale)
            finite = np.isfinite(z)
            if not ((scaled[finite] >= 1) & (scaled[finite] <= 65535)).all():
                return None
        units = np.where(finite, scaled, 0).astype(np.uint16)
        back = self.projector.to_organized(units)[..., 2]
        same = (back.view(np.uint32) == z.view(np.uint32)) | (~finite & np.isnan(back))
        return units if bool(same.all()) else None


def find_units(z: npt.NDArray[np.float32]) -> DepthUnits | None:
    """The depth units (millimetres, then 1/5000, 1/4000 and 1/10000 m) the cloud's z values
    are whole steps of, or ``None``. Drivers compute z from integer depth: such clouds are
    stored as uint16 units, which rebuild every z bit for bit and encode several times faster
    than float32."""
    h, w = z.shape
    for scale in (1000.0, 5000.0, 4000.0, 10000.0):
        units = DepthUnits(w, h, scale)
        if units.of(z) is not None:
            return units
    return None


#: The point layout of the clouds written: PCL's PointXYZRGB, 32 bytes per point.
CLOUD_DTYPE = np.dtype(
    {"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
     "offsets": [0, 4, 8, 16], "itemsize": 32}
)  # fmt: skip


def cloud_array(
    projector: Any, depth: npt.NDArray[Any], color: npt.NDArray[np.uint8] | None
) -> npt.NDArray[Any]:
    """An organized H×W array of :data:`CLOUD_DTYPE` points from depth and color.

    x, y, z come from ``projector.to_organized`` (NaN where there is no depth); ``rgb`` packs the
    color as ``r << 16 | g << 8 | b`` for every pixel, holes included.
    """
    xyz = projector.to_organized(depth)
    h, w = depth.shape
    pts = np.zeros((h, w), CLOUD_DTYPE)
    pts["x"] = xyz[..., 0]
    pts["y"] = xyz[..., 1]
    pts["z"] = xyz[..., 2]
    if color is not None:
        c = color.astype(np.uint32)
        pts["rgb"] = (c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]
    return pts
