"""Color codecs through PyAV (FFmpeg's libavcodec): H.264, H.265, AV1, VP9, MJPEG, MPEG-4,
and the lossless FFV1, HuffYUV, FFVHuff and H.264 RGB.

Every codec here works on packets without a container, so a recording can store them as it
likes and decoding can start at any keyframe. Encoder input is RGB24; the codec's pixel format
conversion (BT.601, limited range for the YUV formats) happens inside FFmpeg's swscale.

Pixel formats with chroma subsampling need even sizes (4:2:0 both, 4:2:2 the width): odd frames
are padded by repeating the last row or column, and the decoder crops them back. Nothing is
ever resized.
"""

from __future__ import annotations

import functools
import importlib.util
import os
from fractions import Fraction
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from .._validate import check_choice, check_int, check_number
from ..errors import CodecUnavailableError, DecodeError
from .base import DecodedFrame, Packet, StreamCodec, VideoDecoder, VideoEncoder

__all__ = [
    "AV1",
    "FFV1",
    "H264",
    "H264NVENC",
    "H265",
    "HEVCNVENC",
    "MJPEG",
    "MPEG4",
    "VP9",
    "FFVHuff",
    "H264Lossless",
    "HuffYUV",
    "PyAVCodec",
]

_INSTALL = "install PyAV with FFmpeg codecs (pip install av)"

# SVT-AV1 prints a banner to stderr for every encoder unless told otherwise; it reads this
# variable once, so it is set before the library is first used. A value set by the user wins.
os.environ.setdefault("SVT_LOG", "1")


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
def _probe(
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


class PyAVCodec(StreamCodec):
    """Base of the PyAV color codecs. Subclasses name the FFmpeg encoder and decoder."""

    #: libavcodec encoder and decoder names.
    encoder_name: ClassVar[str]
    decoder_name: ClassVar[str]
    #: The format name of Foxglove's CompressedVideo schema for this bitstream, if it has one.
    video_format: ClassVar[str | None] = None
    #: Pixel formats the codec may be asked for; the first is the default.
    pix_fmts: ClassVar[tuple[str, ...]] = ("yuv420p",)
    install_hint: ClassVar[str] = _INSTALL
    runtime_params: ClassVar[tuple[str, ...]] = ("threads",)

    pix_fmt: str
    threads: int

    #: Encoder options used when probing whether the encoder opens (to keep it quiet).
    probe_options: ClassVar[tuple[tuple[str, str], ...]] = ()

    @classmethod
    def unavailable_reason(cls) -> str | None:
        return _probe(cls.encoder_name, cls.decoder_name, cls.pix_fmts[0], cls.probe_options)

    # What subclasses decide.
    def _options(self) -> dict[str, str]:
        return {}

    def _decoder_options(self) -> dict[str, str]:
        return {}

    def _gop(self, fps: float) -> int:
        gop = getattr(self, "gop", None)
        return int(gop) if gop is not None else max(1, round(fps))

    def _bframes(self) -> int:
        return int(getattr(self, "bframes", 0))

    def _pad(self) -> tuple[int, int]:
        """Multiples the width and height must be padded to for :attr:`pix_fmt`."""
        if "420" in self.pix_fmt:
            return 2, 2
        if "422" in self.pix_fmt:
            return 2, 1
        return 1, 1

    def encoder(self, width: int, height: int, fps: float = 30.0) -> VideoEncoder:
        """Start a stream of ``width`` × ``height`` RGB frames at about ``fps`` frames/s.

        The keyframe interval defaults to one second of frames. Raises
        :class:`~pcdcodec.CodecUnavailableError` when the FFmpeg encoder cannot be opened.
        """
        self._require_available()
        return _PyAVEncoder(self, width, height, fps)

    def decoder(self, width: int, height: int, extradata: bytes | None = None) -> VideoDecoder:
        """Start decoding a ``width`` × ``height`` stream; pass the encoder's ``extradata``."""
        self._require_available()
        return _PyAVDecoder(self, width, height, extradata)


def _padded(size: int, multiple: int) -> int:
    return -(-size // multiple) * multiple


class _PyAVEncoder(VideoEncoder):
    codec: PyAVCodec

    def __init__(self, codec: PyAVCodec, width: int, height: int, fps: float) -> None:

        super().__init__(codec, width, height, fps)
        mx, my = codec._pad()
        self._pw, self._ph = _padded(self.width, mx), _padded(self.height, my)
        rate = Fraction(self.fps).limit_denominator(1001)
        ctx = _context(codec.encoder_name, "w")
        ctx.width, ctx.height = self._pw, self._ph
        ctx.pix_fmt = codec.pix_fmt
        ctx.time_base = 1 / rate
        ctx.framerate = rate
        ctx.gop_size = codec._gop(self.fps)
        ctx.max_b_frames = codec._bframes()
        ctx.thread_count = codec.threads
        ctx.options = codec._options()
        try:
            ctx.open()
        except Exception as exc:
            raise CodecUnavailableError(
                f"color codec {codec.name!r} ({codec.encoder_name}) could not open a "
                f"{self._pw}x{self._ph} {codec.pix_fmt} encoder: {exc}"
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
        if self.codec.pix_fmt != "rgb24":
            frame = frame.reformat(format=self.codec.pix_fmt)
        frame.pts = self.frames_in
        self._stamps[self.frames_in] = timestamp
        return self._packets(self._ctx.encode(frame))

    def _flush(self) -> list[Packet]:
        return self._packets(self._ctx.encode(None))


class _PyAVDecoder(VideoDecoder):
    codec: PyAVCodec

    def __init__(self, codec: PyAVCodec, width: int, height: int, extradata: bytes | None) -> None:

        super().__init__(codec, width, height, extradata)
        mx, my = codec._pad()
        self._pw, self._ph = _padded(self.width, mx), _padded(self.height, my)
        ctx = _context(codec.decoder_name, "r")
        ctx.width, ctx.height = self._pw, self._ph
        if extradata:
            ctx.extradata = extradata
        # Slice threads only: frame threading delays output by a frame per thread, which costs
        # random access, and made MPEG-4 output vary between runs.
        ctx.thread_type = "SLICE"
        ctx.thread_count = codec.threads
        ctx.options = codec._decoder_options()
        self._ctx = ctx

    def _frames(self, av_frames: list[Any]) -> list[DecodedFrame]:
        out = []
        for f in av_frames:
            if (f.width, f.height) != (self._pw, self._ph):
                raise DecodeError(
                    f"{self.codec.name} decoded a {f.width}x{f.height} frame in a stream of "
                    f"{self._pw}x{self._ph}"
                )
            if f.pts is None:
                raise DecodeError(f"{self.codec.name} decoded a frame without a timestamp")
            # PyAV returns a view of the frame's rows where they are padded (424 x 3 = 1272
            # bytes in lines of 1296): copy it into a C-contiguous image, cropped to the
            # camera's size where the codec needed a padded one. A no-op copy otherwise.
            rgb = np.ascontiguousarray(f.to_ndarray(format="rgb24")[: self.height, : self.width])
            out.append(DecodedFrame(rgb, int(f.pts)))
        return out

    def _run(self, packet: Any, pts: int | None) -> list[DecodedFrame]:
        try:
            return self._frames(self._ctx.decode(packet))
        except DecodeError:
            raise
        except Exception as exc:
            where = f"packet at pts {pts} ns" if pts is not None else "end of stream"
            raise DecodeError(
                f"{self.codec.name} could not decode the {where}: {type(exc).__name__}: {exc}"
            ) from exc

    def _decode(self, packet: Packet) -> list[DecodedFrame]:
        avp = ffmpeg_packet(packet.data)
        avp.pts, avp.dts = packet.pts, packet.dts
        return self._run(avp, packet.pts)

    def _flush(self) -> list[DecodedFrame]:
        return self._run(None, None)


# -- lossy codecs ------------------------------------------------------------------------------

_X26X_PRESETS = (
    "ultrafast",
    "superfast",
    "veryfast",
    "faster",
    "fast",
    "medium",
    "slow",
    "slower",
    "veryslow",
)


def _x264_tune(tune: str | None, low_delay: bool) -> str | None:
    """x264's tune string: one psy tuning and zerolatency may be combined ("film,zerolatency")."""
    if not low_delay or tune == "zerolatency":
        return tune
    return f"{tune},zerolatency" if tune else "zerolatency"


class H264(PyAVCodec):
    """H.264 through libx264: the default color codec.

    ``crf`` is the constant rate factor (0–51, lower is better; 18 is about visually
    lossless), ``preset`` the speed/size trade-off, ``tune`` an optional x264 tuning
    (``film``, ``grain``, ``stillimage``, …), ``gop`` the keyframe interval in frames (default:
    one second), ``bframes`` the number of B-frames (0 keeps decode order = display order),
    ``pix_fmt`` ``yuv420p`` (most compatible) or ``yuv444p`` (full chroma). ``low_delay``
    (the default) adds x264's ``zerolatency`` tuning: no lookahead and sliced threads, so every
    frame's packet comes out as it goes in and a crash loses no frame the encoder held back;
    ``False`` lets x264 hold about a dozen frames for a file a few percent smaller at most
    (see ``docs/format.md``).
    """

    video_format: ClassVar[str | None] = "h264"
    name: ClassVar[str] = "h264"
    encoder_name: ClassVar[str] = "libx264"
    decoder_name: ClassVar[str] = "h264"
    pix_fmts: ClassVar[tuple[str, ...]] = ("yuv420p", "yuv444p")

    def __init__(
        self,
        *,
        crf: float = 18,
        preset: str = "veryfast",
        tune: str | None = None,
        gop: int | None = None,
        bframes: int = 0,
        pix_fmt: str = "yuv420p",
        threads: int = 0,
        low_delay: bool = True,
    ) -> None:
        check_number(self.name, "crf", crf, 0, 51)
        check_choice(self.name, "preset", preset, _X26X_PRESETS)
        check_choice(self.name, "low_delay", low_delay, (True, False))
        check_choice(
            self.name,
            "tune",
            tune,
            (
                None,
                "film",
                "animation",
                "grain",
                "stillimage",
                "psnr",
                "ssim",
                "fastdecode",
                "zerolatency",
            ),
        )
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "bframes", bframes, 0, 16)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        check_int(self.name, "threads", threads, 0, 64)
        self.crf, self.preset, self.tune = crf, preset, tune
        self.gop, self.bframes, self.pix_fmt, self.threads = gop, bframes, pix_fmt, threads
        self.low_delay = low_delay

    def _options(self) -> dict[str, str]:
        opts = {"crf": str(self.crf), "preset": self.preset}
        tune = _x264_tune(self.tune, self.low_delay)
        if tune:
            opts["tune"] = tune
        return opts


class H265(PyAVCodec):
    """H.265/HEVC through libx265: smaller than H.264 at equal quality, slower to encode.

    ``low_delay`` (the default) selects x265's ``zerolatency`` tuning, so the encoder holds no
    frames back (with B-frames, only as many as a B-frame run); ``False`` lets it keep a
    lookahead of several frames.
    """

    video_format: ClassVar[str | None] = "h265"
    name: ClassVar[str] = "h265"
    encoder_name: ClassVar[str] = "libx265"
    decoder_name: ClassVar[str] = "hevc"
    pix_fmts: ClassVar[tuple[str, ...]] = ("yuv420p", "yuv444p")
    probe_options: ClassVar[tuple[tuple[str, str], ...]] = (("x265-params", "log-level=error"),)

    def __init__(
        self,
        *,
        crf: float = 24,
        preset: str = "ultrafast",
        gop: int | None = None,
        bframes: int = 0,
        pix_fmt: str = "yuv420p",
        threads: int = 0,
        low_delay: bool = True,
    ) -> None:
        check_number(self.name, "crf", crf, 0, 51)
        check_choice(self.name, "preset", preset, _X26X_PRESETS)
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "bframes", bframes, 0, 16)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        check_int(self.name, "threads", threads, 0, 64)
        check_choice(self.name, "low_delay", low_delay, (True, False))
        self.crf, self.preset, self.gop, self.bframes = crf, preset, gop, bframes
        self.pix_fmt, self.threads, self.low_delay = pix_fmt, threads, low_delay

    def _options(self) -> dict[str, str]:
        opts = {
            "crf": str(self.crf),
            "preset": self.preset,
            "x265-params": "log-level=error:repeat-headers=1",
        }
        if self.low_delay and self.bframes == 0:
            opts["tune"] = "zerolatency"
        elif self.low_delay:  # x265 needs a lookahead deeper than its B-frame runs
            opts["x265-params"] += f":rc-lookahead={self.bframes + 1}:frame-threads=1"
        return opts


class AV1(PyAVCodec):
    """AV1 through SVT-AV1 (decoded by dav1d): the smallest lossy files; ``preset`` 0–13.

    Unlike the other codecs, ``low_delay`` is off by default: SVT-AV1's random-access
    structure holds back about 55 frames (a crash loses them), but its low-delay structure
    (``low_delay=True``: no frame held back) made streams 78–121 % larger on every measured
    sequence, which defeats the point of AV1 (``docs/format.md`` has the numbers).
    """

    video_format: ClassVar[str | None] = "av1"
    name: ClassVar[str] = "av1"
    encoder_name: ClassVar[str] = "libsvtav1"
    decoder_name: ClassVar[str] = "libdav1d"

    def __init__(
        self,
        *,
        crf: int = 30,
        preset: int = 10,
        gop: int | None = None,
        pix_fmt: str = "yuv420p",
        threads: int = 0,
        low_delay: bool = False,
    ) -> None:
        check_int(self.name, "crf", crf, 1, 63)
        check_int(self.name, "preset", preset, 0, 13)
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        check_int(self.name, "threads", threads, 0, 64)
        check_choice(self.name, "low_delay", low_delay, (True, False))
        self.crf, self.preset, self.gop, self.pix_fmt, self.threads = (
            crf,
            preset,
            gop,
            pix_fmt,
            threads,
        )
        self.low_delay = low_delay

    def _options(self) -> dict[str, str]:
        opts = {"crf": str(self.crf), "preset": str(self.preset)}
        if self.low_delay:
            opts["svtav1-params"] = "pred-struct=1"
        return opts


class VP9(PyAVCodec):
    """VP9 through libvpx in constant-quality mode; ``speed`` is libvpx's cpu-used (0–8).

    ``low_delay`` (the default) sets libvpx's ``lag-in-frames`` to 0, so every frame's packet
    comes out as it goes in; ``False`` lets libvpx look up to 25 frames ahead (alt-ref frames).
    """

    video_format: ClassVar[str | None] = "vp9"
    name: ClassVar[str] = "vp9"
    encoder_name: ClassVar[str] = "libvpx-vp9"
    decoder_name: ClassVar[str] = "vp9"
    pix_fmts: ClassVar[tuple[str, ...]] = ("yuv420p", "yuv444p")

    def __init__(
        self,
        *,
        crf: int = 32,
        speed: int = 8,
        gop: int | None = None,
        pix_fmt: str = "yuv420p",
        threads: int = 0,
        low_delay: bool = True,
    ) -> None:
        check_int(self.name, "crf", crf, 0, 63)
        check_int(self.name, "speed", speed, 0, 8)
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        check_int(self.name, "threads", threads, 0, 64)
        check_choice(self.name, "low_delay", low_delay, (True, False))
        self.crf, self.speed, self.gop, self.pix_fmt, self.threads = (
            crf,
            speed,
            gop,
            pix_fmt,
            threads,
        )
        self.low_delay = low_delay

    def _options(self) -> dict[str, str]:
        opts = {
            "crf": str(self.crf),
            "b": "0",
            "cpu-used": str(self.speed),
            "deadline": "realtime" if self.speed >= 5 else "good",
            "row-mt": "1",
        }
        if self.low_delay:
            opts["lag-in-frames"] = "0"
        return opts


class MJPEG(PyAVCodec):
    """Motion JPEG: every frame a JPEG (all keyframes); ``quality`` is the quantiser, 2 (best)
    to 31."""

    name: ClassVar[str] = "mjpeg"
    encoder_name: ClassVar[str] = "mjpeg"
    decoder_name: ClassVar[str] = "mjpeg"
    pix_fmts: ClassVar[tuple[str, ...]] = ("yuvj420p", "yuvj444p")

    def __init__(self, *, quality: int = 3, pix_fmt: str = "yuvj420p", threads: int = 0) -> None:
        check_int(self.name, "quality", quality, 2, 31)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        check_int(self.name, "threads", threads, 0, 64)
        self.quality, self.pix_fmt, self.threads = quality, pix_fmt, threads

    def _gop(self, fps: float) -> int:
        return 1

    def _options(self) -> dict[str, str]:
        return {"qmin": str(self.quality), "qmax": str(self.quality)}


class MPEG4(PyAVCodec):
    """MPEG-4 Part 2 (the paper's mp4v/XVID family) at a constant quantiser ``qscale`` 2–31."""

    name: ClassVar[str] = "mpeg4"
    encoder_name: ClassVar[str] = "mpeg4"
    decoder_name: ClassVar[str] = "mpeg4"

    def __init__(
        self, *, qscale: int = 3, gop: int | None = None, bframes: int = 0, threads: int = 0
    ) -> None:
        check_int(self.name, "qscale", qscale, 2, 31)
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "bframes", bframes, 0, 16)
        check_int(self.name, "threads", threads, 0, 64)
        self.qscale, self.gop, self.bframes, self.threads = qscale, gop, bframes, threads
        self.pix_fmt = "yuv420p"

    def _options(self) -> dict[str, str]:
        return {"qmin": str(self.qscale), "qmax": str(self.qscale)}

    def _decoder_options(self) -> dict[str, str]:
        # With FFmpeg's defaults the decoded frames of one stream varied between runs in one
        # process (after other native libraries ran); bit-exact mode keeps them identical.
        return {"idct": "simple", "flags": "+bitexact", "ec": "0"}


# -- lossless codecs ---------------------------------------------------------------------------


class FFV1(PyAVCodec):
    """FFV1, lossless, on RGB (``bgr0``): the paper's best lossless color codec.

    ``level`` 3 adds per-slice CRCs and multithreaded slices; ``level`` 1 is the older variant.
    """

    name: ClassVar[str] = "ffv1"
    encoder_name: ClassVar[str] = "ffv1"
    decoder_name: ClassVar[str] = "ffv1"
    pix_fmts: ClassVar[tuple[str, ...]] = ("bgr0",)
    lossless: ClassVar[bool] = True

    def __init__(self, *, level: int = 3, gop: int | None = None, threads: int = 0) -> None:
        check_choice(self.name, "level", level, (1, 3))
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "threads", threads, 0, 64)
        self.level, self.gop, self.threads = level, gop, threads
        self.pix_fmt = "bgr0"

    def _options(self) -> dict[str, str]:
        opts = {"level": str(self.level), "coder": "range_def"}
        if self.level == 3:
            opts["slicecrc"] = "1"
        return opts


class HuffYUV(PyAVCodec):
    """HuffYUV, lossless, on RGB24: very fast, large."""

    name: ClassVar[str] = "huffyuv"
    encoder_name: ClassVar[str] = "huffyuv"
    decoder_name: ClassVar[str] = "huffyuv"
    pix_fmts: ClassVar[tuple[str, ...]] = ("rgb24",)
    lossless: ClassVar[bool] = True

    def __init__(self, *, threads: int = 0) -> None:
        check_int(self.name, "threads", threads, 0, 64)
        self.threads = threads
        self.pix_fmt = "rgb24"

    def _gop(self, fps: float) -> int:
        return 1


class FFVHuff(HuffYUV):
    """FFVHuff, FFmpeg's extended HuffYUV, lossless, on RGB24."""

    name: ClassVar[str] = "ffvhuff"
    encoder_name: ClassVar[str] = "ffvhuff"
    decoder_name: ClassVar[str] = "ffvhuff"


class H264Lossless(PyAVCodec):
    """Lossless H.264 on RGB through libx264rgb at qp 0: bit-exact, and inter-frame coded.

    ``low_delay`` (the default) adds x264's ``zerolatency`` tuning, as for :class:`H264`.
    """

    video_format: ClassVar[str | None] = "h264"
    name: ClassVar[str] = "h264-lossless"
    encoder_name: ClassVar[str] = "libx264rgb"
    decoder_name: ClassVar[str] = "h264"
    pix_fmts: ClassVar[tuple[str, ...]] = ("rgb24",)
    lossless: ClassVar[bool] = True

    def __init__(
        self,
        *,
        preset: str = "veryfast",
        gop: int | None = None,
        threads: int = 0,
        low_delay: bool = True,
    ) -> None:
        check_choice(self.name, "preset", preset, _X26X_PRESETS)
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "threads", threads, 0, 64)
        check_choice(self.name, "low_delay", low_delay, (True, False))
        self.preset, self.gop, self.threads = preset, gop, threads
        self.pix_fmt = "rgb24"
        self.low_delay = low_delay

    def _options(self) -> dict[str, str]:
        opts = {"qp": "0", "preset": self.preset}
        if self.low_delay:
            opts["tune"] = "zerolatency"
        return opts


# -- GPU encoders ------------------------------------------------------------------------------


class H264NVENC(PyAVCodec):
    """H.264 on an NVIDIA GPU (NVENC), decoded on the CPU. Needs an NVIDIA GPU and driver;
    ``cq`` is the constant-quality level (0–51), ``preset`` p1 (fastest) to p7."""

    video_format: ClassVar[str | None] = "h264"
    name: ClassVar[str] = "h264-nvenc"
    encoder_name: ClassVar[str] = "h264_nvenc"
    decoder_name: ClassVar[str] = "h264"
    install_hint: ClassVar[str] = (
        "NVENC needs an NVIDIA GPU with its driver and an FFmpeg build with NVENC "
        "(the PyAV wheels have it)"
    )

    def __init__(
        self,
        *,
        cq: int = 23,
        preset: str = "p4",
        gop: int | None = None,
        bframes: int = 0,
        pix_fmt: str = "yuv420p",
    ) -> None:
        check_int(self.name, "cq", cq, 0, 51)
        check_choice(self.name, "preset", preset, tuple(f"p{i}" for i in range(1, 8)))
        check_int(self.name, "gop", gop, 1, 10000, none_ok=True)
        check_int(self.name, "bframes", bframes, 0, 4)
        check_choice(self.name, "pix_fmt", pix_fmt, self.pix_fmts)
        self.cq, self.preset, self.gop, self.bframes, self.pix_fmt = (
            cq,
            preset,
            gop,
            bframes,
            pix_fmt,
        )
        self.threads = 0

    def _options(self) -> dict[str, str]:
        return {"rc": "vbr", "cq": str(self.cq), "b": "0", "preset": self.preset}


class HEVCNVENC(H264NVENC):
    """H.265/HEVC on an NVIDIA GPU (NVENC), decoded on the CPU."""

    video_format: ClassVar[str | None] = "h265"
    name: ClassVar[str] = "h265-nvenc"
    encoder_name: ClassVar[str] = "hevc_nvenc"
    decoder_name: ClassVar[str] = "hevc"
