"""Every depth codec on every depth test set, dense and sparse, side by side with jpegxl.

``pytest benchmarks/test_bench_depth_sets.py --benchmark-only`` prints a table of ratio,
encode and decode ms per codec and test set, and the times relative to jpegxl's measured in
the same run (``benchmarks/conftest.py``).
The ratio is over the set's sampled frames and is kept in ``extra_info``.

The test sets are the real sequences (640×480), their sparse variants (``-sparse``: large
regions removed the way sensors lose depth, ``pcdcodec.bench.sparse.sparsify_depth``), the Spot
depth frame (424×240, ``spot``), the Azure Kinect ToF frame (640×576, ``azure_kinect``) and D435
frames upsampled to 1280×720 with nearest neighbour (``realsense_d435-1280x720``: no real
1280×720 depth is at hand; :func:`pcdcodec.bench.sequences.upsample_720p`). Every registered
codec runs with its defaults; ``zstd-19`` adds Zstandard at level 19, the strongest
general-purpose baseline.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.sequences import ALL_DEPTH_SETS, load_frames, set_present
from pcdcodec.depth import FrameCodec

CONFIGS: dict[str, dict[str, Any]] = {
    name: {"id": name} for name in pcdcodec.list_codecs("depth", available_only=True)
}
CONFIGS["zstd-19"] = {"id": "zstd", "level": 19}


PRESENT = [name for name in ALL_DEPTH_SETS if set_present(name)]
FRAMES = 6


Prepared = tuple[FrameCodec, list[Any], list[bytes], dict[str, float]]


def prepare(
    config: dict[str, Any],
    sequence: str,
    check: Callable[[Any, Any], None] = np.testing.assert_array_equal,
) -> Prepared:
    """The codec, the set's frames, their encodings and the ratio; every frame is decoded and
    ``check(decoded, original)``-ed (bit-exact by default) before anything is timed."""
    codec = pcdcodec.get_codec(config)
    assert isinstance(codec, FrameCodec)
    depths = load_frames(sequence, FRAMES)
    encoded = [codec.encode(d) for d in depths]
    for depth, data in zip(depths, encoded, strict=True):
        check(codec.decode(data), depth)
    raw = sum(d.nbytes for d in depths)
    info = {"ratio": round(raw / sum(len(b) for b in encoded), 3), "frames": len(depths)}
    return codec, depths, encoded, info


def setup(label: str, sequence: str) -> Prepared:
    return prepare(CONFIGS[label], sequence)


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("label", CONFIGS)
def test_encode(benchmark: Any, label: str, sequence: str) -> None:
    benchmark.group = f"depth sets encode {sequence}"
    codec, depths, encoded, info = setup(label, sequence)
    benchmark.extra_info.update(info, codec=label, sequence=sequence, kind="depthset", op="encode")
    frame = depths[len(depths) // 2]
    result = benchmark(codec.encode, frame)
    assert len(result) == len(encoded[len(depths) // 2])


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("label", CONFIGS)
def test_decode(benchmark: Any, label: str, sequence: str) -> None:
    benchmark.group = f"depth sets decode {sequence}"
    codec, depths, encoded, info = setup(label, sequence)
    benchmark.extra_info.update(info, codec=label, sequence=sequence, kind="depthset", op="decode")
    index = len(depths) // 2
    result = benchmark(codec.decode, encoded[index])
    np.testing.assert_array_equal(result, depths[index])
