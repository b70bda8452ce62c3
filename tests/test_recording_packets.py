"""Packets in both directions: Recording.packets()/depth_bytes()/keyframes/extradata out, and
RecordingWriter.write_encoded() in, with no encoder opened."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.color.base import Packet, StreamCodec
from pcdcodec.errors import InputError, InputTypeError


def _record(path: Path, color: str, frames: int = 6) -> Any:
    seq = pcdcodec.load_sample(max_frames=frames)
    with pcdcodec.open(path, "w", intrinsics=seq.intrinsics, depth_scale=5000.0, color=color) as w:
        w.write_frames(seq)
    return seq


def _groups(rec: Any) -> list[list[Packet]]:
    """Each frame's packets: a packet goes with the latest frame (display order) reached so far
    in decode order."""
    frame_of = {int(t): i for i, t in enumerate(rec.timestamps)}
    groups: list[list[Packet]] = [[] for _ in range(len(rec))]
    current = 0
    for packet in rec.packets(rec.keyframes[0]):
        current = max(current, frame_of.get(packet.pts, current))
        groups[current].append(packet)
    return groups


@pytest.mark.parametrize("color", ["h264", "ffv1"])
def test_remux_through_write_encoded_is_identical(tmp_path: Path, color: str) -> None:
    src = tmp_path / "a.pcdc"
    _record(src, color)
    dst = tmp_path / "b.pcdc"
    with pcdcodec.open(src) as rec:
        assert rec.keyframes[0] == 0
        assert len(rec.packet_timestamps) == len(rec)
        assert (rec.extradata is not None) == (color == "ffv1")
        with pcdcodec.open(
            dst, "w", intrinsics=rec.intrinsics, depth_scale=rec.depth_scale,
            color=rec.codecs["color"], depth=rec.codecs["depth"],
        ) as w:  # fmt: skip
            for i, group in enumerate(_groups(rec)):
                w.write_encoded(
                    group, rec.depth(i), int(rec.timestamps[i]), extradata=rec.extradata
                )
        original = list(rec)
        depth_bytes = [rec.depth_bytes(i) for i in range(len(rec))]
        packets = [p.data for p in rec.packets()]
        keyframes, extradata = rec.keyframes, rec.extradata
    with pcdcodec.open(dst) as back:
        assert [p.data for p in back.packets()] == packets
        assert back.keyframes == keyframes
        assert back.extradata == extradata
        for i, (a, b) in enumerate(zip(back, original, strict=True)):
            assert a.timestamp_ns == b.timestamp_ns
            assert np.array_equal(a.color, b.color)
            assert np.array_equal(a.depth, b.depth)
            assert back.depth_bytes(i) == depth_bytes[i]
            assert pcdcodec.decode_depth(depth_bytes[i]).tobytes() == b.depth.tobytes()


def test_write_encoded_needs_no_encoder_and_rejects_mixing(tmp_path: Path) -> None:
    src = tmp_path / "a.pcdc"
    seq = _record(src, "h264", frames=3)
    with pcdcodec.open(src) as rec:
        packets = list(rec.packets())
    # A codec whose encoder cannot open here (NVENC on a machine without a GPU) still records.
    nvenc = pcdcodec.codec_class("h264-nvenc", "color")
    w = pcdcodec.open(
        tmp_path / "n.pcdc", "w", intrinsics=seq.intrinsics, depth_scale=5000.0, color=nvenc()
    )
    with w:
        for p, f in zip(packets, seq, strict=True):
            w.write_encoded([p], f.depth, f.timestamp_ns)
        with pytest.raises(InputError, match=r"cannot take packets too|takes encoded color"):
            w.write(seq[0].color, seq[0].depth, seq[-1].timestamp_ns + 1)
        with pytest.raises(InputTypeError, match="packet 0 is a bytes"):
            w.write_encoded([b"raw"], seq[0].depth, seq[-1].timestamp_ns + 2)  # type: ignore[list-item]
    with pcdcodec.open(tmp_path / "n.pcdc") as rec:
        assert rec.codecs["color"]["id"] == "h264-nvenc"  # type: ignore[index]
        assert [p.data for p in rec.packets()] == [p.data for p in packets]
        assert np.array_equal(rec.depth(1), seq[1].depth)
    with (
        pcdcodec.open(tmp_path / "m.pcdc", "w", intrinsics=seq.intrinsics, color=None) as w2,
        pytest.raises(InputError, match="no color codec"),
    ):
        w2.write_encoded(packets[:1], seq[0].depth, 0)


def test_video_format_is_declared_on_every_stream_codec() -> None:
    assert StreamCodec.video_format is None
    for name in pcdcodec.list_codecs("color"):
        cls = pcdcodec.codec_class(name, "color")
        if issubclass(cls, StreamCodec):
            assert cls.video_format in (None, "h264", "h265", "av1", "vp9"), name
    assert pcdcodec.codec_class("h264", "color").video_format == "h264"
    assert pcdcodec.codec_class("ffv1", "color").video_format is None
