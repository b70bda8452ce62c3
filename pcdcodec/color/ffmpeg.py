"""FFmpeg through PyAV: the encoder and decoder that every PyAV color codec runs on.

:mod:`.pyav` defines the codecs (their parameters, configs and availability) and hands each
stream an :class:`FFmpegSetup`; this module opens FFmpeg with it. It is loaded when a codec is
probed or a stream is started, not by ``import pcdcodec``, and imports PyAV only inside its
functions, so it loads where PyAV is missing.

Encoder input is RGB24; the conversion to the codec's pixel format (BT.601, limited range for
the YUV formats) happens inside FFmpeg's swscale. Frames whose size the pixel format cannot
hold are padded by repeating the last row or column, and the decoder crops them back.
"""

from __future__ import annotations

import functools
import importlib.util
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from ..errors import CodecUnavailableError, DecodeError
from .base import (
    DecodedFrame,
    DecodedPicture,
    Packet,
    StreamCodec,
    VideoDecoder,
    VideoEncoder,
    default_keyframe_interval,
)

__all__ = ["FFmpegDecoder", "FFmpegEncoder", "FFmpegSetup", "ffmpeg_packet", "probe"]


def _context(name: str, mode: Literal["r", "w"]) -> Any:
    """An FFmpeg codec context (typed loosely: PyAV's stubs are narrower than its objects)."""
    import av

    return av.CodecContext.create(name, mode)


def ffmpeg_packet(data: bytes | bytearray | memoryview) -> Any:
    """An ``av.Packet`` holding a copy of ``data`` in memory that FFmpeg allocated and owns.

    ``av.Packet(data)`` would lend FFmpeg the Python object's memory, released through a
    callback that takes the GIL. Threaded codecs (dav1d, frame-threaded decoders, muxers)
    release packets on their own worker threads, and one that does so while the main thread
    holds the GIL and waits for those workers (``avcodec_free_context`` -> ``dav1d_flush``)
    deadlocks the process. A packet FFmpeg owns is freed without Python, on any thread.
    """
    import av

    size = len(memoryview(data).cast("B"))
    packet = av.Packet(size)
    if size:
        memoryview(packet)[:] = memoryview(data).cast("B")
    return packet


@functools.cache
def probe(
    encoder: str, decoder: str, pix_fmt: str, options: tuple[tuple[str, str], ...]
) -> str | None:
    """Why ``encoder``/``decoder`` cannot run here (``None`` when they can); opened once."""
    if importlib.util.find_spec("av") is None:
        return "PyAV is not installed"
    modes: tuple[tuple[str, Literal["r", "w"]], ...] = ((encoder, "w"), (decoder, "r"))
    for name, mode in modes:
        try:
            ctx = _context(name, mode)
        except Exception:
            return f"this FFmpeg build has no {name!r} {'encoder' if mode == 'w' else 'decoder'}"
        if mode == "w":
            ctx.width, ctx.height, ctx.pix_fmt = 256, 256, pix_fmt
            ctx.time_base = Fraction(1, 30)
            ctx.options = dict(options)
            try:
                ctx.open()
            except Exception as exc:  # e.g. NVENC without an NVIDIA GPU and driver
                return f"the {name!r} encoder does not open here ({exc})"
    return None


@dataclass(frozen=True)
class FFmpegSetup:
    """What a PyAV codec opens FFmpeg with (built by ``PyAVCodec``)."""

    #: libavcodec encoder and decoder names.
    encoder_name: str
    decoder_name: str
    pix_fmt: str
    #: Multiples the width and height are padded to for :attr:`pix_fmt`.
    pad: tuple[int, int]
    threads: int
    #: Keyframe interval in frames; ``None``: the default (a third of a second of frames).
    gop: int | None
    bframes: int
    options: dict[str, str]
    decoder_options: dict[str, str]

    def padded(self, width: int, height: int) -> tuple[int, int]:
        """``width`` and ``height`` padded up to the multiples :attr:`pix_fmt` needs."""
        mx, my = self.pad
        return -(-width // mx) * mx, -(-height // my) * my


class FFmpegEncoder(VideoEncoder):
    """The encoder of a PyAV codec: RGB frames in, packets with nanosecond timestamps out."""

    def __init__(
        self, codec: StreamCodec, setup: FFmpegSetup, width: int, height: int, fps: float
    ) -> None:
        super().__init__(codec, width, height, fps)
        self._setup = setup
        self._pw, self._ph = setup.padded(self.width, self.height)
        rate = Fraction(self.fps).limit_denominator(1001)
        ctx = _context(setup.encoder_name, "w")
        ctx.width, ctx.height = self._pw, self._ph
        ctx.pix_fmt = setup.pix_fmt
        ctx.time_base = 1 / rate
        ctx.framerate = rate
        ctx.gop_size = setup.gop if setup.gop is not None else default_keyframe_interval(self.fps)
        ctx.max_b_frames = setup.bframes
        ctx.thread_count = setup.threads
        ctx.options = setup.options
        try:
            ctx.open()
        except Exception as exc:
            raise CodecUnavailableError(
                f"color codec {codec.name!r} ({setup.encoder_name}) could not open a "
                f"{self._pw}x{self._ph} {setup.pix_fmt} encoder: {exc}"
            ) from exc
        self._ctx = ctx
        self._stamps: dict[int, int] = {}
        self._interval = round(1e9 / self.fps)

    @property
    def extradata(self) -> bytes | None:
        data = self._ctx.extradata
        return bytes(data) if data else None

    def _to_ns(self, index: int | None) -> int:
        if index is None:
            raise DecodeError(f"{self.codec.name} encoder returned a packet without timestamps")
        if index in self._stamps:
            return self._stamps[index]
        first = min(self._stamps)  # negative dts before the first frame (B-frame delay)
        return self._stamps[first] + (index - first) * self._interval

    def _packets(self, av_packets: list[Any]) -> list[Packet]:
        out = []
        for p in av_packets:
            pts = self._to_ns(p.pts)
            dts = self._to_ns(p.dts if p.dts is not None else p.pts)
            out.append(Packet.create(bytes(p), pts, dts, bool(p.is_keyframe)))
            # Timestamps of frames long since shown are no longer needed.
            for old in [k for k in self._stamps if k < (p.dts or 0) - 64]:
                del self._stamps[old]
        return out

    def _encode(self, rgb: npt.NDArray[np.uint8], timestamp: int) -> list[Packet]:
        import av

        if (self._pw, self._ph) != (self.width, self.height):
            rgb = np.pad(
                rgb, ((0, self._ph - self.height), (0, self._pw - self.width), (0, 0)), mode="edge"
            )
        frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
        if self._setup.pix_fmt != "rgb24":
            frame = frame.reformat(format=self._setup.pix_fmt)
        frame.pts = self.frames_in
        self._stamps[self.frames_in] = timestamp
        return self._packets(self._ctx.encode(frame))

    def _flush(self) -> list[Packet]:
        return self._packets(self._ctx.encode(None))


class FFmpegDecoder(VideoDecoder):
    """The decoder of a PyAV codec: packets in, RGB frames cropped to the stream's size out."""

    def __init__(
        self,
        codec: StreamCodec,
        setup: FFmpegSetup,
        width: int,
        height: int,
        extradata: bytes | None,
    ) -> None:
        super().__init__(codec, width, height, extradata)
        self._pw, self._ph = setup.padded(self.width, self.height)
        ctx = _context(setup.decoder_name, "r")
        ctx.width, ctx.height = self._pw, self._ph
        if extradata:
            ctx.extradata = extradata
        # Slice threads only: frame threading delays output by a frame per thread, which costs
        # random access, and made MPEG-4 output vary between runs.
        ctx.thread_type = "SLICE"
        ctx.thread_count = setup.threads
        ctx.options = setup.decoder_options
        self._ctx = ctx

    def _rgb(self, frame: Any) -> npt.NDArray[np.uint8]:
        """One decoded picture as a new C-contiguous RGB image of the stream's size."""
        try:
            # PyAV returns a view of the frame's rows where they are padded (424 x 3 = 1272
            # bytes in lines of 1296): copy it into a C-contiguous image, cropped to the
            # camera's size where the codec needed a padded one. A no-op copy otherwise.
            rgb = frame.to_ndarray(format="rgb24")[: self.height, : self.width]
            return np.ascontiguousarray(rgb)
        except Exception as exc:
            raise DecodeError(
                f"{self.codec.name} could not convert the frame at pts {frame.pts} ns to RGB: "
                f"{type(exc).__name__}: {exc}"
            ) from exc

    def _pictures(self, av_frames: list[Any]) -> list[DecodedPicture]:
        out = []
        for f in av_frames:
            if (f.width, f.height) != (self._pw, self._ph):
                raise DecodeError(
                    f"{self.codec.name} decoded a {f.width}x{f.height} frame in a stream of "
                    f"{self._pw}x{self._ph}"
                )
            if f.pts is None:
                raise DecodeError(f"{self.codec.name} decoded a frame without a timestamp")
            # The picture keeps FFmpeg's reference-counted frame, which the decoder never
            # writes to again: converting it later gives what converting it now would.
            nbytes = sum(p.buffer_size for p in f.planes)
            out.append(DecodedPicture(int(f.pts), functools.partial(self._rgb, f), nbytes))
        return out

    def _run(self, packet: Any, pts: int | None) -> list[DecodedPicture]:
        try:
            return self._pictures(self._ctx.decode(packet))
        except DecodeError:
            raise
        except Exception as exc:
            where = f"packet at pts {pts} ns" if pts is not None else "end of stream"
            raise DecodeError(
                f"{self.codec.name} could not decode the {where}: {type(exc).__name__}: {exc}"
            ) from exc

    def _decode_pictures(self, packet: Packet) -> list[DecodedPicture]:
        avp = ffmpeg_packet(packet.data)
        avp.pts, avp.dts = packet.pts, packet.dts
        return self._run(avp, packet.pts)

    def _flush_pictures(self) -> list[DecodedPicture]:
        return self._run(None, None)

    def _decode(self, packet: Packet) -> list[DecodedFrame]:
        return [DecodedFrame(p.rgb(), p.timestamp) for p in self._decode_pictures(packet)]

    def _flush(self) -> list[DecodedFrame]:
        return [DecodedFrame(p.rgb(), p.timestamp) for p in self._flush_pictures()]
