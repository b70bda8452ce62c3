"""The ``rvl`` depth codec against a slow scalar reference of Wilson's RVL.

The reference below is written straight from the description of the format (one pixel and one
nibble at a time), so the vectorised codec must match it byte for byte. The hand-worked
examples pin the reference itself to the format.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pcdcodec
from pcdcodec.depth.base import read_header
from pcdcodec.depth.rvl import RVL
from pcdcodec.errors import DecodeError, InputTypeError

from .conftest import SHARED_SEQUENCES, load_depths

BUNDLED_DEPTH = Path(pcdcodec.__file__).resolve().parent / "data" / "tum_fr1_rpy" / "depth"

Image = np.ndarray[Any, np.dtype[np.uint16]]


# -- the scalar reference -------------------------------------------------------------------


def pack_codes(values: list[int]) -> bytes:
    """Write numbers as RVL variable-length codes into little-endian 32-bit words."""
    words: list[int] = []
    word = 0
    filled = 0
    for value in values:
        while True:
            nibble = value & 7
            value >>= 3
            if value:
                nibble |= 8
            word = word << 4 | nibble
            filled += 1
            if filled == 8:
                words.append(word)
                word = 0
                filled = 0
            if not value:
                break
    if filled:
        words.append(word << 4 * (8 - filled))
    return struct.pack(f"<{len(words)}I", *words)


def reference_symbols(image: Image) -> list[int]:
    """The numbers RVL writes for an image: zero counts, non-zero counts and zig-zag deltas."""
    pixels = [int(v) for v in image.ravel()]
    symbols: list[int] = []
    i = 0
    previous = 0
    while i < len(pixels):
        zeros = 0
        while i < len(pixels) and pixels[i] == 0:
            zeros += 1
            i += 1
        nonzeros = 0
        while i + nonzeros < len(pixels) and pixels[i + nonzeros] != 0:
            nonzeros += 1
        symbols += [zeros, nonzeros]
        for _ in range(nonzeros):
            delta = pixels[i] - previous
            symbols.append((delta << 1) ^ (delta >> 31))
            previous = pixels[i]
            i += 1
    return symbols


def reference_encode(image: Image) -> bytes:
    return pack_codes(reference_symbols(image))


def reference_decode(body: bytes, npix: int) -> Image:
    words = struct.unpack(f"<{len(body) // 4}I", body)
    nibbles = [(word >> (28 - 4 * k)) & 15 for word in words for k in range(8)]
    position = 0

    def read() -> int:
        nonlocal position
        value = 0
        shift = 0
        while True:
            nibble = nibbles[position]
            position += 1
            value |= (nibble & 7) << shift
            shift += 3
            if not nibble & 8:
                return value

    pixels: list[int] = []
    previous = 0
    while len(pixels) < npix:
        pixels += [0] * read()
        for _ in range(read()):
            code = read()
            previous += (code >> 1) ^ -(code & 1)
            pixels.append(previous)
    assert len(pixels) == npix
    return np.array(pixels, dtype=np.uint16)


# -- helpers ----------------------------------------------------------------------------------


def body_of(data: bytes) -> bytes:
    return data[read_header(data).header_size :]


def decode_body(body: bytes, shape: tuple[int, int]) -> Image:
    image = RVL()._decode_body(memoryview(body), shape, np.dtype("<u2"))
    return np.asarray(image)


def read_png(path: Path) -> Image:
    import imagecodecs

    with open(path, "rb") as f:
        return np.asarray(imagecodecs.png_decode(f.read()))


def check_against_reference(image: Image) -> None:
    image = np.ascontiguousarray(image, dtype=np.uint16)
    body = body_of(RVL().encode(image))
    assert body == reference_encode(image)
    np.testing.assert_array_equal(reference_decode(body, image.size).reshape(image.shape), image)
    decoded = RVL().decode(RVL().encode(image))
    assert decoded.dtype == np.uint16
    np.testing.assert_array_equal(decoded, image)


def _u16(rows: list[list[int]]) -> Image:
    return np.array(rows, dtype=np.uint16)


# -- the reference itself, against hand-worked bitstreams ---------------------------------------

# Each nibble below was worked out by hand from the format description.
HAND_WORKED = [
    # 2 zeros, 2 non-zeros; 5 -> zig-zag 10 = groups 2, 1 -> A 1; 7-5=2 -> 4 -> 4.
    # Nibbles 2 2 A 1 4 fill word 0x22A14000.
    (_u16([[0, 0, 5, 7]]), "0040a122"),
    # 0 zeros, 1 non-zero (3 -> 6), then the trailing pair (1 zero, 0 non-zeros): 0 1 6 1 0.
    (_u16([[3, 0]]), "00006101"),
    # 7 -> 14 -> E 1; 2-7=-5 -> zig-zag 9 -> 9 1.  Nibbles 0 2 E 1 9 1.
    (_u16([[7, 2]]), "0091e102"),
    # 65535 -> 131070 -> groups 6 7 7 7 7 3 -> E F F F F 3 ends the first word exactly;
    # the trailing pair (1, 0) starts the second: 0 1 E F F F F 3 | 1 0.
    (_u16([[65535, 0]]), "f3ffef0100000010"),
    # Exactly one full word: 0 6 2 0 0 0 0 0, no padding.
    (_u16([[1, 1, 1, 1, 1, 1]]), "00002006"),
]


@pytest.mark.parametrize(("image", "hex_body"), HAND_WORKED)
def test_reference_matches_hand_worked_streams(image: Image, hex_body: str) -> None:
    assert reference_encode(image).hex() == hex_body
    np.testing.assert_array_equal(
        reference_decode(bytes.fromhex(hex_body), image.size), image.ravel()
    )


@pytest.mark.parametrize(("image", "hex_body"), HAND_WORKED)
def test_codec_writes_hand_worked_streams(image: Image, hex_body: str) -> None:
    assert body_of(RVL().encode(image)).hex() == hex_body
    np.testing.assert_array_equal(decode_body(bytes.fromhex(hex_body), image.shape), image)


# -- byte-identical to the reference on small images --------------------------------------------


def _nibble_edges() -> Image:
    # Differences whose zig-zag codes sit on both sides of every nibble-count boundary
    # (8, 64, 512, 4096, 32768), up and down, and zero runs of 7, 8, 63 and 64 pixels.
    deltas = [3, 4, -4, -5, 31, 32, -32, -33, 255, 256, -256, -257, 2047, 2048, -2048, -2049]
    deltas += [16383, 16384, -16384, -16385]
    values: list[int] = []
    level = 30000
    for d in deltas:
        values += [level, level + d]
    for run in (7, 8, 63, 64):
        values += [0] * run + [run]
    return np.array(values, dtype=np.uint16).reshape(1, -1)


STRUCTURED = {
    "one zero": _u16([[0]]),
    "one pixel": _u16([[1]]),
    "one max pixel": _u16([[65535]]),
    "all zeros": np.zeros((5, 7), np.uint16),
    "no zeros": (np.arange(35, dtype=np.uint16) * 1000 + 1).reshape(5, 7),
    "constant": np.full((6, 9), 4321, np.uint16),
    "max next to zero": _u16([[65535, 0, 65535, 1, 0, 65535], [0, 0, 65535, 65535, 1, 1]]),
    "large deltas": np.tile(_u16([[1, 65535]]), (3, 5)),
    "one row": _u16([[0, 0, 9, 10, 0, 500, 501, 502, 0, 0, 0, 7]]),
    "one column": _u16([[5], [0], [0], [65535], [12], [0], [1]]),
    "checkerboard": (np.indices((9, 9)).sum(axis=0) % 2 * 777).astype(np.uint16),
    "starts and ends with zeros": _u16([[0, 0, 3, 4, 5, 0], [0, 6, 0, 0, 0, 0]]),
    "nibble edges": _nibble_edges(),
}


@pytest.mark.parametrize("name", list(STRUCTURED))
def test_structured_images_match_reference(name: str) -> None:
    check_against_reference(STRUCTURED[name])


@pytest.mark.parametrize("seed", range(40))
def test_random_images_match_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 12)), int(rng.integers(1, 12)))
    zero_fraction = rng.choice([0.0, 0.1, 0.5, 0.9, 1.0])
    high = int(rng.choice([8, 300, 5000, 65536]))
    image = rng.integers(1, high, shape).astype(np.uint16)
    image[rng.random(shape) < zero_fraction] = 0
    check_against_reference(image)


@settings(max_examples=200, deadline=None)
@given(hnp.arrays(np.uint16, hnp.array_shapes(min_dims=2, max_dims=2, max_side=10)))
def test_any_small_image_matches_reference(image: Image) -> None:
    check_against_reference(image)


@given(
    st.lists(st.sampled_from([0, 0, 0, 1, 2, 7, 8, 1000, 32767, 32768, 65534, 65535]), min_size=1)
)
def test_zero_runs_and_extreme_values_match_reference(pixels: list[int]) -> None:
    check_against_reference(np.array(pixels, dtype=np.uint16).reshape(1, -1))


def test_views_and_big_endian_input_give_the_standard_body() -> None:
    image = np.random.default_rng(7).integers(0, 3000, (6, 10)).astype(np.uint16)
    expected = reference_encode(image[:, ::2])
    assert body_of(RVL().encode(image[:, ::2])) == expected
    big = image[:, ::2].astype(">u2")
    assert body_of(RVL().encode(big)) == expected


# -- real frames ------------------------------------------------------------------------------


def bundled_paths() -> list[Path]:
    paths = sorted(BUNDLED_DEPTH.glob("*.png"))
    assert paths, f"no bundled depth frames in {BUNDLED_DEPTH}"
    return paths


def test_bundled_frames_round_trip_bit_exact() -> None:
    codec = RVL()
    raw = packed = 0
    for path in bundled_paths():
        depth = read_png(path)
        assert depth.dtype == np.uint16
        data = codec.encode(depth)
        decoded = codec.decode(data)
        assert decoded.dtype == np.uint16
        np.testing.assert_array_equal(decoded, depth)
        raw += depth.nbytes
        packed += len(data)
    # RVL compresses Kinect depth about 3.5 to 4 times; far less means the coder broke.
    assert raw / packed > 3.0


def test_bundled_crops_match_reference() -> None:
    depth = read_png(bundled_paths()[0])
    assert (depth == 0).any()
    # A corner (where the Kinect leaves holes) and the middle, small enough for the reference.
    for crop in (depth[:24, :32], depth[228:252, 300:340], depth[-20:, -40:]):
        check_against_reference(crop)


@pytest.mark.shared_data
@pytest.mark.parametrize("name", SHARED_SEQUENCES)
def test_shared_sequences_round_trip_bit_exact(name: str) -> None:
    codec = RVL()
    depths = load_depths(name, 12)
    for depth in depths:
        np.testing.assert_array_equal(codec.decode(codec.encode(depth)), depth)
    # One crop per sequence against the reference as well.
    check_against_reference(depths[len(depths) // 2][200:230, 280:330])


# -- corrupt input ----------------------------------------------------------------------------


def test_truncated_frame_raises() -> None:
    data = RVL().encode(STRUCTURED["no zeros"])
    for cut in (1, 4, len(body_of(data))):
        with pytest.raises(DecodeError):
            RVL().decode(data[:-cut])


@pytest.mark.parametrize("seed", range(6))
def test_corrupted_bodies_never_decode_to_wrong_depth(seed: int) -> None:
    depth = read_png(bundled_paths()[0])[:120, :160]
    data = RVL().encode(depth)
    start = read_header(data).header_size
    rng = np.random.default_rng(seed)
    raised = 0
    for offset in rng.integers(start, len(data), 20):
        broken = bytearray(data)
        broken[offset] ^= 1 << int(rng.integers(0, 8))
        try:
            decoded = RVL().decode(bytes(broken))
        except DecodeError:
            raised += 1
        else:
            # A flip can at most turn a code into a longer spelling of the same value.
            np.testing.assert_array_equal(decoded, depth)
    assert raised >= 15


@pytest.mark.parametrize(
    ("body", "shape", "message"),
    [
        (b"", (1, 1), "not a positive multiple of 4"),
        (b"\x00\x00\x00", (1, 1), "not a positive multiple of 4"),
        # The last nibble still has its continuation bit set.
        (struct.pack("<I", 0x00000008), (1, 1), "ends inside a code"),
        # 16 continuation nibbles, then a last one: a 17-nibble code.
        (struct.pack("<3I", 0xFFFFFFFF, 0xFFFFFFFF, 0x10000000), (1, 1), "longer than 11"),
        # 10 continuation nibbles and a top group of 2: 2**31, beyond a C int.
        (struct.pack("<2I", 0x88888888, 0x88200000), (1, 1), "does not fit"),
        # A 4x4 image's runs read into a 3x4 frame.
        (reference_encode(np.ones((4, 4), np.uint16)), (3, 4), "cover 16 pixels, the frame has 12"),
        # A 3x4 image's codes run out in a 4x4 frame.
        (reference_encode(np.ones((3, 4), np.uint16)), (4, 4), "still to decode"),
        # The last run promises 9 differences; the body holds 1 and 4 padding nibbles.
        (pack_codes([0, 9, 2]), (1, 9), "short of the last run"),
        # A difference code above 2 * 65535.
        (pack_codes([0, 1, 131071]), (1, 1), "larger than any uint16 difference"),
        # +65535 then +1: pixel 65536.
        (pack_codes([0, 2, 131070, 2]), (1, 2), "outside 1..65535"),
        # +5 then -5: a zero pixel inside a run of non-zeros.
        (pack_codes([0, 2, 10, 9]), (1, 2), "outside 1..65535"),
        # A whole extra word after the last pixel.
        (pack_codes([0, 1, 2]) + b"\x00" * 4, (1, 1), "after the last pixel"),
    ],
)
def test_corrupt_bodies_raise_decode_error(
    body: bytes, shape: tuple[int, int], message: str
) -> None:
    with pytest.raises(DecodeError, match=message):
        decode_body(body, shape)


def test_non_zero_padding_raises() -> None:
    body = bytearray(reference_encode(_u16([[0, 0, 5, 7]])))
    decode_body(bytes(body), (1, 4))  # the clean body decodes
    body[0] |= 1  # the lowest nibble of the only word is padding
    with pytest.raises(DecodeError, match="after the last pixel"):
        decode_body(bytes(body), (1, 4))


def test_corrupt_body_inside_a_frame_raises_through_decode() -> None:
    image = STRUCTURED["no zeros"]
    data = RVL().encode(image)
    header = data[: read_header(data).header_size]
    with pytest.raises(DecodeError):
        RVL().decode(header + b"\xff" * len(body_of(data)))


# -- input types and config -------------------------------------------------------------------


def test_float32_depth_is_rejected() -> None:
    with pytest.raises(InputTypeError, match="uint16"):
        RVL().encode(np.ones((4, 4), np.float32))


def test_config_round_trip() -> None:
    config = RVL().get_config()
    assert config == {"id": "rvl"}
    assert RVL.from_config(config) == RVL()
    assert RVL.name == "rvl"
    assert RVL.dtypes == ("uint16",)
