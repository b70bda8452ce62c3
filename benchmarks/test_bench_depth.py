"""Encode and decode time of every depth codec on real 640×480 frames.

Uses pcdcodec's pytest plugin as a user's benchmark would: ``rgbd_sequence`` is each present
sequence (:mod:`pcdcodec.bench.sequences`, or ``--pcdcodec-data``), ``depth_codec`` each
available depth codec. ``pytest benchmarks/ --benchmark-only`` prints pytest-benchmark's timing
tables and then ratio, KiB per frame, encode and decode ms per codec and sequence.
"""

from __future__ import annotations

from typing import Any

from pcdcodec.testing import bench_depth


def test_encode(benchmark: Any, rgbd_sequence: Any, depth_codec: Any) -> None:
    encoded = bench_depth(benchmark, depth_codec, rgbd_sequence, op="encode")
    assert depth_codec.decode(encoded).shape == rgbd_sequence[0].depth.shape


def test_decode(benchmark: Any, rgbd_sequence: Any, depth_codec: Any) -> None:
    decoded = bench_depth(benchmark, depth_codec, rgbd_sequence, op="decode")
    middle = len(rgbd_sequence) // 2
    assert (decoded == rgbd_sequence[middle].depth).all()
