"""Golden files: committed frames of every built-in depth codec decode to the same depth forever."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color import Packet, StreamCodec, decode_packets

from .golden.make_golden import golden_source

GOLDEN = Path(__file__).resolve().parent / "golden" / "depth"
BUILTIN_DEPTH = [
    n
    for n in pcdcodec.list_codecs("depth")
    if pcdcodec.codec_class(n).__module__.startswith("pcdcodec.")
]


@pytest.mark.parametrize("name", BUILTIN_DEPTH)
def test_golden_frames_decode_exactly(name: str) -> None:
    index_path = GOLDEN / f"{name}.json"
    assert index_path.exists(), f"no golden frames for {name}: run tests/golden/make_golden.py"
    index = json.loads(index_path.read_text())
    codec = pcdcodec.get_codec(index["config"])
    assert codec.get_config() == index["config"]
    assert len(index["frames"]) >= 2
    for entry in index["frames"]:
        data = (GOLDEN / entry["file"]).read_bytes()
        expected = golden_source(entry)
        decoded = codec.decode(data)
        assert decoded.dtype == expected.dtype
        view = np.uint32 if expected.dtype.itemsize == 4 else np.uint16
        np.testing.assert_array_equal(
            decoded.view(view), expected.view(view), err_msg=entry["file"]
        )
        assert pcdcodec.decode_depth(data).shape == expected.shape


COLOR_GOLDEN = Path(__file__).resolve().parent / "golden" / "color"
STREAM_CODECS = [
    n
    for n in pcdcodec.list_codecs("color", available_only=True)
    if isinstance(pcdcodec.get_codec(n), StreamCodec) and not n.endswith("nvenc")
]


@pytest.mark.parametrize("name", STREAM_CODECS)
def test_golden_color_streams_decode(name: str) -> None:
    import base64

    from .golden.make_color_golden import digest, golden_frames

    path = COLOR_GOLDEN / f"{name}.json"
    assert path.exists(), f"no golden stream for {name}: run tests/golden/make_color_golden.py"
    entry = json.loads(path.read_text())
    codec = pcdcodec.get_codec(entry["config"])
    assert isinstance(codec, StreamCodec)
    extradata = base64.b64decode(entry["extradata"]) if entry["extradata"] else None
    packets = [
        Packet.create(base64.b64decode(p["data"]), p["pts"], p["dts"], p["keyframe"])
        for p in entry["packets"]
    ]
    decoded = decode_packets(codec, packets, entry["width"], entry["height"], extradata)
    assert [f.timestamp for f in decoded] == [0, 33_000_000, 66_000_000]
    originals = golden_frames()
    if codec.lossless:
        for frame, original in zip(decoded, originals, strict=True):
            np.testing.assert_array_equal(frame.rgb, original)
    if entry["decoded_sha256"] is not None:
        assert digest([f.rgb for f in decoded]) == entry["decoded_sha256"]
    for frame, original in zip(decoded, originals, strict=True):
        diff = frame.rgb.astype(np.float64) - original
        assert 10 * np.log10(255.0**2 / max(float(np.mean(diff**2)), 1e-12)) > 25
