"""RGB-D image folders (TUM layout, or rgb/ + depth/) as a :class:`Source`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .base import Source, register_source

__all__: list[str] = []


def _is_folder(path: Path) -> bool:
    return path.is_dir() and (
        ((path / "rgb.txt").exists() and (path / "depth.txt").exists())
        or ((path / "depth").is_dir() and any((path / n).is_dir() for n in ("rgb", "color")))
    )


def _open(path: Path, **options: Any) -> Source:
    from ..datasets import open_folder

    return open_folder(path, **options)


register_source(
    "folder", _is_folder, _open, "a TUM RGB-D folder, or rgb/ (or color/) and depth/ image folders"
)
