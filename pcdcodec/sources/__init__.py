"""Everything that yields RGB-D frames, behind one :class:`Source` protocol."""

from __future__ import annotations

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
