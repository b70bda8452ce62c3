"""Color codecs on real frames: bytes per frame, PSNR, encode and decode ms per frame.

This is the per-codec version of the compressed point cloud streams paper's Table I, written
with pcdcodec's pytest plugin: ``rgbd_sequence`` is each present sequence, ``color_codec`` each
available stream codec. Encoders keep state across frames, so each round encodes (or decodes)
the whole run of consecutive frames (``--pcdcodec-frames``, 10 by default) and the summary
divides the round's time by the frame count.
"""

from __future__ import annotations

from typing import Any

from pcdcodec.testing import bench_color


def test_encode(benchmark: Any, rgbd_sequence: Any, color_codec: Any) -> None:
    packets, _ = bench_color(benchmark, color_codec, rgbd_sequence, op="encode")
    assert packets
    if color_codec.lossless:
        assert benchmark.extra_info["psnr"] == "inf"


def test_decode(benchmark: Any, rgbd_sequence: Any, color_codec: Any) -> None:
    decoded = bench_color(benchmark, color_codec, rgbd_sequence, op="decode")
    assert len(decoded) == len(rgbd_sequence)
