"""Bounded-error depth: every valid pixel within the stated bound, holes kept, corruption caught."""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pcdcodec
from pcdcodec.bench.sequences import DEPTH_SETS, SEQUENCES, load_frames
from pcdcodec.depth import FrameCodec, read_header
from pcdcodec.depth.base import LAYOUT_BOUNDED
from pcdcodec.depth.bounded import (
    KIND_F32_FRAME,
    KIND_F32_LATTICE,
    KIND_U16_FRAME,
    ErrorBound,
    frame_levels,
    uint16_lattice,
)
from pcdcodec.depth.depthac import DepthAC
from pcdcodec.depth.zstd import Zstd
from pcdcodec.registry import parse_codec_spec

from .golden.make_golden import golden_source

#: (max_error, max_rel_error) in depth units for uint16 and metres for float32.
BOUNDS_U16 = [(None, 0.005), (None, 0.01), (20.0, 0.005)]
BOUNDS_F32 = [(None, 0.005), (None, 0.01), (0.004, 0.005)]


def _scale(name: str) -> float:
    return 1000.0 if name == "spot" else SEQUENCES[name.removesuffix("-sparse")].depth_scale


def _metres(depth: np.ndarray[Any, Any], scale: float) -> np.ndarray[Any, Any]:
    metres = (depth / scale).astype(np.float32)
    metres[depth == 0] = np.nan
    return metres


def assert_within_bound(
    original: np.ndarray[Any, Any], decoded: np.ndarray[Any, Any], a: float | None, r: float | None
) -> None:
    """Every valid pixel within max(a, r·v) (in float64), holes exactly kept, no new holes."""
    assert decoded.dtype == original.dtype
    assert decoded.shape == original.shape
    if original.dtype == np.uint16:
        valid = original != 0
        assert np.array_equal(decoded == 0, ~valid), "holes must stay holes and only holes"
    else:
        valid = np.isfinite(original) & (original > 0)
        assert np.array_equal(np.isnan(decoded), np.isnan(original)), "NaN must stay NaN"
        assert np.array_equal(decoded[~valid].view(np.uint32), original[~valid].view(np.uint32)), (
            "holes must keep their exact value"
        )
        assert np.all(np.isfinite(decoded[valid]) & (decoded[valid] > 0))
    v = original[valid].astype(np.float64)
    err = np.abs(decoded[valid].astype(np.float64) - v)
    bound = np.maximum(a or 0.0, (r or 0.0) * v)
    worst = int(np.argmax(err - bound)) if err.size else 0
    assert np.all(err <= bound), f"value {v[worst]} decoded {err[worst]} away, bound {bound[worst]}"


@pytest.fixture
def near(request: pytest.FixtureRequest) -> Iterator[int]:
    """Code bounded frames of depthac with a given near-lossless tolerance."""
    saved = DepthAC.bounded_near
    DepthAC.bounded_near = request.param
    yield request.param
    DepthAC.bounded_near = saved


@pytest.mark.parametrize("name", DEPTH_SETS)
@pytest.mark.parametrize("bound", BOUNDS_U16, ids=str)
def test_uint16_within_bound_on_real_depth(name: str, bound: tuple[Any, Any]) -> None:
    codec = DepthAC(max_error=bound[0], max_rel_error=bound[1])
    for depth in load_frames(name, 2):
        data = codec.encode(depth)
        header = read_header(data)
        assert header.layout == LAYOUT_BOUNDED
        assert data[header.header_size + 1] == KIND_U16_FRAME  # levels fitted to the frame
        assert_within_bound(depth, codec.decode(data), *bound)
        assert len(data) < len(DepthAC().encode(depth))


@pytest.mark.parametrize("name", DEPTH_SETS)
@pytest.mark.parametrize("bound", BOUNDS_F32, ids=str)
def test_float32_metres_within_bound_on_real_depth(name: str, bound: tuple[Any, Any]) -> None:
    codec = DepthAC(max_error=bound[0], max_rel_error=bound[1])
    for depth in load_frames(name, 1):
        metres = _metres(depth, _scale(name))
        data = codec.encode(metres)
        assert read_header(data).layout == LAYOUT_BOUNDED
        assert_within_bound(metres, codec.decode(data), *bound)


@pytest.mark.parametrize("near", [1, 2, 3], indirect=True)
@pytest.mark.parametrize("name", ["sample", "tum_fr1_rpy", "realsense_d435", "spot"])
def test_near_lossless_coding_keeps_the_bound(name: str, near: int) -> None:
    codec = DepthAC(max_rel_error=0.005)
    depth = load_frames(name, 1)[0]
    data = codec.encode(depth)
    assert_within_bound(depth, codec.decode(data), None, 0.005)
    metres = _metres(depth, _scale(name))
    assert_within_bound(metres, codec.decode(codec.encode(metres)), None, 0.005)


@pytest.mark.parametrize("name", ["lz4", "zstd", "png16", "jpegxl", "rvl"])
def test_other_codecs_take_the_bound(name: str, sample_depths: list[Any]) -> None:
    cls = pcdcodec.codec_class(name)
    if not cls.is_available():
        pytest.skip(f"{name} is unavailable here")
    codec = pcdcodec.get_codec(name, max_rel_error=0.01)
    assert isinstance(codec, FrameCodec)
    assert not codec.lossless
    depth = sample_depths[3]
    data = codec.encode(depth)
    assert read_header(data).layout == LAYOUT_BOUNDED
    assert_within_bound(depth, codec.decode(data), None, 0.01)
    assert len(data) < len(pcdcodec.get_codec(name).encode(depth))
    assert_within_bound(depth, pcdcodec.decode_depth(data), None, 0.01)
    if "float32" in codec.dtypes:
        metres = _metres(depth, 5000.0)
        assert_within_bound(metres, codec.decode(codec.encode(metres)), None, 0.01)


@pytest.mark.parametrize(("a", "r"), [(0.0, 0.005), (0.0, 0.01), (3.0, 0.0), (2.0, 0.001)])
@pytest.mark.parametrize("near", [0, 1, 2])
def test_uint16_lattice_keeps_the_bound_for_every_value(a: float, r: float, near: int) -> None:
    """Recomputed here: every level within ``near`` indices of f(v) (clamped at 1, as the
    near-lossless decoder clamps) is within the bound of v, for all v in 1..65535."""
    lattice = uint16_lattice(ErrorBound(a, r), near)
    if lattice is None:
        # Steps of one value need 2·near + 1 indices per value at the small end: more than
        # 65,535 for this bound, so frames use a smaller tolerance (near 0 always fits).
        assert near > 0
        assert uint16_lattice(ErrorBound(a, r), 0) is not None
        return
    _, table, lut = lattice
    n = table.size - 1
    v = np.arange(1, 65536)
    k = lut[1:].astype(np.int64)
    assert lut[0] == 0
    assert k.min() >= 1
    assert k.max() + near <= n
    assert np.all(table[1:] >= 1)
    assert np.all(np.diff(table[1:].astype(np.int64)) >= 0)
    bound = np.maximum(a, r * v.astype(np.float64))
    for j in range(-near, near + 1):
        levels = table[np.clip(k + j, 1, n)].astype(np.float64)
        assert np.all(np.abs(levels - v) <= bound)
    if a < 1 and r * 199 < 1:
        assert np.array_equal(table[k[:199]], v[:199])  # small depths stay exact


def test_bound_finer_than_float32_keeps_values_exactly(sample_depths: list[Any]) -> None:
    metres = _metres(sample_depths[0], 5000.0)
    codec = DepthAC(max_error=1e-9)
    data = codec.encode(metres)
    header = read_header(data)
    assert header.layout == LAYOUT_BOUNDED
    assert data[header.header_size + 1] == KIND_F32_FRAME
    np.testing.assert_array_equal(codec.decode(data).view(np.uint32), metres.view(np.uint32))


def test_bound_too_fine_for_any_table_falls_back_to_lossless() -> None:
    # 90,000 distinct values: too many to fit levels to, and a lattice at 1 nm steps over
    # 1..4 m would need billions of levels; the frame is stored exactly instead.
    rng = np.random.default_rng(5)
    metres = rng.uniform(1.0, 4.0, (300, 300)).astype(np.float32)
    codec = DepthAC(max_error=1e-9)
    data = codec.encode(metres)
    assert read_header(data).layout != LAYOUT_BOUNDED
    np.testing.assert_array_equal(codec.decode(data).view(np.uint32), metres.view(np.uint32))
    coarse = DepthAC(max_rel_error=0.01)  # the lattice takes over from fitted levels
    data = coarse.encode(metres)
    header = read_header(data)
    assert data[header.header_size + 1] == KIND_F32_LATTICE
    assert_within_bound(metres, coarse.decode(data), None, 0.01)


def test_float_frames_with_mixed_holes_are_kept_exactly() -> None:
    image = np.full((8, 8), 1.5, dtype=np.float32)
    image[0, 0] = np.nan
    image[1, 1] = 0.0
    image[2, 2] = -np.inf
    codec = DepthAC(max_rel_error=0.01)
    back = codec.decode(codec.encode(image))
    np.testing.assert_array_equal(back.view(np.uint32), image.view(np.uint32))
    only_nan = np.full((4, 5), np.nan, dtype=np.float32)
    assert np.isnan(codec.decode(codec.encode(only_nan))).all()
    zero_holes = np.where(np.arange(20).reshape(4, 5) % 3 == 0, 0.0, 2.0).astype(np.float32)
    back = codec.decode(codec.encode(zero_holes))
    assert_within_bound(zero_holes, back, None, 0.01)


def test_config_states_the_bound() -> None:
    codec = parse_codec_spec("depthac:max_rel_error=0.005", "depth")
    assert isinstance(codec, FrameCodec)
    assert codec.get_config() == {"id": "depthac", "max_rel_error": 0.005}
    assert not codec.lossless
    assert DepthAC().lossless
    assert pcdcodec.get_codec(json.loads(json.dumps(codec.get_config()))) == codec
    both = parse_codec_spec("jpegxl:effort=2,max_error=5,max_rel_error=0.01", "depth")
    assert both.get_config() == {
        "id": "jpegxl",
        "effort": 2,
        "threads": 1,
        "max_error": 5.0,
        "max_rel_error": 0.01,
    }
    assert DepthAC().get_config() == {"id": "depthac"}
    assert DepthAC(max_error=0, max_rel_error=0).lossless


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"max_error": -1}, "max_error must be a finite number >= 0, got -1"),
        ({"max_rel_error": 1.0}, "must be < 1"),
        ({"max_rel_error": 5}, "must be < 1"),
        ({"max_rel_error": math.nan}, "max_rel_error must be a finite number >= 0"),
        ({"max_error": math.inf}, "max_error must be a finite number >= 0"),
        ({"max_error": "5mm"}, "max_error must be a number such as 0.005, got '5mm'"),
        ({"max_rel_error": "abc"}, "max_rel_error must be a number such as 0.005, got 'abc'"),
        ({"max_rel_error": "inf"}, "max_rel_error must be a finite number >= 0, got inf"),
        ({"max_rel_error": True}, "max_rel_error must be a number such as 0.005 .* got True"),
    ],
)
def test_bad_bounds_are_refused(params: dict[str, Any], message: str) -> None:
    with pytest.raises(pcdcodec.PcdcodecError, match=message.replace("(", r"\(")):
        DepthAC(**params)


def _bounded_frames(sample_depths: list[Any]) -> list[bytes]:
    crop = np.ascontiguousarray(sample_depths[2][200:232, 300:340])
    codec = DepthAC(max_rel_error=0.01)
    return [codec.encode(crop), codec.encode(_metres(crop, 5000.0))]


def test_every_corrupted_byte_is_caught(sample_depths: list[Any]) -> None:
    codec = DepthAC(max_rel_error=0.01)
    for data in _bounded_frames(sample_depths):
        good = codec.decode(data)
        for i in range(len(data)):
            bad = bytearray(data)
            bad[i] ^= 0x5A
            try:
                back = codec.decode(bytes(bad))
            except pcdcodec.DecodeError:
                continue
            # A change the decoder never reads may pass, but never with other depth.
            assert back.view(np.uint8).tobytes() == good.view(np.uint8).tobytes(), i
        with pytest.raises(pcdcodec.DecodeError):
            codec.decode(data[:-1])


def test_near_stated_in_the_frame_must_match_the_body(sample_depths: list[Any]) -> None:
    data = bytearray(_bounded_frames(sample_depths)[0])
    params_at = read_header(data).header_size
    data[params_at + 2] = 1  # the near-lossless tolerance
    with pytest.raises(pcdcodec.DecodeError):
        DepthAC().decode(bytes(data))


GOLDEN = Path(__file__).resolve().parent / "golden" / "depth_bounded"


@pytest.mark.parametrize("path", sorted(GOLDEN.glob("*.json")), ids=lambda p: p.stem)
def test_golden_bounded_frames_decode_the_same(path: Path) -> None:
    index = json.loads(path.read_text())
    codec = pcdcodec.get_codec(index["config"])
    assert isinstance(codec, FrameCodec)
    a, r = index["config"].get("max_error"), index["config"].get("max_rel_error")
    for entry in index["frames"]:
        data = (GOLDEN / entry["file"]).read_bytes()
        header = read_header(data)
        assert header.layout == LAYOUT_BOUNDED
        assert data[header.header_size + 2] == index["near"]
        decoded = pcdcodec.decode_depth(data)
        assert hashlib.sha256(decoded.tobytes()).hexdigest() == entry["decoded_sha256"]
        assert_within_bound(golden_source(entry), decoded, a, r)


def test_golden_bounded_set_is_complete() -> None:
    assert {p.stem for p in GOLDEN.glob("*.json")} >= {
        "depthac-rel1",
        "depthac-abs-rel",
        "depthac-rel1-near2",
        "zstd-rel05",
        "depthac-rel05-fitted",
        "jpegxl-abs-fitted",
        "depthac-rel1-fitted",
    }


def test_recording_and_cli_take_the_bound(tmp_path: Path) -> None:
    import subprocess
    import sys

    from pcdcodec.datasets import load_sample, sample_dir

    sample = load_sample(max_frames=3)
    path = tmp_path / "api.pcdc"
    with pcdcodec.open(
        path,
        "w",
        intrinsics=sample.intrinsics,
        depth_scale=sample.depth_scale,
        color=None,
        depth="depthac:max_rel_error=0.005",
    ) as rec:
        for i, frame in enumerate(sample):
            rec.write(None, frame.depth, i * 33_000_000)
    with pcdcodec.open(path) as rd:
        assert rd.depth_codec.get_config() == {"id": "depthac", "max_rel_error": 0.005}
        for i, frame in enumerate(sample):
            assert_within_bound(frame.depth, rd.depth(i), None, 0.005)
    out = tmp_path / "cli.pcdc"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "pcdcodec",
            "encode",
            str(sample_dir()),
            "-o",
            str(out),
            "--max-frames",
            "2",
            "--depth",
            "depthac:max_error=10,max_rel_error=0.01",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    with pcdcodec.open(out) as rd:
        for i in range(2):
            assert_within_bound(sample[i].depth, rd.depth(i), 10.0, 0.01)
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "pcdcodec",
            "encode",
            str(sample_dir()),
            "-o",
            str(out),
            "--max-frames",
            "1",
            "--overwrite",
            "--depth",
            "depthac:max_rel_error=2",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode != 0
    assert "max_rel_error" in bad.stderr


def test_fitted_levels_are_few_and_land_on_sensor_values() -> None:
    # Values 1000, 1004, 1100 at 0.5 %: 1000 and 1004 share a level (within 5), 1100 alone
    # keeps its own value; 10 is below one unit of bound and stays exact.
    image = np.array([[1000, 1004, 1100, 0, 10]], dtype=np.uint16)
    fitted = frame_levels(image, ErrorBound(0.0, 0.005))
    assert fitted is not None
    levels, count = fitted
    assert count == 3
    assert levels[0, 0] == levels[0, 1]
    assert abs(int(levels[0, 0]) - 1000) <= 5
    assert abs(int(levels[0, 1]) - 1004) <= 5
    assert levels[0, 2] == 1100
    assert levels[0, 3] == 0
    assert levels[0, 4] == 10


_SETTINGS = {"max_examples": 60, "deadline": None}


@given(
    image=hnp.arrays(np.uint16, st.tuples(st.integers(1, 24), st.integers(1, 24))),
    max_error=st.sampled_from([None, 0.0, 0.4, 1.0, 3.0, 250.0]),
    max_rel_error=st.sampled_from([None, 0.0, 0.001, 0.005, 0.01, 0.2, 0.9]),
    near=st.integers(0, 3),
)
@settings(**_SETTINGS)
def test_any_uint16_image_keeps_any_bound(
    image: np.ndarray[Any, Any], max_error: Any, max_rel_error: Any, near: int
) -> None:
    saved = DepthAC.bounded_near
    DepthAC.bounded_near = near
    try:
        codec = DepthAC(max_error=max_error, max_rel_error=max_rel_error)
        assert_within_bound(image, codec.decode(codec.encode(image)), max_error, max_rel_error)
    finally:
        DepthAC.bounded_near = saved


@given(
    image=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 16), st.integers(1, 16)),
        elements=st.one_of(
            st.just(np.nan),
            st.floats(0.0625, 80.0, width=32),
            st.floats(2.0**-100, 2.0**100, width=32),
        ),
    ),
    max_error=st.sampled_from([None, 0.0, 1e-6, 0.003, 0.5]),
    max_rel_error=st.sampled_from([None, 0.001, 0.01, 0.3]),
)
@settings(**_SETTINGS)
def test_any_float32_image_keeps_any_bound(
    image: np.ndarray[Any, Any], max_error: Any, max_rel_error: Any
) -> None:
    codec = Zstd(max_error=max_error, max_rel_error=max_rel_error)
    back = codec.decode(codec.encode(image))
    assert_within_bound(image, back, max_error, max_rel_error)


def test_error_bound_is_public_on_every_depth_codec() -> None:
    from pcdcodec.registry import get_codec

    assert get_codec("depthac").error_bound is None
    bound = get_codec({"id": "depthac", "max_error": 3}).error_bound
    assert bound is not None
    assert bound == ErrorBound(3.0, 0.0)
