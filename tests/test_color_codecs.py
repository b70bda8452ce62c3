"""Every color stream codec that opens on this machine, tested through the registry."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color import Packet, StreamCodec, decode_packets, encode_frames
from pcdcodec.datasets import load_sample
from pcdcodec.metrics import psnr

from .conftest import SHARED_SEQUENCES, load_colors

ALL_COLOR = pcdcodec.list_codecs("color")
STREAM = [
    n
    for n in pcdcodec.list_codecs("color", available_only=True)
    if issubclass(pcdcodec.codec_class(n), StreamCodec)
]
LOSSLESS = [n for n in STREAM if pcdcodec.codec_class(n).lossless]
LOSSY = [n for n in STREAM if not pcdcodec.codec_class(n).lossless]

#: Mean RGB PSNR (dB) each lossy codec clears with its defaults on the bundled sample. Measured
#: values are 1.5–2 dB higher (docs/codecs.md); the sample's noisy Kinect v1 color and 4:2:0
#: chroma cap any 4:2:0 codec near 39 dB.
PSNR_FLOOR = {"h264": 32.5, "h265": 32.0, "av1": 32.5, "vp9": 33.0, "mjpeg": 34.0, "mpeg4": 33.0}


def make(name: str, **params: Any) -> StreamCodec:
    codec = pcdcodec.get_codec(name, kind="color", **params)
    assert isinstance(codec, StreamCodec)
    return codec


@pytest.fixture(scope="module")
def sample() -> tuple[list[Any], list[int]]:
    seq = load_sample()
    return seq.colors, [f.timestamp_ns for f in seq]


def test_expected_codecs_are_registered() -> None:
    assert {
        "h264",
        "h265",
        "av1",
        "vp9",
        "mjpeg",
        "mpeg4",
        "ffv1",
        "huffyuv",
        "h264-lossless",
    } <= set(ALL_COLOR)
    assert {"h264", "ffv1", "h264-lossless"} <= set(STREAM)
    assert set(LOSSLESS) >= {"ffv1", "huffyuv", "ffvhuff", "h264-lossless"}
    assert "h264" in LOSSY
    assert pcdcodec.DEFAULT_COLOR_CODEC == "h264"


@pytest.mark.parametrize("name", STREAM)
def test_frames_and_timestamps_survive(name: str, sample: tuple[list[Any], list[int]]) -> None:
    frames, stamps = sample
    codec = make(name)
    packets, extradata = encode_frames(codec, frames, stamps)
    assert all(isinstance(p, Packet) and p.checksum is not None for p in packets)
    assert packets[0].keyframe
    assert sorted(p.pts for p in packets) == stamps
    decoded = decode_packets(codec, packets, 640, 480, extradata)
    assert len(decoded) == len(frames)
    assert [f.timestamp for f in decoded] == stamps
    for frame, original in zip(decoded, frames, strict=True):
        assert frame.rgb.shape == original.shape
        assert frame.rgb.dtype == np.uint8
        if codec.lossless:
            np.testing.assert_array_equal(frame.rgb, original)
    if not codec.lossless:
        mean_psnr = np.mean([psnr(f.rgb, o) for f, o in zip(decoded, frames, strict=True)])
        assert mean_psnr >= PSNR_FLOOR[name], f"{name}: {mean_psnr:.2f} dB"
        assert mean_psnr < 60  # lossy really is lossy: the test would notice a no-op


def test_every_lossy_codec_has_a_psnr_floor() -> None:
    assert set(LOSSY) <= set(PSNR_FLOOR)


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", SHARED_SEQUENCES)
@pytest.mark.parametrize("name", LOSSLESS)
def test_lossless_bit_exact_on_shared_sequences(name: str, sequence: str) -> None:
    frames = load_colors(sequence, 4)
    codec = make(name)
    packets, extradata = encode_frames(codec, frames)
    h, w = frames[0].shape[:2]
    decoded = decode_packets(codec, packets, w, h, extradata)
    assert len(decoded) == len(frames)
    for frame, original in zip(decoded, frames, strict=True):
        np.testing.assert_array_equal(frame.rgb, original)


@pytest.mark.shared_data
@pytest.mark.parametrize("sequence", SHARED_SEQUENCES)
def test_default_lossy_quality_on_shared_sequences(sequence: str) -> None:
    frames = load_colors(sequence, 6)
    codec = make(pcdcodec.DEFAULT_COLOR_CODEC)
    packets, extradata = encode_frames(codec, frames)
    h, w = frames[0].shape[:2]
    decoded = decode_packets(codec, packets, w, h, extradata)
    assert min(psnr(f.rgb, o) for f, o in zip(decoded, frames, strict=True)) > 30.0


def _with_short_gop(name: str) -> StreamCodec:
    params = make(name).param_names()
    return make(name, gop=4) if "gop" in params else make(name)


@pytest.mark.parametrize("name", STREAM)
def test_decoding_can_start_at_every_keyframe(
    name: str, sample: tuple[list[Any], list[int]]
) -> None:
    frames, stamps = sample
    codec = _with_short_gop(name)
    packets, extradata = encode_frames(codec, frames, stamps)
    full = {f.timestamp: f.rgb for f in decode_packets(codec, packets, 640, 480, extradata)}
    keys = [i for i, p in enumerate(packets) if p.keyframe]
    assert len(keys) >= 3  # a keyframe every 4 frames (or every frame)
    for k in keys:
        tail = decode_packets(codec, packets[k:], 640, 480, extradata)
        assert [f.timestamp for f in tail] == stamps[len(stamps) - len(tail) :]
        assert tail[0].timestamp == packets[k].pts
        for frame in tail:
            np.testing.assert_array_equal(frame.rgb, full[frame.timestamp])


def test_b_frames_keep_display_order(sample: tuple[list[Any], list[int]]) -> None:
    frames, stamps = sample
    codec = make("h264", bframes=2, gop=8)
    packets, extradata = encode_frames(codec, frames, stamps)
    assert [p.pts for p in packets] != sorted(p.pts for p in packets)  # reordered
    assert all(p.dts <= p.pts for p in packets)
    decoded = decode_packets(codec, packets, 640, 480, extradata)
    assert [f.timestamp for f in decoded] == stamps


@pytest.mark.parametrize("name", STREAM)
def test_odd_sizes_round_trip_without_resizing(name: str) -> None:
    base = load_sample(max_frames=1).colors[0]
    frames = [np.ascontiguousarray(base[i : i + 37, 5 + i : 5 + i + 51]) for i in range(3)]
    codec = make(name)
    packets, extradata = encode_frames(codec, frames)
    decoded = decode_packets(codec, packets, 51, 37, extradata)
    assert [f.rgb.shape for f in decoded] == [(37, 51, 3)] * 3
    if codec.lossless:
        for frame, original in zip(decoded, frames, strict=True):
            np.testing.assert_array_equal(frame.rgb, original)
    else:
        assert psnr(decoded[1].rgb, frames[1]) > 25


@pytest.mark.parametrize("name", STREAM)
def test_config_round_trips_through_json(name: str) -> None:
    codec = make(name)
    config = codec.get_config()
    assert config["id"] == name
    rebuilt = pcdcodec.get_codec(json.loads(json.dumps(config)))
    assert rebuilt == codec
    assert repr(rebuilt) == repr(codec)


# -- damaged input ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", STREAM)
def test_garbage_packets_raise_decode_error(name: str, sample: tuple[list[Any], list[int]]) -> None:
    frames, stamps = sample
    codec = make(name)
    packets, extradata = encode_frames(codec, frames[:3], stamps[:3])
    rng = np.random.default_rng(5)
    # Random bytes with a matching checksum: the decoder library must refuse them.
    garbage = Packet.create(rng.bytes(4000), 0, 0, True)
    decoder = codec.decoder(640, 480, extradata)

    def feed_garbage() -> None:
        decoder.decode(garbage)
        decoder.flush()

    with pytest.raises(pcdcodec.DecodeError, match=name):
        feed_garbage()
    # A damaged packet with its original checksum: the checksum catches it.
    damaged = bytearray(packets[0].data)
    damaged[len(damaged) // 2] ^= 0x10
    bad = Packet(bytes(damaged), packets[0].pts, packets[0].dts, True, packets[0].checksum)
    with pytest.raises(pcdcodec.DecodeError, match="corrupt"):
        codec.decoder(640, 480, extradata).decode(bad)
    with pytest.raises(pcdcodec.InputTypeError, match="bytes"):
        codec.decoder(640, 480, extradata).decode(bytes(damaged))  # type: ignore[arg-type]


# -- bad input ---------------------------------------------------------------------------------


@pytest.fixture
def h264_encoder() -> Any:
    return make("h264").encoder(64, 48, 30.0)


def frame(h: int = 48, w: int = 64, c: int = 3, dtype: Any = np.uint8) -> np.ndarray[Any, Any]:
    return np.zeros((h, w, c), dtype=dtype)


@pytest.mark.parametrize("dtype", ["float32", "uint16", "int64"])
def test_wrong_dtype_is_rejected(h264_encoder: Any, dtype: str) -> None:
    with pytest.raises(pcdcodec.InputTypeError, match=dtype):
        h264_encoder.encode(frame(dtype=dtype), 0)


def test_wrong_shapes_are_rejected(h264_encoder: Any) -> None:
    with pytest.raises(pcdcodec.InputError, match="RGBA"):
        h264_encoder.encode(frame(c=4), 0)
    with pytest.raises(pcdcodec.InputError, match=r"\(48, 64\)"):
        h264_encoder.encode(np.zeros((48, 64), np.uint8), 0)


def test_size_change_mid_stream_is_rejected(h264_encoder: Any) -> None:
    packets = h264_encoder.encode(frame(), 0)
    with pytest.raises(pcdcodec.InputError, match=r"64x48.*cannot change mid-stream"):
        h264_encoder.encode(frame(h=50), 1)
    # The stream itself is unharmed: it goes on and flushes.
    packets += h264_encoder.encode(frame(), 2)
    assert len(packets + h264_encoder.flush()) == 2


def test_timestamps_must_increase(h264_encoder: Any) -> None:
    h264_encoder.encode(frame(), 100)
    with pytest.raises(pcdcodec.InputError, match="timestamp 100 ns does not increase"):
        h264_encoder.encode(frame(), 100)
    with pytest.raises(pcdcodec.InputTypeError, match="float"):
        h264_encoder.encode(frame(), 200.5)


def test_encoding_after_flush_is_refused(h264_encoder: Any) -> None:
    h264_encoder.encode(frame(), 0)
    h264_encoder.flush()
    with pytest.raises(pcdcodec.InputError, match="flushed"):
        h264_encoder.encode(frame(), 1)


@pytest.mark.parametrize(
    ("name", "params", "match"),
    [
        ("h264", {"crf": 60}, "60"),
        ("h264", {"preset": "warp"}, "warp"),
        ("h264", {"pix_fmt": "rgb24"}, "rgb24"),
        ("h264", {"gop": 0}, "gop"),
        ("mjpeg", {"quality": 1}, "quality"),
        ("ffv1", {"level": 2}, "level"),
    ],
)
def test_bad_parameters_name_the_value(name: str, params: dict[str, Any], match: str) -> None:
    with pytest.raises(pcdcodec.InputError, match=match):
        pcdcodec.get_codec(name, **params)


@pytest.mark.parametrize("size", [(0, 48), (64, -1), (64, 20000)])
def test_bad_stream_sizes(size: tuple[int, int]) -> None:
    with pytest.raises(pcdcodec.InputError):
        make("h264").encoder(*size)


def test_unavailable_codecs_say_why() -> None:
    """GPU encoders are registered everywhere; where they cannot open, using them says so."""
    available = set(pcdcodec.list_codecs("color", available_only=True))
    unavailable = [n for n in ALL_COLOR if n not in available]
    for name in unavailable:
        codec = pcdcodec.get_codec(name)
        reason = codec.unavailable_reason()
        assert reason
        with pytest.raises(pcdcodec.CodecUnavailableError, match=name):
            codec.encoder(64, 48)  # type: ignore[attr-defined]
    assert {"h264-nvenc", "h265-nvenc"} <= set(ALL_COLOR)


def test_keyframe_interval_says_where_a_stream_may_be_cut() -> None:
    from pcdcodec.registry import get_codec

    assert get_codec("mjpeg").keyframe_interval(30.0) == 1  # intra-only
    assert get_codec("huffyuv").keyframe_interval(30.0) == 1
    assert get_codec({"id": "h264", "gop": 12}).keyframe_interval(30.0) == 12
    # The default: a third of a second of frames.
    assert get_codec("h264").keyframe_interval(30.0) == 10
    assert get_codec("h264").keyframe_interval(15.0) == 5
    assert get_codec("h264").keyframe_interval(1.0) == 1
