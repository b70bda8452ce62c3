"""Color codecs through PyAV (FFmpeg's libavcodec): H.264, H.265, AV1, VP9, MJPEG, MPEG-4,
and the lossless FFV1, HuffYUV, FFVHuff and H.264 RGB.

Every codec here works on packets without a container, so a recording can store them as it
likes and decoding can start at any keyframe. Encoder input is RGB24; the codec's pixel format
conversion (BT.601, limited range for the YUV formats) happens inside FFmpeg's swscale.

Pixel formats with chroma subsampling need even sizes (4:2:0 both, 4:2:2 the width): odd frames
are padded by repeating the last row or column, and the decoder crops them back. Nothing is
ever resized.

This module holds the codecs: their parameters (the ones most share are checked once, by
:meth:`PyAVCodec._take_shared`), configs and FFmpeg options. The encoder and decoder that run
them are in :mod:`.ffmpeg`, loaded when a codec is probed or a stream starts.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, ClassVar

from .._validate import check_choice, check_int, check_number
from .base import StreamCodec, VideoDecoder, VideoEncoder, default_keyframe_interval

if TYPE_CHECKING:
    from .ffmpeg import FFmpegSetup

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


def __getattr__(name: str) -> Any:
    # ffmpeg_packet lived here; it is served from .ffmpeg, which `import pcdcodec` does not load.
    if name == "ffmpeg_packet":
        from .ffmpeg import ffmpeg_packet

        return ffmpeg_packet
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: A shared parameter the codec does not take (see :meth:`PyAVCodec._take_shared`).
_ABSENT: Any = object()


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

    #: The parameters most codecs share, set by :meth:`_take_shared` (fixed values where the
    #: codec does not take one).
    gop: int | None
    bframes: int
    pix_fmt: str
    threads: int
    #: Set only on the codecs that take it.
    low_delay: bool

    #: Encoder options used when probing whether the encoder opens (to keep it quiet).
    probe_options: ClassVar[tuple[tuple[str, str], ...]] = ()

    @classmethod
    def unavailable_reason(cls) -> str | None:
        from .ffmpeg import probe

        return probe(cls.encoder_name, cls.decoder_name, cls.pix_fmts[0], cls.probe_options)

    def _take_shared(
        self,
        *,
        gop: Any = _ABSENT,
        bframes: Any = _ABSENT,
        pix_fmt: Any = _ABSENT,
        threads: Any = _ABSENT,
        low_delay: Any = _ABSENT,
        max_bframes: int = 16,
    ) -> None:
        """Check and keep the shared parameters this codec takes, in this order.

        ``gop``: the keyframe interval, 1..10000 frames, or ``None`` for a third of a second of
        frames; ``bframes``: 0..``max_bframes``; ``pix_fmt``: one of :attr:`pix_fmts`; ``threads``:
        0..64 (0 lets FFmpeg choose); ``low_delay``: a bool. A codec that does not take one
        gets ``gop=None``, ``bframes=0``, ``pix_fmt=pix_fmts[0]``, ``threads=0`` and no
        ``low_delay``.
        """
        name = self.name
        if gop is not _ABSENT:
            check_int(name, "gop", gop, 1, 10000, none_ok=True)
        if bframes is not _ABSENT:
            check_int(name, "bframes", bframes, 0, max_bframes)
        if pix_fmt is not _ABSENT:
            check_choice(name, "pix_fmt", pix_fmt, self.pix_fmts)
        if threads is not _ABSENT:
            check_int(name, "threads", threads, 0, 64)
        if low_delay is not _ABSENT:
            check_choice(name, "low_delay", low_delay, (True, False))
            self.low_delay = low_delay
        self.gop = None if gop is _ABSENT else gop
        self.bframes = 0 if bframes is _ABSENT else bframes
        self.pix_fmt = self.pix_fmts[0] if pix_fmt is _ABSENT else pix_fmt
        self.threads = 0 if threads is _ABSENT else threads

    # What subclasses decide.
    def _options(self) -> dict[str, str]:
        return {}

    def _decoder_options(self) -> dict[str, str]:
        return {}

    def _gop(self) -> int | None:
        """The keyframe interval; ``None``: a third of a second of frames."""
        return self.gop

    def keyframe_interval(self, fps: float) -> int:
        gop = self._gop()
        return int(gop) if gop is not None else default_keyframe_interval(fps)

    def _pad(self) -> tuple[int, int]:
        """Multiples the width and height must be padded to for :attr:`pix_fmt`."""
        if "420" in self.pix_fmt:
            return 2, 2
        if "422" in self.pix_fmt:
            return 2, 1
        return 1, 1

    def padded_size(self, width: int, height: int) -> tuple[int, int]:
        """The frame size this codec codes a ``width`` × ``height`` stream at: each padded up
        to what :attr:`pix_fmt` needs (4:2:0 both even, 4:2:2 the width)."""
        mx, my = self._pad()
        return -(-width // mx) * mx, -(-height // my) * my

    def _setup(self) -> FFmpegSetup:
        from .ffmpeg import FFmpegSetup

        return FFmpegSetup(
            encoder_name=self.encoder_name,
            decoder_name=self.decoder_name,
            pix_fmt=self.pix_fmt,
            pad=self._pad(),
            threads=self.threads,
            gop=self._gop(),
            bframes=self.bframes,
            options=self._options(),
            decoder_options=self._decoder_options(),
        )

    def encoder(self, width: int, height: int, fps: float = 30.0) -> VideoEncoder:
        """Start a stream of ``width`` × ``height`` RGB frames at about ``fps`` frames/s.

        The keyframe interval defaults to a third of a second of frames. Raises
        :class:`~pcdcodec.CodecUnavailableError` when the FFmpeg encoder cannot be opened.
        """
        self._require_available()
        from .ffmpeg import FFmpegEncoder

        return FFmpegEncoder(self, self._setup(), width, height, fps)

    def decoder(self, width: int, height: int, extradata: bytes | None = None) -> VideoDecoder:
        """Start decoding a ``width`` × ``height`` stream; pass the encoder's ``extradata``."""
        self._require_available()
        from .ffmpeg import FFmpegDecoder

        return FFmpegDecoder(self, self._setup(), width, height, extradata)


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
    a third of a second, 10 frames at 30 fps), ``bframes`` the number of B-frames (0 keeps
    decode order = display order), ``pix_fmt`` ``yuv420p`` (most compatible) or ``yuv444p``
    (full chroma). ``low_delay`` (the default) adds x264's ``zerolatency`` tuning: no lookahead
    and sliced threads, so every frame's packet comes out as it goes in and a crash loses no
    frame the encoder held back;
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
        self._take_shared(
            gop=gop, bframes=bframes, pix_fmt=pix_fmt, threads=threads, low_delay=low_delay
        )
        self.crf, self.preset, self.tune = crf, preset, tune

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
        self._take_shared(
            gop=gop, bframes=bframes, pix_fmt=pix_fmt, threads=threads, low_delay=low_delay
        )
        self.crf, self.preset = crf, preset

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
        self._take_shared(gop=gop, pix_fmt=pix_fmt, threads=threads, low_delay=low_delay)
        self.crf, self.preset = crf, preset

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
        self._take_shared(gop=gop, pix_fmt=pix_fmt, threads=threads, low_delay=low_delay)
        self.crf, self.speed = crf, speed

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
        self._take_shared(pix_fmt=pix_fmt, threads=threads)
        self.quality = quality

    def _gop(self) -> int:
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
        self._take_shared(gop=gop, bframes=bframes, threads=threads)  # in yuv420p
        self.qscale = qscale

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
        self._take_shared(gop=gop, threads=threads)  # in bgr0
        self.level = level

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
        self._take_shared(threads=threads)  # in rgb24

    def _gop(self) -> int:
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
        self._take_shared(gop=gop, threads=threads, low_delay=low_delay)  # in rgb24
        self.preset = preset

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
        # NVENC runs on the GPU: no CPU threads to choose.
        self._take_shared(gop=gop, bframes=bframes, pix_fmt=pix_fmt, max_bframes=4)
        self.cq, self.preset = cq, preset

    def _options(self) -> dict[str, str]:
        return {"rc": "vbr", "cq": str(self.cq), "b": "0", "preset": self.preset}


class HEVCNVENC(H264NVENC):
    """H.265/HEVC on an NVIDIA GPU (NVENC), decoded on the CPU."""

    video_format: ClassVar[str | None] = "h265"
    name: ClassVar[str] = "h265-nvenc"
    encoder_name: ClassVar[str] = "hevc_nvenc"
    decoder_name: ClassVar[str] = "hevc"
