"""pcdcodec's depth codecs in numcodecs and in Zarr arrays.

Every depth codec (:func:`pcdcodec.list_codecs` ``("depth")``) is two things here:

* a numcodecs codec with the id ``pcdcodec.<name>`` (:mod:`pcdcodec.zarr.numcodecs`), found by
  :func:`numcodecs.get_codec` through the ``numcodecs.codecs`` entry points, and usable as the
  compressor of a Zarr format 2 array;
* a Zarr format 3 array-to-bytes codec, a *serializer*, named ``pcdcodec.<name>`` in the
  array's metadata (:mod:`pcdcodec.zarr.v3`), found by Zarr through the ``zarr.codecs`` entry
  points.

Both code one chunk as one depth image: a chunk of shape ``(1, ..., 1, H, W)``, so a T×H×W
depth array is chunked one frame per chunk. ``docs/zarr.md`` has the usage and the sizes.

This package imports neither numcodecs nor zarr until one of its names is used, and
:mod:`pcdcodec.zarr.numcodecs` never imports zarr.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names below load on first use (__getattr__)
    from .numcodecs import DepthNumcodec, numcodec, numcodec_class
    from .v3 import DepthSerializer, serializer

__all__ = ["DepthNumcodec", "DepthSerializer", "numcodec", "numcodec_class", "serializer"]

_WHERE = {
    "DepthNumcodec": "numcodecs",
    "numcodec": "numcodecs",
    "numcodec_class": "numcodecs",
    "DepthSerializer": "v3",
    "serializer": "v3",
}


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'pcdcodec.zarr' has no attribute {name!r}")
    from importlib import import_module

    return getattr(import_module(f"{__name__}.{module}"), name)


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
