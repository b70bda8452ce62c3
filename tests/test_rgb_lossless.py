"""The lossless RGB coder of kept colour images and clouds (:mod:`pcdcodec.color.rgb_lossless`):
bit-exact whatever the image, a camera's Bayer pattern found and used, damage refused."""

from __future__ import annotations

from typing import Any

import imagecodecs
import numpy as np
import pytest

from pcdcodec.color import rgb_lossless as rl
from pcdcodec.datasets import load_sample

from .conftest import SEQUENCES


def _bayer_image(rng: Any, h: int, w: int, phase: int, rule: int) -> Any:
    """A smooth scene seen through a Bayer filter and demosaiced by ``rule``."""
    yy, xx = np.mgrid[0:h, 0:w]
    base = 120 + 60 * np.sin(xx / 9.0) * np.cos(yy / 13.0)
    mosaic = np.clip(base + rng.normal(0, 6, (h, w)), 0, 255).astype(np.uint8)
    return rl._rebuild(mosaic, phase >> 1, phase & 1, rule)


@pytest.mark.parametrize("phase", [0, 1, 2, 3])
@pytest.mark.parametrize("rule", [0, 1, 2])
def test_a_demosaiced_image_is_coded_as_its_bayer_pattern(phase: int, rule: int) -> None:
    rng = np.random.default_rng(phase * 3 + rule)
    rgb = _bayer_image(rng, 96, 128, phase, rule)
    assert rl.model_of(rgb) == (1, phase, rule)
    data = rl.encode(rgb)
    assert np.array_equal(rl.decode(data, (96, 128)), rgb)
    planar = rl.encode(rgb[:, :-2])  # an even width still, but the pattern's columns shifted
    assert np.array_equal(rl.decode(planar, (96, 126)), rgb[:, :-2])
    # a third of the values are measured: well under the planar model's bytes
    g = rgb[..., 1]
    planes = np.vstack([g, rgb[..., 0] - g, rgb[..., 2] - g])
    assert len(data) < 0.6 * len(imagecodecs.jpegls_encode(planes))


@pytest.mark.parametrize("order", [0, 1])
def test_a_yuy2_image_is_coded_as_its_luma_and_shared_chroma(order: int) -> None:
    """Pixel pairs converted from YUY2 the way librealsense converts them (RealSense color),
    red first or blue first (bgr8): coded as luma and one chroma pair per two pixels."""
    rng = np.random.default_rng(20 + order)
    h, w = 64, 96
    yy, xx = np.mgrid[0:h, 0:w]
    luma = np.clip(120 + 50 * np.sin(xx / 7.0) + rng.normal(0, 3, (h, w)), 0, 255)
    chroma = np.clip(128 + 20 * np.cos(yy[:, : w // 2] / 11.0), 0, 255)
    chroma = np.concatenate([chroma, 255 - chroma], axis=1)  # U, then V
    rgb = np.empty((h, w, 3), np.uint8)
    rl._yuy2_rebuild(luma.astype(np.uint8), chroma.astype(np.uint8), 2 * order, 2 - 2 * order, rgb)
    assert rl.model_of(rgb) == (2, order, 0)
    data = rl.encode(rgb, check=True)
    assert np.array_equal(rl.decode(data, (h, w)), rgb)
    g = rgb[..., 1]
    planes = np.vstack([g, rgb[..., 0] - g, rgb[..., 2] - g])
    assert len(data) < len(imagecodecs.jpegls_encode(planes))


def test_pixels_the_pattern_misses_come_back_from_the_residual() -> None:
    rng = np.random.default_rng(7)
    rgb = _bayer_image(rng, 256, 128, 1, 0)
    spots = rng.integers(0, 128, (40, 2)) * [2, 1]
    rgb[spots[:, 0], spots[:, 1]] ^= np.uint8(0x55)  # pixels off the pattern, and borders
    assert rl.model_of(rgb)[0] == 1
    data = rl.encode(rgb)
    assert np.array_equal(rl.decode(data, (256, 128)), rgb)


def test_tum_frames_are_a_third_of_jpeg_xl() -> None:
    """The bundled TUM frames (a Kinect v1 through the OpenNI driver) are found to be
    demosaiced, and take well under half of lossless JPEG XL's bytes (0.39-0.40 measured)."""
    for frame in load_sample(3):
        rgb = np.asarray(frame.color)
        assert rl.model_of(rgb)[0] == 1
        data = rl.encode(rgb)
        assert np.array_equal(rl.decode(data, rgb.shape[:2]), rgb)
        jxl = imagecodecs.jpegxl_encode(rgb, lossless=True, effort=1)
        assert len(data) < 0.5 * len(jxl)


@pytest.mark.parametrize(
    ("name", "model", "share"), [("realsense_d435", 2, 0.7), ("7scenes_redkitchen", 0, 1.0)]
)
def test_other_cameras_frames_come_back_exactly_and_smaller(
    name: str, model: int, share: float
) -> None:
    """RealSense color (YUY2 converted by librealsense) takes 0.55 of lossless JPEG XL's
    bytes (measured); 7-Scenes (JPEG-decoded) 0.87, by the planar model."""
    seq = SEQUENCES.get(name)
    if seq is None or not seq.present:
        pytest.skip(f"{name} is not in ../shared/data")
    from pcdcodec.bench.sequences import load_colors

    for rgb in load_colors(name, 20)[::5]:
        assert rl.model_of(rgb)[0] == model
        data = rl.encode(rgb)
        assert np.array_equal(rl.decode(data, rgb.shape[:2]), rgb)
        jxl = imagecodecs.jpegxl_encode(rgb, lossless=True, effort=1)
        assert len(data) < share * len(jxl)


@pytest.mark.parametrize("shape", [(1, 1), (3, 5), (7, 8), (8, 7), (8, 8), (31, 33), (2, 640)])
@pytest.mark.parametrize("fill", ["noise", "zeros", "full", "gradient"])
def test_any_image_comes_back_bit_exact(shape: tuple[int, int], fill: str) -> None:
    rng = np.random.default_rng(sum(shape))
    h, w = shape
    rgb = {
        "noise": rng.integers(0, 256, (h, w, 3), dtype=np.uint8),
        "zeros": np.zeros((h, w, 3), np.uint8),
        "full": np.full((h, w, 3), 255, np.uint8),
        "gradient": (np.arange(h * w * 3) % 256).astype(np.uint8).reshape(h, w, 3),
    }[fill]
    assert np.array_equal(rl.decode(rl.encode(rgb), shape), rgb)
    bgr = rgb[..., ::-1]  # a strided view
    assert np.array_equal(rl.decode(rl.encode(bgr), shape), bgr)


def test_what_is_not_an_rgb_image_is_refused() -> None:
    for bad in (np.zeros((4, 4), np.uint8), np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 3))):
        with pytest.raises(ValueError, match="expected an H x W x 3 uint8 image"):
            rl.encode(bad)


def test_damaged_data_is_a_value_error_never_wrong_pixels() -> None:
    rng = np.random.default_rng(11)
    for rgb in (_bayer_image(rng, 32, 48, 2, 0), rng.integers(0, 256, (32, 48, 3), np.uint8)):
        data = rl.encode(rgb)
        with pytest.raises(ValueError, match=r"expected \(30, 48\)"):
            rl.decode(data, (30, 48))
        cases = [data[:n] for n in rng.integers(0, len(data), 40)] + [data + b"\0"]
        for pos in rng.integers(0, len(data), 300):
            cases.append(data[:pos] + bytes([data[pos] ^ (1 << int(pos % 8))]) + data[pos + 1 :])
        for damaged in cases:
            try:
                back = rl.decode(damaged, (32, 48))
            except ValueError:
                continue
            # JPEG-LS has no checksum: a flipped bit can decode; the packed message's CRC-32
            # is what catches it (tests/test_kept_compressed.py). The shape always holds.
            assert back.shape == (32, 48, 3)
            assert back.dtype == np.uint8
