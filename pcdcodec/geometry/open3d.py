"""Open3D RGBDImages to and from numpy arrays.

Open3D has two RGBDImages: the legacy ``open3d.geometry.RGBDImage``, whose depth is float32 metres
(``create_from_color_and_depth`` divides by its ``depth_scale``), and the tensor
``open3d.t.geometry.RGBDImage``, which keeps depth as it was given (uint16 depth units, or
float32). :func:`open3d_rgbd` makes either from a color and a depth array,
:func:`from_open3d_rgbd` gives the arrays back with the depth in depth units, and
:func:`split_rgbd` reads an image the way :class:`~pcdcodec.Projector` takes it.
:func:`open3d_rgbd_kind` tells the two apart without importing Open3D.

``import pcdcodec`` does not load this module: :class:`~pcdcodec.Frame`, the projector and the
recording writer load it when they are handed or asked for an Open3D image. Open3D itself is
imported only by :func:`open3d_rgbd`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import OPEN3D_DEPTH_SCALE, check_depth, check_depth_scale
from ..errors import InputError, InputTypeError

__all__ = [
    "OPEN3D_DEPTH_SCALE",
    "from_open3d_rgbd",
    "open3d_rgbd",
    "open3d_rgbd_kind",
    "split_rgbd",
    "tensor_point_cloud",
]


def open3d_rgbd(
    color: npt.NDArray[np.uint8] | None,
    depth: npt.NDArray[Any],
    depth_scale: float | None,
    *,
    tensor: bool = False,
) -> Any:
    """An Open3D RGBDImage from arrays (see :meth:`pcdcodec.Frame.to_open3d_rgbd`).

    Black color stands in where ``color`` is ``None``. Float32 depth is metres already; uint16
    depth needs ``depth_scale`` (depth units per metre) for the legacy image.
    """
    import open3d as o3d

    depth = np.ascontiguousarray(depth)
    rgb = np.ascontiguousarray(
        color if color is not None else np.zeros((*depth.shape, 3), np.uint8)
    )
    if tensor:
        t: Any = o3d.t.geometry
        core: Any = o3d.core
        return t.RGBDImage(t.Image(core.Tensor(rgb)), t.Image(core.Tensor(depth)))
    if depth.dtype == np.float32:
        scale = 1.0
    elif depth_scale is None:
        raise InputError(
            "uint16 depth needs depth_scale (depth units per metre) to become an Open3D RGBDImage"
        )
    else:
        scale = float(depth_scale)
    geometry: Any = o3d.geometry
    return geometry.RGBDImage.create_from_color_and_depth(
        geometry.Image(rgb),
        geometry.Image(depth),
        depth_scale=scale,
        depth_trunc=float(np.finfo(np.float32).max),
        convert_rgb_to_intensity=False,
    )


def tensor_point_cloud(
    positions: npt.NDArray[np.float32], colors: npt.NDArray[np.float32] | None = None
) -> Any:
    """An ``open3d.t.geometry.PointCloud`` on the CPU holding ``positions`` (and ``colors``)
    without a copy: ``Tensor.from_numpy`` shares their memory and keeps them alive."""
    import open3d as o3d

    pcd = o3d.t.geometry.PointCloud(o3d.core.Tensor.from_numpy(positions))
    if colors is not None:
        pcd.point.colors = o3d.core.Tensor.from_numpy(colors)
    return pcd


def open3d_rgbd_kind(obj: Any) -> str | None:
    """``"legacy"`` or ``"tensor"`` for an Open3D RGBDImage, else ``None`` (imports nothing)."""
    cls = type(obj)
    if cls.__name__ != "RGBDImage" or not cls.__module__.startswith("open3d"):
        return None
    return "tensor" if ".t." in cls.__module__ else "legacy"


def _arrays(rgbd: Any, kind: str) -> tuple[npt.NDArray[Any], npt.NDArray[Any]]:
    """An RGBDImage's color as it is stored and its checked 2-D depth (legacy: float32 metres),
    with single-channel images squeezed to 2-D."""
    if kind == "legacy":
        depth = check_depth(np.asarray(rgbd.depth), allowed=("float32",), name="RGBDImage depth")
        color = np.asarray(rgbd.color)
    else:
        raw = rgbd.depth.as_tensor().cpu().numpy()
        if raw.ndim == 3 and raw.shape[2] == 1:
            raw = raw[..., 0]
        depth = check_depth(raw, name="RGBDImage depth")
        color = rgbd.color.as_tensor().cpu().numpy()
    if color.ndim == 3 and color.shape[2] == 1:
        color = color[..., 0]
    return color, depth


def from_open3d_rgbd(
    rgbd: Any, *, depth_scale: float = OPEN3D_DEPTH_SCALE
) -> tuple[npt.NDArray[np.uint8] | None, npt.NDArray[Any]]:
    """``(color, depth)`` arrays of an Open3D RGBDImage, the depth back in depth units.

    ``depth_scale`` is the one the image was made with, in Open3D's sense (depth units per
    metre; Open3D's default, :data:`OPEN3D_DEPTH_SCALE`, is 1000):

    * a legacy ``open3d.geometry.RGBDImage`` holds float32 metres (``create_from_color_and_depth``
      divided the depth by ``depth_scale``); they are multiplied back and must come out as whole
      uint16 depth units, else :class:`~pcdcodec.InputError` says the scale does not fit;
    * a tensor ``open3d.t.geometry.RGBDImage`` holds the depth as it was given: uint16 depth
      units are returned unchanged, float32 depth is divided by ``depth_scale`` into metres
      (pass ``depth_scale=1.0`` for metres).

    Color must be 8-bit RGB (``convert_rgb_to_intensity=False`` for legacy images); an image
    without color gives ``None``.
    """
    scale = check_depth_scale(depth_scale)
    kind = open3d_rgbd_kind(rgbd)
    if kind is None:
        raise InputTypeError(
            f"expected an open3d.geometry.RGBDImage or open3d.t.geometry.RGBDImage, "
            f"got {type(rgbd).__name__}"
        )
    color, depth = _arrays(rgbd, kind)
    if kind == "legacy":
        units = depth.astype(np.float64) * scale
        units[~np.isfinite(units)] = 0.0
        rounded = np.rint(units)
        if float(rounded.max(initial=0.0)) > 65535 or not np.allclose(units, rounded, atol=1e-3):
            raise InputError(
                f"RGBDImage depth (metres) times depth_scale={scale:g} is not whole uint16 depth "
                "units: pass the depth_scale the image was made with (Open3D's default is 1000)"
            )
        depth = rounded.astype(np.uint16)
    elif depth.dtype == np.float32 and scale != 1.0:
        depth = (depth / np.float32(scale)).astype(np.float32)
    if color.size == 0:
        return None, depth
    if color.dtype != np.uint8 or color.ndim != 3 or color.shape[2] != 3:
        hint = ""
        if kind == "legacy" and color.ndim == 2:
            hint = "; make the RGBDImage with convert_rgb_to_intensity=False to keep RGB"
        raise InputTypeError(
            f"RGBDImage color must be H×W×3 uint8 RGB, got {color.dtype} with shape "
            f"{color.shape}{hint}"
        )
    if color.shape[:2] != depth.shape:
        raise InputError(
            f"RGBDImage color is {color.shape[1]}x{color.shape[0]} but its depth is "
            f"{depth.shape[1]}x{depth.shape[0]}"
        )
    return np.ascontiguousarray(color), depth


def split_rgbd(
    rgbd: Any, kind: str, depth_scale: float
) -> tuple[npt.NDArray[Any], float, npt.NDArray[np.uint8] | None]:
    """``(depth, its depth units per metre, color or None)`` of an RGBDImage of ``kind`` (see
    :func:`open3d_rgbd_kind`), as :class:`~pcdcodec.Projector` reads it.

    Legacy depth is metres (scale 1); tensor depth is raw depth units at ``depth_scale``. A
    float32 intensity image (``convert_rgb_to_intensity=True``) becomes gray RGB, the intensity
    rounded to 8 bits; other color must be H × W × 3 uint8, else
    :class:`~pcdcodec.InputTypeError`.
    """
    color, depth = _arrays(rgbd, kind)
    scale = 1.0 if kind == "legacy" else depth_scale
    if color.size == 0:
        return depth, scale, None
    if color.ndim == 2 and color.dtype.kind == "f":
        gray = np.rint(np.clip(color, 0.0, 1.0) * 255.0).astype(np.uint8)
        return depth, scale, np.repeat(gray[..., None], 3, axis=2)
    if color.dtype != np.uint8 or color.ndim != 3 or color.shape[2] != 3:
        raise InputTypeError(
            f"RGBDImage color must be uint8 RGB or float32 intensity, got {color.dtype} "
            f"with shape {color.shape}"
        )
    return depth, scale, color
