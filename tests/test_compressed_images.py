"""Structure checks of JPEG and PNG images (pcdcodec.color.images)."""

from __future__ import annotations

import imagecodecs
import numpy as np
import pytest

import pcdcodec
from pcdcodec.color.images import check_compressed, image_header
from pcdcodec.errors import DecodeError


@pytest.fixture(scope="module")
def images() -> dict[str, bytes]:
    frame = pcdcodec.load_sample(max_frames=1)[0]
    assert frame.color is not None
    color = np.ascontiguousarray(frame.color)
    depth = frame.depth
    return {
        "jpeg rgb": bytes(imagecodecs.jpeg8_encode(color, level=90)),
        "jpeg gray": bytes(imagecodecs.jpeg8_encode(np.ascontiguousarray(color[..., 1]))),
        "png rgb": bytes(imagecodecs.png_encode(color)),
        "png16": bytes(imagecodecs.png_encode(depth)),
    }


@pytest.mark.parametrize("name", ["jpeg rgb", "jpeg gray", "png rgb", "png16"])
def test_whole_images_pass_with_their_size(images, name):  # type: ignore[no-untyped-def]
    header = check_compressed(images[name], "img", (480, 640))
    assert (header.width, header.height) == (640, 480)
    assert header.format == name.split()[0].rstrip("16")
    assert header.bits == (16 if name == "png16" else 8)


@pytest.mark.parametrize("name", ["jpeg rgb", "jpeg gray", "png rgb", "png16"])
def test_every_cut_is_refused(images, name):  # type: ignore[no-untyped-def]
    data = images[name]
    for cut in range(1, len(data), max(1, len(data) // 200)):
        with pytest.raises(DecodeError, match="img"):
            image_header(data[:cut], "img")


def test_a_wrong_size_is_refused_before_decoding(images):  # type: ignore[no-untyped-def]
    with pytest.raises(DecodeError, match="declares 640x480 pixels, expected 320x240"):
        check_compressed(images["jpeg rgb"], "img", (240, 320))


def test_a_damaged_png_chunk_is_refused(images):  # type: ignore[no-untyped-def]
    data = bytearray(images["png16"])
    data[len(data) // 2] ^= 0x10
    with pytest.raises(DecodeError, match="fails its CRC"):
        image_header(bytes(data), "img")


def test_a_jpeg_bomb_declares_its_size(images):  # type: ignore[no-untyped-def]
    data = bytearray(images["jpeg gray"])
    sof = data.find(b"\xff\xc0")
    data[sof + 5 : sof + 9] = (30000).to_bytes(2, "big") * 2
    header = image_header(bytes(data), "img")
    assert (header.width, header.height) == (30000, 30000)
    assert header.decoded_bytes == 900_000_000


def test_other_data_is_refused() -> None:
    with pytest.raises(DecodeError, match="neither JPEG nor PNG"):
        image_header(b"GIF89a....", "img")
