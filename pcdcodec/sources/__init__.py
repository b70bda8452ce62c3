"""Everything that yields RGB-D frames, behind one :class:`Source` protocol.

:mod:`.base` holds the protocol and the registry of readers; each reader (:mod:`.folder`,
:mod:`.rosbag`, :mod:`.realsense`, :mod:`.azure_kinect`) registers itself when imported. The
built-in readers are imported here, on the registry's first use, so that importing the package
loads none of them. :func:`realsense_live` (:mod:`.live`, live RealSense cameras through
``pyrealsense2``) loads on first use too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from . import base
from .base import (
    FrameIndex,
    Source,
    SourceKind,
    open_source,
    register_source,
    source_kinds,
)

if TYPE_CHECKING:
    from .camera_rule import CameraDefaults, settle_camera

__all__ = [
    "CameraDefaults",
    "FrameIndex",
    "Source",
    "SourceKind",
    "open_source",
    "realsense_live",
    "register_source",
    "settle_camera",
    "source_kinds",
]

#: Names served from :mod:`.live`, loaded when first asked for.
_LIVE_NAMES = ("RealSenseLiveSource", "connected_serials", "realsense_live")


def __getattr__(name: str) -> Any:
    if name in ("CameraDefaults", "settle_camera"):  # the camera rule, loaded on first use
        from . import camera_rule

        return getattr(camera_rule, name)
    if name in _LIVE_NAMES:
        from . import live

        return getattr(live, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _register_builtin() -> None:
    """Import the built-in readers; each registers itself (probes run in this order, but for
    the RealSense reader, which puts itself first)."""
    from . import (  # noqa: F401 - imported to register
        azure_kinect,
        folder,
        realsense,
        rosbag,
    )


base._LOADERS.append(_register_builtin)
