"""Encode and decode time of every depth codec on real 640×480 frames.

``pytest benchmarks/ --benchmark-only`` prints pytest-benchmark's timing tables and then a
table of ratio, encode and decode ms per codec and sequence (``benchmarks/conftest.py``).
The ratio is over the sequence's sampled frames and is kept in ``extra_info``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.depth import FrameCodec
from tests.conftest import SEQUENCES, load_depths

DEPTH_CODECS = pcdcodec.list_codecs("depth", available_only=True)
PRESENT = [name for name, seq in SEQUENCES.items() if seq.present]
FRAMES = 6


def setup(name: str, sequence: str) -> tuple[FrameCodec, list[Any], list[bytes], dict[str, float]]:
    codec = pcdcodec.get_codec(name)
    assert isinstance(codec, FrameCodec)
    depths = load_depths(sequence, FRAMES)
    encoded = [codec.encode(d) for d in depths]
    for depth, data in zip(depths, encoded, strict=True):
        np.testing.assert_array_equal(codec.decode(data), depth)  # correct before timed
    raw = sum(d.nbytes for d in depths)
    info = {"ratio": round(raw / sum(len(b) for b in encoded), 3), "frames": len(depths)}
    return codec, depths, encoded, info


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("name", DEPTH_CODECS)
def test_encode(benchmark: Any, name: str, sequence: str) -> None:
    benchmark.group = f"depth encode {sequence}"
    codec, depths, encoded, info = setup(name, sequence)
    benchmark.extra_info.update(info, codec=name, sequence=sequence, kind="depth", op="encode")
    frame = depths[len(depths) // 2]
    result = benchmark(codec.encode, frame)
    assert len(result) == len(encoded[len(depths) // 2])


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("name", DEPTH_CODECS)
def test_decode(benchmark: Any, name: str, sequence: str) -> None:
    benchmark.group = f"depth decode {sequence}"
    codec, depths, encoded, info = setup(name, sequence)
    benchmark.extra_info.update(info, codec=name, sequence=sequence, kind="depth", op="decode")
    index = len(depths) // 2
    result = benchmark(codec.decode, encoded[index])
    np.testing.assert_array_equal(result, depths[index])
