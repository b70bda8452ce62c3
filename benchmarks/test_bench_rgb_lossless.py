"""Lossless colour (kept RGB images, clouds' packed colours): ``pcdcodec.color.rgb_lossless``
against lossless JPEG XL at effort 1 (what kept colours took before), on every color set at
hand: the bundled TUM sample and the real 640×480 sequences of ``../shared/data``.

``pytest benchmarks/test_bench_rgb_lossless.py --benchmark-only`` times encode and decode of
each set's frames with both coders, one after the other (the same machine load). Every frame is
decoded and compared bit for bit before anything is timed; each coder's bytes a frame and the
model found go into ``extra_info``. ``scripts/rgb_lossless_table.py`` prints the table in
``docs/bags.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pcdcodec.bench.sequences import load_colors, set_present
from pcdcodec.color import rgb_lossless

SETS = ("sample", "tum_fr1_rpy", "realsense_d435", "7scenes_redkitchen")
FRAMES = 3


def _jxl() -> tuple[Any, Any]:
    import imagecodecs

    def encode(rgb: Any) -> bytes:
        return bytes(imagecodecs.jpegxl_encode(rgb, lossless=True, effort=1, numthreads=1))

    return encode, imagecodecs.jpegxl_decode


@pytest.mark.parametrize("op", ["encode", "decode"])
@pytest.mark.parametrize("coder", ["rgb_lossless", "jpegxl-e1"])
@pytest.mark.parametrize("name", SETS)
def test_lossless_colour(benchmark: Any, name: str, coder: str, op: str) -> None:
    if not set_present(name):
        pytest.skip(f"{name} is not in ../shared/data")
    frames = [np.ascontiguousarray(c) for c in load_colors(name, 30)[::10][:FRAMES]]
    if coder == "rgb_lossless":
        encode: Any = rgb_lossless.encode

        def decode(data: bytes) -> Any:
            return rgb_lossless.decode(data, frames[0].shape[:2])
    else:
        encode, decode = _jxl()
    coded = [encode(f) for f in frames]
    for f, c in zip(frames, coded, strict=True):
        assert np.array_equal(np.asarray(decode(c)), f)
    benchmark.group = f"lossless colour: {name} {op}"
    benchmark.extra_info.update(
        bytes_per_frame=sum(map(len, coded)) / len(coded),
        model=sorted({rgb_lossless.model_of(f)[0] for f in frames}),
    )
    if op == "encode":
        out = benchmark(lambda: [encode(f) for f in frames])
    else:
        out = benchmark(lambda: [decode(c) for c in coded])
    assert len(out) == len(frames)
