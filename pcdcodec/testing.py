"""Helpers for comparing codecs with pytest-benchmark; the pytest plugin that provides the
``rgbd_sequence``, ``depth_codec`` and ``color_codec`` fixtures is
:mod:`pcdcodec.bench.pytest_plugin` (registered when pcdcodec is installed).

A benchmark file on your own data::

    from pcdcodec.testing import bench_color, bench_depth

    def test_depth(benchmark, rgbd_sequence, depth_codec):
        bench_depth(benchmark, depth_codec, rgbd_sequence, op="encode")

    def test_color(benchmark, rgbd_sequence, color_codec):
        bench_color(benchmark, color_codec, rgbd_sequence, op="encode")

``pytest that_file.py --pcdcodec-data path/to/folder --benchmark-only`` prints pytest-benchmark's
timings and then the ratio, bytes per frame, PSNR and depth error of every codec beside the
median time per frame.
"""

from __future__ import annotations

# The helpers are the plugin's public names; this is their documented import path.
from .bench.pytest_plugin import *  # noqa: F403
from .bench.pytest_plugin import __all__ as __all__
