"""Color codecs on real frames: bytes per frame, PSNR, encode and decode ms per frame.

This is the per-codec version of the compressed point cloud streams paper's Table I.
Encoders keep state across frames, so each round encodes (or decodes) a whole run of
consecutive frames and the time per frame is the round's time divided by the frame count.
``pytest benchmarks/ --benchmark-only`` ends with a summary table (``benchmarks/conftest.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color import StreamCodec, decode_packets, encode_frames
from pcdcodec.metrics import psnr
from tests.conftest import SEQUENCES, load_colors

COLOR_CODECS = [
    n
    for n in pcdcodec.list_codecs("color", available_only=True)
    if issubclass(pcdcodec.codec_class(n), StreamCodec)
]
PRESENT = [name for name in ("sample", "tum_fr1_rpy", "realsense_d435") if SEQUENCES[name].present]
FRAMES = 15


def prepare(name: str, sequence: str) -> tuple[StreamCodec, list[Any], Any, dict[str, Any]]:
    codec = pcdcodec.get_codec(name)
    assert isinstance(codec, StreamCodec)
    frames = load_colors(sequence, FRAMES)
    packets, extradata = encode_frames(codec, frames)
    h, w = frames[0].shape[:2]
    decoded = decode_packets(codec, packets, w, h, extradata)
    assert len(decoded) == len(frames)  # correct before timed
    quality = float(np.mean([psnr(d.rgb, f) for d, f in zip(decoded, frames, strict=True)]))
    if codec.lossless:
        assert quality == float("inf")
    size = sum(len(p.data) for p in packets)
    info = {
        "codec": name,
        "sequence": sequence,
        "kind": "color",
        "bytes_per_frame": size / len(frames),
        "ratio": round(sum(f.nbytes for f in frames) / size, 2),
        "psnr": round(quality, 2) if quality != float("inf") else "inf",
        "frames": len(frames),
    }
    return codec, frames, (packets, extradata), info


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("name", COLOR_CODECS)
def test_encode(benchmark: Any, name: str, sequence: str) -> None:
    benchmark.group = f"color encode {sequence} ({FRAMES} frames per round)"
    codec, frames, (packets, _), info = prepare(name, sequence)
    benchmark.extra_info.update(info, op="encode")
    result, _ = benchmark.pedantic(encode_frames, args=(codec, frames), rounds=3, iterations=1)
    assert len(result) == len(packets)


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("name", COLOR_CODECS)
def test_decode(benchmark: Any, name: str, sequence: str) -> None:
    benchmark.group = f"color decode {sequence} ({FRAMES} frames per round)"
    codec, frames, (packets, extradata), info = prepare(name, sequence)
    benchmark.extra_info.update(info, op="decode")
    h, w = frames[0].shape[:2]
    result = benchmark.pedantic(
        decode_packets, args=(codec, packets, w, h, extradata), rounds=3, iterations=1
    )
    assert len(result) == len(frames)
