"""Every registered depth codec, tested through the registry: a new codec needs no new test."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pcdcodec
from pcdcodec.depth import FrameCodec, read_header

from .conftest import SEQUENCES, SHARED_SEQUENCES, load_depths, to_metres

DEPTH_CODECS = pcdcodec.list_codecs("depth")


def make(name: str) -> FrameCodec:
    codec = pcdcodec.get_codec(name, kind="depth")
    assert isinstance(codec, FrameCodec)
    return codec


def carries_float(name: str) -> bool:
    return "float32" in make(name).dtypes


def assert_bit_exact(decoded: np.ndarray[Any, Any], original: np.ndarray[Any, Any]) -> None:
    assert decoded.shape == original.shape
    assert decoded.dtype == original.dtype
    # Compare bits, so NaN payloads and -0.0 count too.
    view = np.uint32 if original.dtype.itemsize == 4 else np.uint16
    np.testing.assert_array_equal(decoded.view(view), original.view(view))


@pytest.fixture(params=DEPTH_CODECS)
def codec(request: pytest.FixtureRequest) -> FrameCodec:
    return make(request.param)


def test_every_builtin_depth_codec_is_registered() -> None:
    assert {"lz4", "zstd", "png16", "jpegxl", "rvl"} <= set(DEPTH_CODECS)
    assert pcdcodec.DEFAULT_DEPTH_CODEC in DEPTH_CODECS


# -- bit-exact round trips on real frames ------------------------------------------------


def test_round_trip_bundled_sample(codec: FrameCodec, sample_depths: list[Any]) -> None:
    assert codec.lossless
    for depth in sample_depths:
        data = codec.encode(depth)
        assert isinstance(data, bytes)
        assert len(data) < depth.nbytes  # real depth compresses with every codec
        assert_bit_exact(codec.decode(data), depth)


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", SHARED_SEQUENCES)
def test_round_trip_shared_sequences(codec: FrameCodec, sequence: str) -> None:
    for depth in load_depths(sequence, 6):
        assert_bit_exact(codec.decode(codec.encode(depth)), depth)


@pytest.mark.parametrize("sequence", ["sample", *SHARED_SEQUENCES])
def test_float32_metres_round_trip(codec: FrameCodec, sequence: str) -> None:
    depth = load_depths(sequence, 2)[-1]
    metres = to_metres(depth, SEQUENCES[sequence].depth_scale)
    if not carries_float(codec.name):
        with pytest.raises(pcdcodec.InputTypeError, match="float32"):
            codec.encode(metres)
        return
    assert np.isnan(metres).any()
    assert_bit_exact(codec.decode(codec.encode(metres)), metres)


FLOAT_CODECS = [n for n in DEPTH_CODECS if carries_float(n)]


def test_float32_support_as_promised() -> None:
    assert {"lz4", "zstd", pcdcodec.DEFAULT_DEPTH_CODEC} <= set(FLOAT_CODECS)


@pytest.mark.parametrize("name", FLOAT_CODECS)
def test_float32_special_values_and_many_distinct(name: str) -> None:
    codec = make(name)
    rng = np.random.default_rng(7)
    # More distinct values than a 16-bit index holds: the split-plane layout.
    many = rng.uniform(0.3, 8.0, size=(300, 300)).astype(np.float32)
    special = np.array(
        [[np.nan, -np.nan, np.inf, -np.inf], [0.0, -0.0, 1e-45, 3.4e38]], dtype=np.float32
    )
    payload_nan = np.array([[0x7FC00001, 0xFFC00000]], dtype=np.uint32).view(np.float32)
    for image in (many, special, payload_nan, many[::2, 1::3]):
        assert_bit_exact(codec.decode(codec.encode(image)), np.ascontiguousarray(image))


# -- configuration ----------------------------------------------------------------------


def test_config_round_trips_through_json(codec: FrameCodec, sample_depths: list[Any]) -> None:
    config = codec.get_config()
    assert config["id"] == codec.name
    # Error bounds that are not set stay out of the config, so lossless configs never change.
    unset = {"max_error", "max_rel_error"} & set(codec.param_names())
    assert set(config) == {"id", *codec.param_names()} - unset
    rebuilt = pcdcodec.get_codec(json.loads(json.dumps(config)))
    assert rebuilt == codec
    assert rebuilt is not codec
    assert hash(rebuilt) == hash(codec)
    assert repr(rebuilt) == repr(codec)
    depth = sample_depths[0]
    assert_bit_exact(rebuilt.decode(codec.encode(depth)), depth)


def test_decode_depth_picks_the_codec_from_the_bytes(
    codec: FrameCodec, sample_depths: list[Any]
) -> None:
    data = codec.encode(sample_depths[1])
    header = read_header(data)
    assert header.codec == codec.name
    assert header.shape == sample_depths[1].shape
    assert_bit_exact(pcdcodec.decode_depth(data), sample_depths[1])


def test_unknown_parameter_is_rejected(codec: FrameCodec) -> None:
    with pytest.raises(pcdcodec.InputError, match="no_such_param"):
        pcdcodec.get_codec(codec.name, no_such_param=1)


# -- corrupt input ----------------------------------------------------------------------

GARBAGE = [
    b"",
    b"\x00",
    b"PCDF",
    bytes(range(256)) * 4,
    np.random.default_rng(0).bytes(5000),
]


@pytest.mark.parametrize(
    "garbage", GARBAGE, ids=["empty", "one-byte", "magic-only", "ramp", "random"]
)
def test_garbage_raises_decode_error(codec: FrameCodec, garbage: bytes) -> None:
    with pytest.raises(pcdcodec.DecodeError):
        codec.decode(garbage)


def test_truncated_input_raises(codec: FrameCodec, sample_depths: list[Any]) -> None:
    data = codec.encode(sample_depths[2])
    for cut in (1, 10, len(data) // 2, len(data) - 1):
        with pytest.raises(pcdcodec.DecodeError):
            codec.decode(data[:cut])
    with pytest.raises(pcdcodec.DecodeError, match="extra bytes"):
        codec.decode(data + b"\x00")


def test_bit_flips_never_return_wrong_depth(codec: FrameCodec, sample_depths: list[Any]) -> None:
    depth = sample_depths[3]
    data = codec.encode(depth)
    rng = np.random.default_rng(11)
    positions = sorted({*rng.integers(0, len(data), 40).tolist(), 5, 6, len(data) - 1})
    for pos in positions:
        flipped = bytearray(data)
        flipped[pos] ^= 1 << int(rng.integers(0, 8))
        try:
            decoded = codec.decode(bytes(flipped))
        except pcdcodec.DecodeError:
            continue
        # A flip the format cannot see (none is expected) must still give the right depth.
        assert_bit_exact(decoded, depth)


def test_bytes_of_another_codec_are_refused(codec: FrameCodec, sample_depths: list[Any]) -> None:
    other = next(n for n in DEPTH_CODECS if n != codec.name)
    data = make(other).encode(sample_depths[0])
    with pytest.raises(pcdcodec.DecodeError, match=other):
        codec.decode(data)


def test_newer_format_version_is_refused(codec: FrameCodec, sample_depths: list[Any]) -> None:
    data = bytearray(codec.encode(sample_depths[0]))
    data[4] = 99
    with pytest.raises(pcdcodec.DecodeError, match="version 99"):
        codec.decode(bytes(data))


def test_decode_rejects_non_bytes(codec: FrameCodec) -> None:
    with pytest.raises(pcdcodec.InputTypeError, match="str"):
        codec.decode("not bytes")  # type: ignore[arg-type]


# -- bad input ----------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", ["int64", "uint8", "float64", "int16", "uint32"])
def test_wrong_dtype_raises_naming_it(codec: FrameCodec, dtype: str) -> None:
    with pytest.raises(pcdcodec.InputTypeError, match=dtype):
        codec.encode(np.ones((4, 5), dtype=dtype))


@pytest.mark.parametrize("shape", [(4, 5, 1), (4, 5, 3), (20,), (0, 5), (5, 0), ()], ids=str)
def test_wrong_shape_raises_naming_it(codec: FrameCodec, shape: tuple[int, ...]) -> None:
    with pytest.raises(pcdcodec.InputError, match=r"shape|\(\)"):
        codec.encode(np.ones(shape, dtype=np.uint16))


def test_views_and_foreign_layouts_work(codec: FrameCodec, sample_depths: list[Any]) -> None:
    depth = sample_depths[4]
    variants = {
        "strided": depth[::2, ::3],
        "offset": depth[17:301, 5:-7],
        "fortran": np.asfortranarray(depth),
        "transposed": depth.T,
        "big-endian": depth.astype(">u2"),
        "reversed": depth[::-1, ::-1],
    }
    for name, view in variants.items():
        decoded = codec.decode(codec.encode(view))
        assert decoded.dtype == np.uint16, name
        np.testing.assert_array_equal(decoded, view, err_msg=name)


def test_decoded_array_is_writable(codec: FrameCodec, sample_depths: list[Any]) -> None:
    decoded = codec.decode(codec.encode(sample_depths[0]))
    decoded[0, 0] = 1
    assert decoded[0, 0] == 1


# -- property-based round trips -----------------------------------------------------------


def depth_images() -> st.SearchStrategy[np.ndarray[Any, Any]]:
    shapes = hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=48)
    values = st.one_of(
        st.integers(0, 65535),
        st.sampled_from([0, 0, 0, 1, 65534, 65535]),  # holes and extremes, often
    )
    return hnp.arrays(np.uint16, shapes, elements=values)


@pytest.mark.parametrize("name", DEPTH_CODECS)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(depth=depth_images())
def test_random_uint16_round_trip(name: str, depth: np.ndarray[Any, Any]) -> None:
    codec = make(name)
    assert_bit_exact(codec.decode(codec.encode(depth)), depth)


@pytest.mark.parametrize("name", FLOAT_CODECS)
@settings(max_examples=40, deadline=None)
@given(
    depth=hnp.arrays(
        np.float32,
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=32),
        elements=st.floats(width=32, allow_nan=True, allow_infinity=True),
    )
)
def test_random_float32_round_trip(name: str, depth: np.ndarray[Any, Any]) -> None:
    codec = make(name)
    assert_bit_exact(codec.decode(codec.encode(depth)), depth)


@pytest.mark.parametrize("distinct", [1, 300, 65536, 65537])
def test_float_value_table_matches_a_sort(distinct: int) -> None:
    from pcdcodec.depth import base

    rng = np.random.default_rng(distinct)
    values = rng.integers(0, 2**32, distinct, dtype=np.uint32)
    bits = values[rng.integers(0, distinct, 640 * 480)]
    bits[: min(distinct, bits.size)] = values[: bits.size]  # every value present
    image = bits.reshape(480, 640).view(np.float32)
    mapped = base._float_to_table(image)
    table = np.unique(bits)
    if distinct > 65536:
        assert mapped is None
        return
    assert mapped is not None
    got_table, got_index = mapped
    nan = np.isnan(table.view(np.float32))
    # NaN patterns first, then the rest in bit order; each pixel indexes its own bits.
    np.testing.assert_array_equal(got_table, np.concatenate([table[nan], table[~nan]]))
    np.testing.assert_array_equal(got_table[got_index].ravel(), bits)


def test_float_value_table_falls_back_to_sorting(monkeypatch: pytest.MonkeyPatch) -> None:
    from pcdcodec.bench.sequences import load_frames
    from pcdcodec.depth import _table_kernels, base

    raw = load_frames("sample", 1)[0]
    image = np.where(raw > 0, raw / 5000.0, np.nan).astype(np.float32)
    expected = base._float_to_table(image)
    assert expected is not None

    def colliding(bits: Any, limit: int) -> tuple[Any, Any, int]:
        return bits[:0], np.zeros(0, np.int32), 2  # as when the probe budget runs out

    monkeypatch.setattr(_table_kernels, "distinct_values", colliding)
    got = base._float_to_table(image)
    assert got is not None
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_array_equal(got[1], expected[1])


@pytest.mark.parametrize("bound", [None, 0.01])
def test_warm_up_codes_every_depth_type_and_changes_no_output(
    codec: FrameCodec, sample_depths: list[Any], bound: float | None
) -> None:
    """A writer warms its depth codec up when it opens: that must work for every codec and
    depth type it takes, bounded or not, and leave what the codec writes as it was."""
    if bound is not None:
        if "max_error" not in type(codec).param_names():
            pytest.skip(f"{codec.name} takes no error bound")
        codec = type(codec)(max_error=bound)  # type: ignore[call-arg]
    depth = sample_depths[0]
    before = codec.encode(depth)
    codec.warm_up(depth.shape)
    codec.warm_up((3, 5))  # another shape, odd sizes
    assert codec.encode(depth) == before
    back = codec.decode(before)
    if bound is None:
        assert_bit_exact(back, depth)
