"""One RGB-D frame, the same object from sources, recordings and evaluation.

A :class:`Frame` holds a color image (H×W×3 uint8 RGB, or ``None`` for depth only), a depth
image (H×W uint16 depth units or float32 metres), its time ``timestamp_ns`` (nanoseconds; each
image's own time, where an input stamps them apart, in ``color_timestamp_ns`` and
``depth_timestamp_ns``), and optionally its position in a sequence (``index``) and the camera
pose (``pose``, 4×4 float64 camera-to-world). Frames read from a recording also carry the
recording's :class:`~pcdcodec.Projector`, so they turn into points and Open3D objects directly;
frames from elsewhere take a projector as an argument.

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

from ._validate import OPEN3D_DEPTH_SCALE, check_depth_scale
from .errors import InputError

if TYPE_CHECKING:
    from .geometry.open3d import from_open3d_rgbd, open3d_rgbd
    from .geometry.open3d import open3d_rgbd_kind as open3d_rgbd_kind
    from .geometry.projector import Projector

__all__ = ["OPEN3D_DEPTH_SCALE", "Frame", "from_open3d_rgbd", "open3d_rgbd"]

#: Names that live in :mod:`pcdcodec.geometry.open3d`, served from here too; that module loads
#: on first use, so that ``import pcdcodec`` stays light.
_OPEN3D_NAMES = ("from_open3d_rgbd", "open3d_rgbd", "open3d_rgbd_kind")


def __getattr__(name: str) -> Any:
    if name in _OPEN3D_NAMES:
        from .geometry import open3d

        return getattr(open3d, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    points (set on frames read from a recording). ``color_timestamp_ns`` and
    ``depth_timestamp_ns`` are each image's own time, where the input stamps them apart
    (default: ``timestamp_ns``; the color's is ``None`` without color).
    """

    color: npt.NDArray[np.uint8] | None
    depth: npt.NDArray[Any]
    timestamp_ns: int
    index: int | None = None
    pose: npt.NDArray[np.float64] | None = None
    projector: Projector | None = field(default=None, repr=False)
    #: The color image's own time (ns), where it differs from :attr:`timestamp_ns`: an input
    #: that stamps color and depth apart (TUM's ``rgb.txt`` and ``depth.txt``) pairs images
    #: taken a little apart. ``None`` given means the frame's time; ``None`` without color.
    color_timestamp_ns: int | None = None
    #: The depth image's own time (ns); ``None`` given means the frame's time.
    depth_timestamp_ns: int | None = None

    def __post_init__(self) -> None:
        if self.depth_timestamp_ns is None:
            self.depth_timestamp_ns = self.timestamp_ns
        if self.color is None:
            self.color_timestamp_ns = None
        elif self.color_timestamp_ns is None:
            self.color_timestamp_ns = self.timestamp_ns

    # -- identity ---------------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Frame):
            return NotImplemented
        return (
            self.timestamp_ns == other.timestamp_ns
            and self.color_timestamp_ns == other.color_timestamp_ns
            and self.depth_timestamp_ns == other.depth_timestamp_ns
            and _same(self.depth, other.depth)
            and _same(self.color, other.color)
            and _same(self.pose, other.pose)
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays: not hashable

    def __repr__(self) -> str:
        parts = [] if self.index is None else [f"index={self.index}"]
        parts.append(f"timestamp_ns={self.timestamp_ns}")
        for what, own in (("color", self.color_timestamp_ns), ("depth", self.depth_timestamp_ns)):
            if own is not None and own != self.timestamp_ns:
                parts.append(f"{what}_timestamp_ns={own}")
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
        from .geometry.open3d import open3d_rgbd

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
        """A frame from an Open3D RGBDImage, legacy or tensor (see
        :func:`pcdcodec.geometry.open3d.from_open3d_rgbd`)."""
        from .geometry.open3d import from_open3d_rgbd

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
