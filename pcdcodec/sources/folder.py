"""RGB-D image folders (TUM layout, rgb/ + depth/, or flat) as a :class:`Source`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .base import Source, register_source

__all__: list[str] = []


def _flat_depth_and_others(path: Path) -> tuple[bool, list[str]]:
    """Whether the folder holds a depth file of the flat layout (``*depth*.png``, ...), and its
    other files that are not images (which may be bags or camera recordings)."""
    from ..datasets import DEPTH_SUFFIXES, FLAT_DEPTH, IMAGE_SUFFIXES

    flat = False
    others: list[str] = []
    try:
        with os.scandir(path) as entries:
            for e in entries:
                stem, ext = os.path.splitext(e.name)
                ext = ext.lower()
                if ext in DEPTH_SUFFIXES + IMAGE_SUFFIXES:
                    flat = flat or (
                        ext in DEPTH_SUFFIXES and bool(FLAT_DEPTH.match(stem)) and e.is_file()
                    )
                elif e.is_file():
                    others.append(e.path)
    except OSError:
        return False, []
    return flat, others


def _is_folder(path: Path) -> bool:
    if not path.is_dir():
        return False
    if ((path / "rgb.txt").is_file() and (path / "depth.txt").is_file()) or (
        (path / "depth").is_dir() and any((path / n).is_dir() for n in ("rgb", "color"))
    ):
        return True  # color and depth: an RGB-D folder whatever else it holds
    # Depth alone (depth.txt, depth/, or files named *depth*) is an RGB-D folder only beside no
    # other input: a folder of bags with a depth/ of previews or a depth_preview.png is a
    # folder of bags, to be searched, not frames of depth.
    flat, others = _flat_depth_and_others(path)
    if not (flat or (path / "depth.txt").is_file() or (path / "depth").is_dir()):
        return False
    from .base import detect_kind

    return not any(detect_kind(f) is not None for f in others)


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
