"""One RGB-D frame, the same object from sources, recordings and evaluation.

A :class:`Frame` holds a color image (H×W×3 uint8 RGB, or ``None`` for depth only), a depth
image (H×W uint16 depth units or float32 metres), its time ``timestamp_ns`` (nanoseconds), and
optionally its position in a sequence (``index``) and the camera pose (``pose``, 4×4 float64
camera-to-world). Frames read from a recording also carry the recording's
:class:`~pcdcodec.Projector`, so they turn into points and Open3D objects directly; frames from
elsewhere take a projector as an argument.

Frames compare equal when their arrays, timestamps and poses are equal (``index`` and the
projector are where the frame came from, not what it holds), and any frame can be handed to
:meth:`pcdcodec.RecordingWriter.write_frames`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ._validate import check_depth_scale
from .errors import InputError, InputTypeError

if TYPE_CHECKING:
    from .geometry.projector import Projector

__all__ = ["OPEN3D_DEPTH_SCALE", "Frame", "from_open3d_rgbd", "open3d_rgbd"]

#: The ``depth_scale`` Open3D assumes when none is given (depth units per metre, millimetres).
OPEN3D_DEPTH_SCALE = 1000.0


def _describe(array: Any) -> str:
    if array is None:
        return "None"
    shape = getattr(array, "shape", None)
    dtype = getattr(array, "dtype", None)
    if shape is None:
        return type(array).__name__
    return f"{'x'.join(str(s) for s in shape)} {dtype}"


def _same(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


@dataclass(eq=False)
class Frame:
    """One color/depth pair at one time.

    ``color`` is H×W×3 uint8 RGB (``None`` when depth only), ``depth`` H×W uint16 depth units
    or float32 metres, ``timestamp_ns`` nanoseconds, ``index`` the frame's position in its
    recording or sequence (``None`` when unknown), ``pose`` the 4×4 float64 camera-to-world
    transform (``None`` when unknown), and ``projector`` the camera that turns the depth into
    points (set on frames read from a recording).
    """

    color: npt.NDArray[np.uint8] | None
    depth: npt.NDArray[Any]
    timestamp_ns: int
    index: int | None = None
    pose: npt.NDArray[np.float64] | None = None
    projector: Projector | None = field(default=None, repr=False)

    # -- identity ---------------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Frame):
            return NotImplemented
        return (
            self.timestamp_ns == other.timestamp_ns
            and _same(self.depth, other.depth)
            and _same(self.color, other.color)
            and _same(self.pose, other.pose)
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays: not hashable

    def __repr__(self) -> str:
        parts = [] if self.index is None else [f"index={self.index}"]
        parts.append(f"timestamp_ns={self.timestamp_ns}")
        parts.append(f"color={_describe(self.color)}")
        parts.append(f"depth={_describe(self.depth)}")
        if self.pose is not None:
            t = np.asarray(self.pose)[:3, 3]
            parts.append(f"pose=at ({t[0]:.3f}, {t[1]:.3f}, {t[2]:.3f}) m")
        return f"Frame({', '.join(parts)})"

    @property
    def timestamp(self) -> int:
        """Deprecated name of :attr:`timestamp_ns`."""
        warnings.warn(
            "Frame.timestamp is deprecated; use Frame.timestamp_ns",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.timestamp_ns

    @property
    def seconds(self) -> float:
        """The timestamp in seconds."""
        return self.timestamp_ns / 1e9

    # -- projection -------------------------------------------------------------------

    def _projector(self, projector: Projector | None) -> Projector:
        chosen = projector if projector is not None else self.projector
        if chosen is None:
            raise InputError(
                "this frame has no camera: pass projector=pcdcodec.Projector(intrinsics, "
                "depth_scale) (frames read from a recording carry one)"
            )
        return chosen

    def to_points(
        self, projector: Projector | None = None
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8] | None]:
        """N×3 float32 points in metres (camera frame) and their N×3 uint8 colors.

        Uses the frame's own projector unless ``projector`` is given; raises
        :class:`~pcdcodec.InputError` when there is neither.
        """
        return self._projector(projector).to_points(self.depth, self.color)

    def to_point_cloud(self, tensor: bool = False, projector: Projector | None = None) -> Any:
        """The frame as an Open3D point cloud in the camera frame
        (``open3d.t.geometry.PointCloud`` if ``tensor``)."""
        return self._projector(projector).to_point_cloud(self.depth, self.color, tensor=tensor)

    def to_open3d_rgbd(self, tensor: bool = False, *, depth_scale: float | None = None) -> Any:
        """The frame as an Open3D RGBDImage.

        With a color camera apart from depth (a projector with ``color_intrinsics``), the
        image is the depth camera's and each depth pixel takes the color of its point
        (:meth:`Projector.color_for_depth`).

        Legacy (``tensor=False``): an ``open3d.geometry.RGBDImage`` with depth in float32
        metres and 8-bit RGB color, as ``create_from_color_and_depth(...,
        convert_rgb_to_intensity=False)`` makes it. Tensor (``tensor=True``): an
        ``open3d.t.geometry.RGBDImage`` holding the depth exactly as stored (uint16 depth
        units), to be used with ``depth_scale`` = the recording's depth scale in Open3D's
        tensor functions.

        ``depth_scale`` (depth units per metre) states the scale the frame's depth is at; it
        never rescales. A frame with a projector (one read from a recording) is at its
        projector's scale, the default: another value raises :class:`~pcdcodec.InputError`
        naming both, since a legacy image made with it would not be in metres. A frame without
        a projector needs it for the legacy image of uint16 depth.
        """
        scale = None if depth_scale is None else check_depth_scale(depth_scale)
        color = self.color
        if self.projector is not None:
            own = self.projector.depth_scale
            if scale is not None and scale != own:
                raise InputError(
                    f"depth_scale={scale:g} differs from this frame's depth scale, {own:g} depth "
                    f"units per metre (its camera's); depth is never rescaled silently: leave "
                    f"depth_scale out (a legacy RGBDImage holds metres whatever the scale), or "
                    f"convert the depth yourself"
                )
            scale = own
            if color is not None and self.projector.color_intrinsics is not None:
                # Two cameras: the image is the depth camera's, each pixel colored by its point.
                color = self.projector.color_for_depth(self.depth, color)
        return open3d_rgbd(color, self.depth, scale, tensor=tensor)

    def registered_depth(
        self, *, footprint: bool = False, projector: Projector | None = None
    ) -> npt.NDArray[Any]:
        """Depth registered to the color image, of the color camera's size, in the depth's
        dtype (see :meth:`Projector.register_depth`)."""
        dtype = "float32" if self.depth.dtype == np.float32 else "uint16"
        return self._projector(projector).register_depth(
            self.depth, dtype=dtype, footprint=footprint
        )

    @classmethod
    def from_open3d_rgbd(
        cls,
        rgbd: Any,
        *,
        depth_scale: float = OPEN3D_DEPTH_SCALE,
        timestamp_ns: int = 0,
        index: int | None = None,
        pose: npt.NDArray[np.float64] | None = None,
    ) -> Frame:
        """A frame from an Open3D RGBDImage, legacy or tensor (see :func:`from_open3d_rgbd`)."""
        color, depth = from_open3d_rgbd(rgbd, depth_scale=depth_scale)
        return cls(color, depth, timestamp_ns, index=index, pose=pose)

    def to_rgbd(self, tensor: bool = False) -> Any:
        """Deprecated name of :meth:`to_open3d_rgbd`."""
        warnings.warn(
            "Frame.to_rgbd is deprecated; use Frame.to_open3d_rgbd",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.to_open3d_rgbd(tensor=tensor)


def open3d_rgbd(
    color: npt.NDArray[np.uint8] | None,
    depth: npt.NDArray[Any],
    depth_scale: float | None,
    *,
    tensor: bool = False,
) -> Any:
    """An Open3D RGBDImage from arrays (see :meth:`Frame.to_open3d_rgbd`).

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


def open3d_rgbd_kind(obj: Any) -> str | None:
    """``"legacy"`` or ``"tensor"`` for an Open3D RGBDImage, else ``None`` (imports nothing)."""
    cls = type(obj)
    if cls.__name__ != "RGBDImage" or not cls.__module__.startswith("open3d"):
        return None
    return "tensor" if ".t." in cls.__module__ else "legacy"


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
    from ._validate import check_depth

    scale = check_depth_scale(depth_scale)
    kind = open3d_rgbd_kind(rgbd)
    if kind is None:
        raise InputTypeError(
            f"expected an open3d.geometry.RGBDImage or open3d.t.geometry.RGBDImage, "
            f"got {type(rgbd).__name__}"
        )
    if kind == "legacy":
        color = np.asarray(rgbd.color)
        metres = check_depth(np.asarray(rgbd.depth), allowed=("float32",), name="RGBDImage depth")
        units = metres.astype(np.float64) * scale
        units[~np.isfinite(units)] = 0.0
        rounded = np.rint(units)
        if float(rounded.max(initial=0.0)) > 65535 or not np.allclose(units, rounded, atol=1e-3):
            raise InputError(
                f"RGBDImage depth (metres) times depth_scale={scale:g} is not whole uint16 depth "
                "units: pass the depth_scale the image was made with (Open3D's default is 1000)"
            )
        depth: npt.NDArray[Any] = rounded.astype(np.uint16)
    else:
        color = rgbd.color.as_tensor().cpu().numpy()
        raw = rgbd.depth.as_tensor().cpu().numpy()
        if raw.ndim == 3 and raw.shape[2] == 1:
            raw = raw[..., 0]
        depth = check_depth(raw, name="RGBDImage depth")
        if depth.dtype == np.float32 and scale != 1.0:
            depth = (depth / np.float32(scale)).astype(np.float32)
    if color.ndim == 3 and color.shape[2] == 1:
        color = color[..., 0]
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
