"""Everything that yields RGB-D frames, behind one :class:`Source` protocol.

:mod:`.base` holds the protocol and the registry of readers; each reader (:mod:`.folder`,
:mod:`.rosbag`, :mod:`.realsense`, :mod:`.azure_kinect`) registers itself when imported. The
built-in readers are imported here, on the registry's first use, so that importing the package
loads none of them.
"""

from __future__ import annotations

from . import base
from .base import (
    CameraDefaults,
    FrameIndex,
    Source,
    SourceKind,
    open_source,
    register_source,
    source_kinds,
)

__all__ = [
    "CameraDefaults",
    "FrameIndex",
    "Source",
    "SourceKind",
    "open_source",
    "register_source",
    "source_kinds",
]


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
