"""``depthac`` against lossless JPEG XL effort 2, on one thread, on every depth set.

``pytest benchmarks/test_bench_depthac_jxl.py --benchmark-only`` (also part of
``scripts/run bench``) times encode and decode of each set's frames with three coders in one
run, side by side: ``depthac`` (numba, one thread), pcdcodec's ``jpegxl`` codec (effort 2,
``threads=1``: the same container as ``depthac``, header and CRC included) and bare libjxl
(``imagecodecs.jpegxl_encode(lossless=True, effort=2, numthreads=1)`` and its decode, no
container). For each set the three coders of one operation run one after the other, so they see
the same machine load. After the run ``benchmarks/conftest.py`` prints ms per frame (the best
round of each: the median moves with a shared machine's load), each ``depthac`` time over
libjxl's and over the ``jpegxl`` codec's, and the range over every set.

The sets (:data:`pcdcodec.bench.sequences.ALL_DEPTH_SETS`, those present): the bundled sample
and the real 640×480 sequences in ``../shared/data`` (TUM fr1_rpy, RealSense D435 office,
7-Scenes redkitchen), their sparse variants (``pcdcodec.bench.sparse.sparsify_depth``), the
Spot frame (424×240), the Azure Kinect ToF frame (640×576) and a 1280×720 set. No real
1280×720 depth is at hand: that set is D435 frames, their centre 640×360 upsampled 2× with
nearest neighbour (:func:`pcdcodec.bench.sequences.upsample_720p`), which stands in for the
pixel count, not for the ratio.

Every frame is decoded and compared bit for bit before anything is timed, and the timed
result is checked again; the ratio against raw uint16 over the set's frames and the bytes per
frame go into ``extra_info``. Under ``--benchmark-disable`` (``scripts/run test``) each case
runs once, untimed, as a smoke test of the same checks.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.sequences import ALL_DEPTH_SETS, load_frames, set_present

#: Frames per set, timed together in each round (sets with one frame have one).
FRAMES = 3
CODERS = ("depthac", "jpegxl", "libjxl")
OPS = ("encode", "decode")


def _libjxl() -> tuple[Callable[[Any], bytes], Callable[[bytes], Any]]:
    import imagecodecs

    def encode(depth: Any) -> bytes:
        return bytes(imagecodecs.jpegxl_encode(depth, lossless=True, effort=2, numthreads=1))

    def decode(data: bytes) -> Any:
        return imagecodecs.jpegxl_decode(data, numthreads=1)

    return encode, decode


def coder(name: str) -> tuple[Callable[[Any], bytes], Callable[[bytes], Any]]:
    """``(encode, decode)`` of one of :data:`CODERS`."""
    if name == "libjxl":
        return _libjxl()
    config = {"id": "jpegxl", "effort": 2, "threads": 1} if name == "jpegxl" else {"id": name}
    codec = pcdcodec.get_codec(config)
    assert codec.get_config() == (config if name == "jpegxl" else {"id": "depthac"})
    return codec.encode, codec.decode


_prepared: dict[tuple[str, str], tuple[list[Any], list[bytes], dict[str, Any]]] = {}


def prepare(name: str, sequence: str) -> tuple[list[Any], list[bytes], dict[str, Any]]:
    """The set's frames, their encodings and the sizes; every frame is checked bit-exact."""
    key = (name, sequence)
    if key not in _prepared:
        encode, decode = coder(name)
        depths = load_frames(sequence, FRAMES)
        encoded = [encode(d) for d in depths]
        for depth, data in zip(depths, encoded, strict=True):
            back = decode(data)
            assert back.dtype == depth.dtype
            np.testing.assert_array_equal(back, depth, err_msg=f"{name} is not lossless")
        size = sum(len(b) for b in encoded)
        info = {
            "ratio": round(sum(d.nbytes for d in depths) / size, 3),
            "bytes_per_frame": size / len(depths),
            "frames": len(depths),
            "pixels": int(depths[0].size),
            "shape": f"{depths[0].shape[1]}x{depths[0].shape[0]}",
        }
        _prepared[key] = (depths, encoded, info)
    return _prepared[key]


CASES = [
    pytest.param(sequence, op, name, id=f"{sequence}-{op}-{name}")
    for sequence in ALL_DEPTH_SETS
    for op in OPS
    for name in CODERS
]


@pytest.mark.parametrize(("sequence", "op", "name"), CASES)
def test_depthac_against_jpegxl(benchmark: Any, sequence: str, op: str, name: str) -> None:
    if not set_present(sequence):
        pytest.skip(f"the data of {sequence} is not present")
    benchmark.group = f"depthac vs jpegxl e2 {op} {sequence}"
    encode, decode = coder(name)
    depths, encoded, info = prepare(name, sequence)
    benchmark.extra_info.update(info, coder=name, sequence=sequence, op=op, kind="depthac-jxl")
    if op == "encode":
        result = benchmark(lambda: [encode(d) for d in depths])
        assert [len(b) for b in result] == [len(b) for b in encoded]
    else:
        result = benchmark(lambda: [decode(b) for b in encoded])
        for back, depth in zip(result, depths, strict=True):
            np.testing.assert_array_equal(back, depth)
