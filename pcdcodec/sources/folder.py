"""RGB-D image folders (TUM layout, rgb/ + depth/, or flat) as a :class:`Source`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .base import Source, register_source

__all__: list[str] = []


def _has_flat_depth(path: Path) -> bool:
    """Whether the folder holds a depth file of the flat layout (``*depth*.png``, ...) and no
    file another reader takes: a folder of bags beside a ``depth_preview.png`` is a folder of
    recordings, to be searched, not one frame of depth."""
    from ..datasets import _DEPTH_SUFFIXES, _FLAT_DEPTH, _IMAGE_SUFFIXES
    from .base import detect_kind

    found = False
    try:
        with os.scandir(path) as entries:
            for e in entries:
                stem, ext = os.path.splitext(e.name)
                ext = ext.lower()
                if ext in _DEPTH_SUFFIXES + _IMAGE_SUFFIXES:
                    found = found or (
                        ext in _DEPTH_SUFFIXES and bool(_FLAT_DEPTH.match(stem)) and e.is_file()
                    )
                elif e.is_file() and detect_kind(e.path) is not None:
                    return False
    except OSError:
        return False
    return found


def _is_folder(path: Path) -> bool:
    return path.is_dir() and (
        (path / "depth.txt").is_file() or (path / "depth").is_dir() or _has_flat_depth(path)
    )


def _open(path: Path, **options: Any) -> Source:
    from ..datasets import open_folder

    return open_folder(path, **options)


register_source(
    "folder",
    _is_folder,
    _open,
    "a TUM RGB-D folder, rgb/ (or color/) and depth/ image folders, or one folder of "
    "*depth* and *rgb* files; other names need depth_pattern= and color_pattern=",
)
