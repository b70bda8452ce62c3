"""Hostile depth frames: memory stays bounded by what the frame header declares.

Each case is a few kilobytes that, decoded naively, would allocate gigabytes. The checks run
under ``tracemalloc`` (which sees the buffers zstandard, lz4, numpy and imagecodecs allocate
through Python) and assert both the error and that the peak stayed near the declared size.
"""

from __future__ import annotations

import struct
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.depth import DEFAULT_MAX_PIXELS, FrameCodec, read_header
from pcdcodec.depth.base import _pack_header
from pcdcodec.errors import DecodeError

#: Peak Python-visible allocation allowed while a hostile frame is refused.
BOUND = 4 << 20


def _frame(codec: str, shape: tuple[int, int], body: bytes, dtype: str = "<u2") -> bytes:
    """A depth frame whose header declares ``shape`` around an arbitrary body (CRC unset)."""
    return _pack_header(codec, np.dtype(dtype), 0, shape, len(body)) + b"\0\0\0\0" + body


def _peak(run: Callable[[], Any]) -> int:
    """Peak bytes allocated while ``run`` raises DecodeError (which it must)."""
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError):
            run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _codec(name: str) -> FrameCodec:
    codec = pcdcodec.get_codec(name, kind="depth")
    assert isinstance(codec, FrameCodec)
    return codec


def _zstd_rle_frame(content: int, *, declare: bool) -> bytes:
    """A Zstandard frame of ``content`` zero bytes made of RLE blocks: 4 bytes per 128 KiB.

    ``declare`` writes the content size into the frame header (single-segment frame); without
    it the frame only has a window descriptor, as streaming compressors write.
    """
    block = 1 << 17
    assert content % block == 0
    if declare:
        head = struct.pack("<IB", 0xFD2FB528, 0b10100000) + struct.pack("<I", content)
    else:
        head = struct.pack("<IBB", 0xFD2FB528, 0, 0x38)  # window 2**(10 + 7) = 128 KiB
    blocks = []
    count = content // block
    for i in range(count):
        last = 1 if i == count - 1 else 0
        blocks.append(((block << 3) | (1 << 1) | last).to_bytes(3, "little") + b"\0")
    return head + b"".join(blocks)


def _lz4_declaring(content: int, payload: bytes) -> bytes:
    """An LZ4 frame whose header declares ``content`` bytes but holds ``payload`` only."""
    import lz4.frame

    compressor = lz4.frame.LZ4FrameCompressor()
    head = compressor.begin(source_size=content)
    block = struct.pack("<I", len(payload) | 0x80000000) + payload  # an uncompressed block
    return bytes(head) + block + b"\0\0\0\0"


# -- the cases from the report ----------------------------------------------------------------


def test_zstd_frame_declaring_32768_squared_is_refused_before_decompressing() -> None:
    # 64 KiB of RLE blocks that really do hold 2 GiB of zeros.
    body = _zstd_rle_frame(32768 * 32768 * 2, declare=True)
    assert len(body) < 70_000
    data = _frame("zstd", (32768, 32768), body)
    codec = _codec("zstd")
    peak = _peak(lambda: codec.decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match=r"32768x32768.*limit of 67108864.*max_pixels"):
        codec.decode(data)
    with pytest.raises(DecodeError, match="max_pixels"):
        pcdcodec.decode_depth(data)


@pytest.mark.parametrize("declare", [True, False])
def test_zstd_body_larger_than_its_header_allocates_only_the_header_size(declare: bool) -> None:
    # The header says 64x48 (6 KiB); the body holds 256 MiB, with or without saying so.
    data = _frame("zstd", (48, 64), _zstd_rle_frame(256 << 20, declare=declare))
    peak = _peak(lambda: _codec("zstd").decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match="6144"):
        _codec("zstd").decode(data)


def test_lz4_frame_declaring_4_gib_is_refused_before_allocating() -> None:
    # Decoded naively, lz4 allocates the declared 4 GiB before the CRC is ever checked.
    data = _frame("lz4", (48, 64), _lz4_declaring(4 << 30, bytes(100)))
    peak = _peak(lambda: _codec("lz4").decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match=r"declares 4294967296 bytes.*expected 6144"):
        _codec("lz4").decode(data)


def test_lz4_body_holding_more_than_its_header_stops_at_the_header_size() -> None:
    import lz4.frame

    body = lz4.frame.compress(bytes(256 << 20), store_size=False)
    data = _frame("lz4", (48, 64), body)
    peak = _peak(lambda: _codec("lz4").decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match="more than 6144 bytes"):
        _codec("lz4").decode(data)


def test_png_declaring_another_size_is_refused_before_libpng_runs() -> None:
    codec = _codec("png16")
    if not codec.is_available():
        pytest.skip("png16 is unavailable here")
    import imagecodecs

    png = bytearray(imagecodecs.png_encode(np.zeros((48, 64), np.uint16)))
    png[16:24] = struct.pack(">II", 30000, 30000)  # IHDR width, height
    data = _frame("png16", (48, 64), bytes(png))
    peak = _peak(lambda: codec.decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match=r"30000x30000.*header says.*64x48"):
        codec.decode(data)
    png8 = imagecodecs.png_encode(np.zeros((48, 64), np.uint8))
    with pytest.raises(DecodeError, match="8-bit"):
        codec.decode(_frame("png16", (48, 64), bytes(png8)))


def test_jpegxl_declaring_another_size_is_refused_before_libjxl_runs() -> None:
    codec = _codec("jpegxl")
    if not codec.is_available():
        pytest.skip("jpegxl is unavailable here")
    big = codec.encode(np.zeros((2048, 2048), np.uint16))
    body = big[read_header(big).header_size :]
    data = _frame("jpegxl", (48, 64), body)
    peak = _peak(lambda: codec.decode(data))
    assert peak < BOUND
    with pytest.raises(DecodeError, match=r"declares 2048x2048, header says 64x48"):
        codec.decode(data)


@pytest.mark.parametrize(
    "shape", [(1, 1), (7, 3), (48, 64), (480, 640), (256, 512), (600, 1066), (123, 4567)]
)
def test_jpegxl_size_header_is_read_right(shape: tuple[int, int]) -> None:
    from pcdcodec.depth.jpegxl import jpegxl_size

    if not _codec("jpegxl").is_available():
        pytest.skip("jpegxl is unavailable here")
    data = _codec("jpegxl").encode(np.ones(shape, np.uint16))
    body = data[read_header(data).header_size :]
    assert jpegxl_size(body) == shape


@pytest.mark.parametrize("name", pcdcodec.list_codecs("depth"))
def test_every_codec_refuses_a_frame_over_the_pixel_limit_and_a_wrong_shape(name: str) -> None:
    codec = _codec(name)
    if not codec.is_available():
        pytest.skip(f"{name} is unavailable here")
    depth = (np.arange(100 * 120).reshape(100, 120) % 4000).astype(np.uint16)
    data = codec.encode(depth)
    with pytest.raises(DecodeError, match=r"120x100 = 12000 pixels, more than the limit of 5000"):
        codec.decode(data, max_pixels=5000)
    with pytest.raises(DecodeError, match=r"120x100, expected 64x48"):
        codec.decode(data, shape=(48, 64))
    np.testing.assert_array_equal(codec.decode(data, max_pixels=12000, shape=(100, 120)), depth)
    np.testing.assert_array_equal(pcdcodec.decode_depth(data, max_pixels=None), depth)
    with pytest.raises(DecodeError, match="limit of 11999"):
        pcdcodec.decode_depth(data, max_pixels=11999)


def test_the_default_limit_admits_large_real_frames() -> None:
    assert DEFAULT_MAX_PIXELS == 8192 * 8192
    depth = np.zeros((2160, 3840), np.uint16)
    depth[::7, ::5] = 1234
    np.testing.assert_array_equal(pcdcodec.decode_depth(_codec("zstd").encode(depth)), depth)


# -- the paper layout's LZ4 depth -------------------------------------------------------------


@pytest.fixture
def paper_layout(tmp_path: Path) -> Path:
    from pcdcodec.convert.paper import export_paper

    seq = pcdcodec.load_sample(max_frames=3)
    rec = tmp_path / "a.pcdc"
    with pcdcodec.open(
        rec, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=None
    ) as w:
        for f in seq:
            w.write(None, f.depth, f.timestamp_ns)
    export_paper(rec, tmp_path / "layout")
    return tmp_path / "layout"


def _replace_frame(layout: Path, index: int, blob: bytes) -> None:
    import json

    doc = json.loads((layout / "frames.json").read_text())
    depth = layout / "depth.lz4"
    data = depth.read_bytes()
    entry = doc["frames"][index]
    start, length = entry["depth_offset"], entry["depth_length"]
    shift = len(blob) - length
    depth.write_bytes(data[:start] + blob + data[start + length :])
    entry["depth_length"] = len(blob)
    for later in doc["frames"][index + 1 :]:
        later["depth_offset"] += shift
    (layout / "frames.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("declare", [True, False])
def test_paper_import_bounds_a_huge_lz4_depth_frame(
    paper_layout: Path, tmp_path: Path, declare: bool
) -> None:
    import lz4.frame

    from pcdcodec.convert.paper import import_paper

    if declare:  # declares 8 GiB, as a 17.7 MB frame of the report did
        blob = _lz4_declaring(8 << 30, bytes(1000))
    else:  # holds 256 MiB of zeros without declaring it
        blob = lz4.frame.compress(bytes(256 << 20), store_size=False)
    _replace_frame(paper_layout, 1, blob)
    out = tmp_path / "b.pcdc"
    peak = _peak(lambda: import_paper(paper_layout, out))
    # One 640x480 image is 600 KiB; the import holds a few of them, never the frame's content.
    assert peak < 4 * BOUND
    with pytest.raises(DecodeError, match=r"frame 1 .*640x480 uint16 image"):
        import_paper(paper_layout, out)
    assert not out.exists()
