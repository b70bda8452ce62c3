"""The ``depthac`` codec beyond the registry-wide tests: its modes, edge cases, hostile input."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench.sequences import ALL_DEPTH_SETS, load_frames, upsample_720p
from pcdcodec.depth import DepthAC, read_header

from .fuzzing import fuzz_frames, fuzz_images


def round_trip(image: np.ndarray[Any, Any]) -> bytes:
    codec = DepthAC()
    data = codec.encode(image)
    decoded = codec.decode(data)
    assert decoded.dtype == image.dtype
    view = np.uint32 if image.dtype.itemsize == 4 else np.uint16
    np.testing.assert_array_equal(decoded.view(view), np.ascontiguousarray(image).view(view))
    return data


def body_flags(data: bytes) -> int:
    return data[read_header(data).header_size]


@pytest.mark.parametrize("name", ALL_DEPTH_SETS)
def test_bit_exact_on_every_test_set(name: str) -> None:
    for depth in load_frames(name, 3):
        round_trip(depth)


def test_the_720p_set_repeats_each_pixel_of_the_centre_crop() -> None:
    depth = load_frames("sample", 1)[0]
    big = upsample_720p(depth)
    assert big.shape == (720, 1280)
    assert big.dtype == depth.dtype
    for dy in (0, 1):
        for dx in (0, 1):
            np.testing.assert_array_equal(big[dy::2, dx::2], depth[60:420])
    with pytest.raises(ValueError, match="640x480"):
        upsample_720p(big)


def test_sparse_frames_are_sparse_and_compress_better() -> None:
    dense = load_frames("sample", 2)
    sparse = load_frames("sample-sparse", 2)
    for d, s in zip(dense, sparse, strict=True):
        assert 0.45 < float(np.mean(s == 0)) < 0.75
        assert np.all((s == 0) | (s == d))  # only removes pixels
        assert len(round_trip(s)) < len(round_trip(d))


def test_smaller_than_jpegxl_on_the_sample() -> None:
    depths = load_frames("sample", 6)
    ours = sum(len(DepthAC().encode(d)) for d in depths)
    jxl = pcdcodec.get_codec("jpegxl")
    theirs = sum(len(jxl.encode(d)) for d in depths)
    assert theirs / ours > 1.3


def test_value_table_or_raw_values_per_frame() -> None:
    kinect = load_frames("sample", 1)[0]
    assert body_flags(round_trip(kinect)) & 1  # few distinct values: a table
    rng = np.random.default_rng(3)
    noise = rng.integers(1, 65536, size=(40, 50)).astype(np.uint16)
    assert not body_flags(round_trip(noise)) & 1  # all distinct: raw values
    assert body_flags(round_trip(noise)) & 2 == 0  # and no holes, so no mask


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((7, 9), np.uint16),
        np.full((5, 6), 65535, np.uint16),
        np.array([[1]], np.uint16),
        np.array([[0]], np.uint16),
        np.array([[65535, 0, 1, 65535, 0, 1]], np.uint16),
        np.arange(65536, dtype=np.uint16).reshape(256, 256),
        np.arange(65536, dtype=np.uint16)[::-1].reshape(64, 1024).copy(),
    ],
    ids=["zeros", "max", "one", "hole", "extremes", "ramp", "all-values"],
)
def test_edge_images(image: np.ndarray[Any, Any]) -> None:
    round_trip(image)
    round_trip(image.T.copy())


def test_holes_cost_little() -> None:
    depth = load_frames("sample", 1)[0]
    holes = depth.copy()
    holes[100:300, 200:500] = 0
    assert len(round_trip(holes)) < len(round_trip(depth))


def test_fuzzed_frames_raise_decode_error_or_decode_exactly() -> None:
    rng = np.random.default_rng(2024)
    images = fuzz_images(load_frames("sample", 4), rng, 10)
    images.append(load_frames("sample-sparse", 1)[0])
    outcome = fuzz_frames(DepthAC(), images, 2000, seed=7)
    assert sum(outcome.values()) == 2000
    assert sum(v for k, v in outcome.items() if not k.endswith(":exact")) > 1600


def test_corrupt_body_is_reported_as_such() -> None:
    depth = load_frames("sample", 1)[0]
    data = bytearray(DepthAC().encode(depth))
    start = read_header(bytes(data)).header_size
    data[start] = 0xF0  # unknown flag bits
    with pytest.raises(pcdcodec.DecodeError, match="flags"):
        DepthAC().decode(bytes(data))


@pytest.mark.parametrize("near", [1, 2, 5])
@pytest.mark.parametrize("name", ["tum_fr1_rpy", "realsense_d435-sparse", "spot"])
def test_kernel_near_mode_keeps_every_pixel_within_the_tolerance(name: str, near: int) -> None:
    from pcdcodec.depth import _depthac_kernels as kernels

    depth = load_frames(name, 1)[0]
    recon = np.zeros_like(depth)
    body = kernels.encode_image(depth, True, near, recon)
    assert body[0] & 1 == 0  # no value table in near mode
    lossless = kernels.encode_image(depth, False, 0, np.zeros((0, 0), np.uint16))
    assert len(body) < len(lossless)
    decoded = np.empty_like(depth)
    assert kernels.decode_image(body, decoded, near) == kernels.OK
    np.testing.assert_array_equal(decoded, recon)
    valid = depth > 0
    assert np.array_equal(decoded > 0, valid)  # holes stay holes, valid pixels stay valid
    error = np.abs(decoded[valid].astype(np.int64) - depth[valid])
    assert error.max() <= near
    assert error.max() > 0  # the tolerance was used
    wrong = np.empty_like(depth)
    status = kernels.decode_image(body, wrong, near + 1)
    assert status != kernels.OK or not np.array_equal(wrong, recon)


@pytest.mark.parametrize("shape", [(480, 640), (3, 4000), (4000, 3)])
def test_incompressible_frames_grow_the_output_buffer(shape: tuple[int, int]) -> None:
    # White noise over every value costs more than the 2 bytes per pixel reserved up front.
    noise = np.random.default_rng(5).integers(0, 65536, shape, dtype=np.uint16)
    data = round_trip(noise)
    assert len(data) > 2 * noise.size


def test_encoder_memory_is_a_few_frames_not_the_worst_case() -> None:
    import tracemalloc

    depth = load_frames("sample", 1)[0]
    codec = DepthAC()
    codec.encode(depth)  # compiled and loaded before measuring
    tracemalloc.start()
    codec.encode(depth)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 8 * depth.nbytes


def test_encoder_memory_stays_bounded_on_noise() -> None:
    # Noise makes up to 33 decisions a pixel; the encoder models and codes them a block at a
    # time, so its memory is about the body's size, not 2 bytes per decision.
    import tracemalloc

    noise = np.random.default_rng(5).integers(0, 65536, (512, 512)).astype(np.uint16)
    codec = DepthAC()
    codec.encode(noise[:8, :8].copy())  # compiled and loaded before measuring
    tracemalloc.start()
    body = codec.encode(noise)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert np.array_equal(codec.decode(body), noise)
    assert peak < 5 * len(body) + 4 * noise.nbytes


def test_compiled_loops_release_the_gil() -> None:
    # Recordings encode and decode depth on worker threads beside the video codec.
    from pcdcodec.depth import _depthac_kernels as kernels

    for kernel in (kernels.encode_image, kernels.decode_image):
        assert kernel.targetoptions.get("nogil") is True


def test_reused_working_arrays_never_leak_between_frames() -> None:
    """The decoder keeps its working arrays per thread and frame shape: a frame with holes after
    one without, a frame after a corrupt one, and frames of two shapes in turn all decode
    exactly, on one thread and on several."""
    import contextlib
    import threading

    codec = pcdcodec.get_codec("depthac")
    depth = load_frames("sample", 1)[0]
    full = np.where(depth > 0, depth, 4000).astype(np.uint16)
    small = np.ascontiguousarray(depth[100:220, 50:250])
    frames = [full, depth, small, full, small, depth]
    encoded = [codec.encode(f) for f in frames]
    corrupt = bytearray(encoded[1])
    corrupt[len(corrupt) // 2] ^= 0xFF

    def run(errors: list[str]) -> None:
        for k, (frame, data) in enumerate(zip(frames, encoded, strict=True)):
            if k == 3:
                with contextlib.suppress(pcdcodec.DecodeError):
                    codec.decode(bytes(corrupt))  # the kernel stops part way through
            if not np.array_equal(codec.decode(data), frame):
                errors.append(f"frame {k}")

    errors: list[str] = []
    run(errors)
    threads = [threading.Thread(target=run, args=(errors,)) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []


def test_working_arrays_of_the_wrong_size_are_refused() -> None:
    from pcdcodec.depth import _depthac_kernels as kernels

    depth = np.ascontiguousarray(load_frames("sample", 1)[0][:40, :60])
    body = np.frombuffer(pcdcodec.get_codec("depthac").encode(depth), np.uint8)
    header = read_header(body.tobytes())
    body = body[header.header_size :].copy()
    out = np.empty(depth.shape, np.uint16)
    good = np.zeros(kernels.working_size(40, 60), np.int64)
    table = np.empty(65536, np.int64)
    assert kernels.decode_into(body, out, 0, good, table) == kernels.OK
    assert np.array_equal(out, depth)
    short = np.zeros(good.size - 1, np.int64)
    assert kernels.decode_into(body, out, 0, short, table) == kernels.ERR_ARRAYS
    assert kernels.decode_into(body, out, 0, good, table[:100]) == kernels.ERR_ARRAYS


def test_reused_working_arrays_encode_the_same_bytes() -> None:
    """Frames coded one after another with this thread's kept arrays give the bytes of a coder
    with fresh ones, whatever came before (holes where the last frame had none, other shapes,
    bounded coding)."""
    from pcdcodec.depth import _depthac_kernels as kernels

    depth = load_frames("sample", 1)[0]
    full = np.where(depth > 0, depth, 4000).astype(np.uint16)
    small = np.ascontiguousarray(depth[100:220, 50:250])
    codec = pcdcodec.get_codec("depthac")
    bounded = pcdcodec.get_codec("depthac", max_error=3)
    for frame in [full, depth, small, full, depth, small]:
        data = codec.encode(frame)
        header = read_header(data)
        fresh = kernels.encode_image(frame, True, 0, np.zeros((0, 0), np.uint16))
        assert data[header.header_size :] == fresh.tobytes()
        assert np.array_equal(codec.decode(data), frame)
        back = bounded.decode(bounded.encode(frame))
        valid = frame > 0
        assert np.array_equal(back > 0, valid)
        assert np.abs(back.astype(np.int64) - frame)[valid].max() <= 3
