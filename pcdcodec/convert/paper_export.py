"""The paper's two-file layout: the color stream as a video, the depth as LZ4 frames.

The published compressed point cloud streams method kept an RGB-D stream as two files side by
side, the color as an ordinary video (written with OpenCV's ``VideoWriter``) and the depth as
LZ4 frames, held in step by timestamps. :func:`export_paper` writes a recording in that layout
and :func:`import_paper` turns such a folder back into a recording, so results can be compared
with the paper's tools. The folder holds::

    color.mkv    the recording's color packets, muxed as they are (Matroska; HuffYUV and
                 FFVHuff, which Matroska does not list, go into color.avi instead)
    depth.lz4    one standard LZ4 frame per depth frame, concatenated, each the raw
                 little-endian uint16 (or float32) pixels row by row with its size stored:
                 ``lz4 -d depth.lz4`` gives the images one after another
    frames.json  the camera, the depth scale, the codecs and, per frame, its timestamp, where
                 its LZ4 frame lies in depth.lz4 and the pts of its color frame in the video

Color is never re-encoded, either way: a lossless recording stays lossless, a lossy one loses
nothing more. Depth is exact both ways.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from .._atomic import partial_path
from .._validate import check_depth
from ..color.base import Packet, StreamCodec
from ..color.pyav import PyAVCodec, ffmpeg_packet
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import CodecUnavailableError, DecodeError, InputError, PcdcodecError
from ..geometry.camera import CameraIntrinsics
from ..recording.reader import Recording
from ..recording.writer import RecordingWriter
from ..registry import codec_class, get_codec

__all__ = ["FORMAT_NAME", "LAYOUT_VERSION", "export_paper", "import_paper"]

#: The ``format`` and ``version`` written into frames.json.
FORMAT_NAME = "pcdcodec-paper-layout"
LAYOUT_VERSION = 1

FRAMES_FILE = "frames.json"
DEPTH_FILE = "depth.lz4"
#: Video file name by FFmpeg container format.
VIDEO_FILES = {"matroska": "color.mkv", "avi": "color.avi"}

_NS = 1_000_000_000
#: Codecs Matroska does not list (FFmpeg refuses them there); AVI is their usual home.
_AVI_CODECS = frozenset({"huffyuv", "ffvhuff"})
#: FFmpeg's codec names (``AVCodecDescriptor``) and the pcdcodec color codec for each.
CODEC_IDS = {
    "h264": "h264",
    "hevc": "h265",
    "av1": "av1",
    "vp9": "vp9",
    "mjpeg": "mjpeg",
    "mpeg4": "mpeg4",
    "ffv1": "ffv1",
    "huffyuv": "huffyuv",
    "ffvhuff": "ffvhuff",
}
_DEPTH_DTYPES: dict[str, np.dtype[Any]] = {"uint16": np.dtype("<u2"), "float32": np.dtype("<f4")}
#: Packets looked ahead to give imported packets decoding timestamps (H.264's deepest reorder).
_REORDER_WINDOW = 16


# -- export --------------------------------------------------------------------------------------


def export_paper(
    recording_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Write a ``.pcdc`` recording as the paper's files: a video, LZ4 depth and frames.json.

    The color packets are muxed into ``color.mkv`` (``color.avi`` for HuffYUV and FFVHuff)
    unchanged, and the video is then decoded in full to check that every frame plays. The depth
    goes into ``depth.lz4``, one LZ4 frame per depth image (depth units, or float32 metres for
    float recordings); ``frames.json`` describes both (see the module docstring). Files are
    written beside their final names and renamed at the end, so a failed export leaves no
    half-written layout.

    ``progress`` is called with the number of depth frames written so far. Returns a summary:
    ``frames``, ``out_dir``, ``video_file`` (``None`` for depth-only recordings) and ``bytes``,
    the size of each file by name.

    Raises :class:`~pcdcodec.InputError` when ``out_dir`` is a file, or a folder that is not
    empty and ``overwrite`` is false, or when the recording has no frames;
    :class:`~pcdcodec.DecodeError` when the recording is damaged or the video does not play
    back frame for frame.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)!r} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise InputError(
            f"folder {str(out)!r} is not empty; pass overwrite=True to replace the files in it"
        )
    with Recording(recording_path) as rec:
        n = len(rec)
        if n == 0:
            raise InputError(f"recording {str(rec.path)!r} has no frames to export")
        container_format = _container_format(rec.color_codec)
        out.mkdir(parents=True, exist_ok=True)
        names = [DEPTH_FILE, FRAMES_FILE]  # frames.json is renamed into place last
        if container_format is not None:
            names.insert(1, VIDEO_FILES[container_format])
        partial = {name: partial_path(out / name) for name in names}
        try:
            spans, dtype = _write_depth(rec, partial[DEPTH_FILE], progress)
            video: dict[str, Any] | None = None
            pts_of: dict[int, int] = {}
            if container_format is not None:
                name = VIDEO_FILES[container_format]
                video, pts_of = _mux_color(rec, partial[name], container_format)
                video["file"] = name
                _check_video(partial[name], container_format, video, rec, pts_of)
            timestamps = [int(t) for t in rec.timestamps]
            doc = {
                "format": FORMAT_NAME,
                "version": LAYOUT_VERSION,
                "width": rec.intrinsics.width,
                "height": rec.intrinsics.height,
                "depth_dtype": dtype,
                "depth_byte_order": "little",
                "depth_scale": rec.depth_scale,
                "intrinsics": rec.intrinsics.to_dict(),
                "fps": rec.fps,
                "depth_file": DEPTH_FILE,
                "depth_codec": {"id": "lz4-frame", "store_size": True, "content_checksum": True},
                "video_file": video["file"] if video else None,
                "color_codec": rec.codecs["color"],
                "video": video,
                "frames": [
                    {
                        "index": i,
                        "timestamp_ns": t,
                        "depth_offset": spans[i][0],
                        "depth_length": spans[i][1],
                        "pts": pts_of[t] if video else None,
                    }
                    for i, t in enumerate(timestamps)
                ],
            }
            partial[FRAMES_FILE].write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
            for name, path in partial.items():
                os.replace(path, out / name)
        finally:
            for path in partial.values():
                path.unlink(missing_ok=True)
    # A video of another container left by an earlier export would contradict frames.json.
    for name in VIDEO_FILES.values():
        if name not in names:
            (out / name).unlink(missing_ok=True)
    return {
        "frames": n,
        "out_dir": str(out),
        "video_file": video["file"] if video else None,
        "bytes": {name: (out / name).stat().st_size for name in names},
    }


def _container_format(codec: StreamCodec | None) -> str | None:
    if codec is None:
        return None
    if not isinstance(codec, PyAVCodec):
        raise InputError(
            f"color codec {codec.name!r} has no FFmpeg bitstream that a video file can hold"
        )
    return "avi" if _canonical(codec) in _AVI_CODECS else "matroska"


def _canonical(codec: PyAVCodec) -> str:
    """FFmpeg's name for the bitstream of ``codec`` (``hevc`` for H.265, ``av1`` for dav1d)."""
    import av

    try:
        return str(av.Codec(codec.decoder_name, "r").canonical_name)
    except Exception:
        pass
    try:
        return str(av.Codec(codec.encoder_name, "w").canonical_name)
    except Exception:
        pass
    raise CodecUnavailableError(
        f"this FFmpeg build knows neither {codec.decoder_name!r} nor {codec.encoder_name!r} "
        f"(color codec {codec.name!r}); {codec.install_hint}"
    )


def _write_depth(
    rec: Recording, path: Path, progress: Callable[[int], None] | None
) -> tuple[list[tuple[int, int]], str]:
    """Write every depth frame as one LZ4 frame; return each frame's (offset, length), dtype."""
    import lz4.frame

    spans: list[tuple[int, int]] = []
    dtype = ""
    offset = 0
    with open(path, "wb") as fh:
        for i in range(len(rec)):
            # Recording.depth decodes the depth alone; iterating frames would decode color too.
            depth = check_depth(rec.depth(i), name=f"frame {i} depth")  # little-endian, C order
            if not dtype:
                dtype = depth.dtype.name
            elif depth.dtype.name != dtype:
                raise DecodeError(
                    f"recording {str(rec.path)!r}: frame {i} depth is {depth.dtype.name}, "
                    f"earlier frames are {dtype}"
                )
            blob = lz4.frame.compress(
                depth.tobytes(), store_size=True, content_checksum=True, compression_level=0
            )
            fh.write(blob)
            spans.append((offset, len(blob)))
            offset += len(blob)
            if progress is not None:
                progress(i + 1)
    return spans, dtype


def _padded(size: int, multiple: int) -> int:
    return -(-size // multiple) * multiple


def _mux_color(
    rec: Recording, path: Path, container_format: str
) -> tuple[dict[str, Any], dict[int, int]]:
    """Mux the recording's color packets, unchanged, into a video file.

    Returns the video's description for frames.json and the video pts (in its time base) of
    each packet's pts in nanoseconds.
    """
    import av

    codec = rec.color_codec
    assert isinstance(codec, PyAVCodec)
    canonical = _canonical(codec)
    all_pts = [int(t) for t in rec.packet_timestamps]
    # Decoding starts at the first keyframe; the reader drops what comes before it too.
    if not rec.keyframes:
        raise DecodeError(f"recording {str(rec.path)!r} has no color keyframe")
    start = rec.keyframes[0]
    shown = sorted(set(all_pts[start:]))
    extradata = rec.extradata
    first = rec.packet(start)
    # Decoding timestamps only increase, so the first packet's is the smallest of all; starting
    # the clock there keeps every timestamp non-negative (muxers would shift them otherwise).
    origin = min(first.dts, shown[0])
    rate = Fraction(rec.fps).limit_denominator(1001)
    pts_of: dict[int, int] = {}
    if container_format == "avi":
        # AVI counts frames rather than storing times; it only holds intra-only codecs here.
        time_base = 1 / rate
        pts_of = {t: k for k, t in enumerate(shown)}
    else:
        # FFmpeg writes Matroska in milliseconds; frames closer than that are moved apart by
        # 1 ms so each keeps its own pts. frames.json keeps the exact times.
        time_base = Fraction(1, 1000)
        last = -1
        for t in shown:
            last = pts_of[t] = max(round(Fraction(t - origin, _NS) / time_base), last + 1)
    mx, my = codec._pad()
    width = _padded(rec.intrinsics.width, mx)
    height = _padded(rec.intrinsics.height, my)

    container: Any = av.open(str(path), "w", format=container_format)
    count = 0
    try:
        if extradata:
            # A stream whose decoder needs set-up bytes (FFV1, HuffYUV) is declared through an
            # encoder context, since only a codec context can carry extradata into the header.
            # Opening it makes the encoder write its own extradata, which is then replaced with
            # the recording's: nothing is encoded with it.
            stream = container.add_stream(codec.encoder_name, rate=rate)
            ctx = stream.codec_context
            ctx.width, ctx.height = width, height
            ctx.pix_fmt, ctx.time_base = codec.pix_fmt, time_base
            try:
                ctx.open()
            except Exception as exc:
                raise CodecUnavailableError(
                    f"cannot declare a {codec.name} stream in {str(path)!r}: {exc}"
                ) from exc
            ctx.extradata = extradata
        else:
            # No codec context at all; PyAV takes H.264/H.265/AV1 parameter sets from the first
            # packet into the header itself.
            stream = container.add_mux_stream(canonical, rate=rate, width=width, height=height)
        stream.time_base = time_base
        last_dts: int | None = None
        for packet in rec.packets(start):
            pts = pts_of[packet.pts]
            if packet.dts == packet.pts:
                dts = pts
            else:
                dts = min(pts, round(Fraction(packet.dts - origin, _NS) / time_base))
                if last_dts is not None:
                    dts = max(dts, last_dts)
            last_dts = dts
            avp: Any = ffmpeg_packet(packet.data)
            avp.stream = stream
            avp.time_base = time_base
            avp.pts, avp.dts = pts, dts
            avp.is_keyframe = packet.keyframe
            container.mux(avp)
            count += 1
        container.close()  # writes the trailer (Matroska's cues, AVI's index)
    except BaseException as exc:
        with contextlib.suppress(Exception):
            container.close()
        if isinstance(exc, PcdcodecError) or not isinstance(exc, Exception):
            raise
        raise DecodeError(
            f"color packet {count} of {str(rec.path)!r} could not be muxed into "
            f"{container_format}: {type(exc).__name__}: {exc}"
        ) from exc
    video = {
        "format": container_format,
        "codec": canonical,
        "time_base": [time_base.numerator, time_base.denominator],
        "time_origin_ns": origin,
        "width": width,
        "height": height,
        "packets": count,
        # Packets whose frame has no depth (the tail of a recording cut short): they are in
        # the video, the reader drops them, and an import writes them back all the same.
        "color_only_pts": sorted(set(pts_of.values()) - {pts_of[int(t)] for t in rec.timestamps}),
    }
    return video, pts_of


def _check_video(
    path: Path,
    container_format: str,
    video: dict[str, Any],
    rec: Recording,
    pts_of: dict[int, int],
) -> None:
    """Decode the whole video: it must give one frame per packet, every frame at its pts."""
    import av

    name = video["file"]
    try:
        container: Any = av.open(str(path), format=container_format)
    except Exception as exc:
        raise DecodeError(f"the {name} just written does not open: {exc}") from exc
    with container:
        stream = container.streams.video[0]
        time_base = Fraction(*video["time_base"])
        if stream.time_base != time_base:
            raise DecodeError(
                f"the {name} just written has time base {stream.time_base}, not {time_base}"
            )
        if rec.extradata and stream.codec_context.extradata != rec.extradata:
            raise DecodeError(f"the {name} just written lost the codec's extradata")
        stream.thread_type = "AUTO"
        decoded: set[int] = set()
        count = 0
        try:
            for frame in container.decode(stream):
                count += 1
                if frame.pts is not None:
                    decoded.add(int(frame.pts))
        except Exception as exc:
            raise DecodeError(
                f"the {name} just written does not play: frame {count} fails to decode: {exc}"
            ) from exc
    if count != video["packets"]:
        raise DecodeError(
            f"the {name} just written plays {count} frames, but {video['packets']} were muxed"
        )
    missing = [int(t) for t in rec.timestamps if pts_of[int(t)] not in decoded]
    if missing:
        raise DecodeError(
            f"the {name} just written has no frame at the pts of {len(missing)} frames "
            f"(first: t={missing[0]} ns)"
        )


# -- import --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Frame:
    index: int
    timestamp_ns: int
    depth_offset: int
    depth_length: int
    pts: int | None


@dataclass(frozen=True)
class _Layout:
    path: Path
    width: int
    height: int
    depth_dtype: np.dtype[Any]
    depth_scale: float
    intrinsics: CameraIntrinsics
    fps: float
    depth_file: str
    video_file: str | None
    color_codec: dict[str, Any] | None
    #: What frames.json says of the video: the time base of the pts, the time in ns at pts 0,
    #: and the pts of packets that are no listed frame's (color without depth).
    time_base: Fraction | None
    time_origin_ns: int
    color_only_pts: list[int]
    frames: list[_Frame]


def _bad(path: Path, field: str, problem: str) -> DecodeError:
    return DecodeError(f"{str(path)!r}: field {field!r} {problem}")


def _get(doc: Mapping[str, Any], key: str, path: Path, prefix: str = "") -> Any:
    if key not in doc:
        raise _bad(path, prefix + key, "is missing")
    return doc[key]


def _int(value: Any, path: Path, field: str, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise _bad(path, field, f"must be an int >= {lo}, got {value!r}")
    return value


def _number(value: Any, path: Path, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise _bad(path, field, f"must be a positive number, got {value!r}")
    return float(value)


def _file_name(value: Any, path: Path, field: str) -> str:
    # A bare name: the layout is one folder, and a path here must not reach outside it.
    if not isinstance(value, str) or not value or Path(value).name != value or value == "..":
        raise _bad(path, field, f"must be a file name in the same folder, got {value!r}")
    return value


def _read_layout(folder: Path) -> _Layout:
    path = folder / FRAMES_FILE
    if not path.is_file():
        raise InputError(f"{str(path)!r} does not exist; {str(folder)!r} is not a paper layout")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DecodeError(f"{str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise DecodeError(f"{str(path)!r} must hold a JSON object, got {type(doc).__name__}")
    if doc.get("format") != FORMAT_NAME:
        raise _bad(path, "format", f"must be {FORMAT_NAME!r}, got {doc.get('format')!r}")
    version = _int(_get(doc, "version", path), path, "version", 1)
    if version > LAYOUT_VERSION:
        raise _bad(
            path, "version", f"is {version}, newer than this pcdcodec reads ({LAYOUT_VERSION})"
        )
    width = _int(_get(doc, "width", path), path, "width", 1)
    height = _int(_get(doc, "height", path), path, "height", 1)
    dtype = _get(doc, "depth_dtype", path)
    if dtype not in _DEPTH_DTYPES:
        raise _bad(path, "depth_dtype", f"must be one of {list(_DEPTH_DTYPES)}, got {dtype!r}")
    if doc.get("depth_byte_order", "little") != "little":
        raise _bad(path, "depth_byte_order", f"must be 'little', got {doc['depth_byte_order']!r}")
    try:
        intrinsics = CameraIntrinsics.from_dict(_get(doc, "intrinsics", path))
    except InputError as exc:
        raise _bad(path, "intrinsics", f"is not valid: {exc}") from None
    if (intrinsics.width, intrinsics.height) != (width, height):
        raise _bad(
            path,
            "intrinsics",
            f"are for {intrinsics.width}x{intrinsics.height}, but width x height is "
            f"{width}x{height}",
        )
    video_file = doc.get("video_file")
    if video_file is not None:
        video_file = _file_name(video_file, path, "video_file")
    color_codec = doc.get("color_codec")
    if color_codec is not None and not (isinstance(color_codec, dict) and "id" in color_codec):
        raise _bad(path, "color_codec", f"must be a codec config with an 'id', got {color_codec!r}")
    video = doc.get("video") or {}
    if not isinstance(video, dict):
        raise _bad(path, "video", f"must be an object, got {video!r}")
    time_base: Fraction | None = None
    if "time_base" in video:
        tb = video["time_base"]
        if not (
            isinstance(tb, list)
            and len(tb) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in tb)
        ):
            raise _bad(path, "video.time_base", f"must be [numerator, denominator], got {tb!r}")
        time_base = Fraction(tb[0], tb[1])
    origin = _int(video.get("time_origin_ns", 0), path, "video.time_origin_ns")
    color_only = video.get("color_only_pts", [])
    if not isinstance(color_only, list):
        raise _bad(path, "video.color_only_pts", f"must be a list, got {color_only!r}")
    for i, v in enumerate(color_only):
        _int(v, path, f"video.color_only_pts[{i}]", -(2**62))
    raw_frames = _get(doc, "frames", path)
    if not isinstance(raw_frames, list) or not raw_frames:
        raise _bad(path, "frames", "must be a non-empty list")
    frames: list[_Frame] = []
    for i, entry in enumerate(raw_frames):
        where = f"frames[{i}]."
        if not isinstance(entry, dict):
            raise _bad(path, f"frames[{i}]", f"must be an object, got {entry!r}")
        index = _int(_get(entry, "index", path, where), path, where + "index")
        if index != i:
            raise _bad(path, where + "index", f"is {index}, expected {i}")
        ts = _int(_get(entry, "timestamp_ns", path, where), path, where + "timestamp_ns")
        if frames and ts <= frames[-1].timestamp_ns:
            raise _bad(
                path,
                where + "timestamp_ns",
                f"{ts} does not increase (frame {i - 1}: {frames[-1].timestamp_ns})",
            )
        offset = _int(_get(entry, "depth_offset", path, where), path, where + "depth_offset")
        length = _int(_get(entry, "depth_length", path, where), path, where + "depth_length", 1)
        pts = entry.get("pts")
        if video_file is not None:
            pts = _int(_get(entry, "pts", path, where), path, where + "pts", -(2**62))
        frames.append(_Frame(i, ts, offset, length, pts))
    return _Layout(
        path=path,
        width=width,
        height=height,
        depth_dtype=_DEPTH_DTYPES[dtype],
        depth_scale=_number(_get(doc, "depth_scale", path), path, "depth_scale"),
        intrinsics=intrinsics,
        fps=_number(doc.get("fps", 30.0), path, "fps"),
        depth_file=_file_name(doc.get("depth_file", DEPTH_FILE), path, "depth_file"),
        video_file=video_file,
        color_codec=color_codec,
        time_base=time_base,
        time_origin_ns=origin,
        color_only_pts=color_only,
        frames=frames,
    )


class _VideoSource:
    """The color packets of a paper layout's video, demuxed in decode order, times in ns."""

    def __init__(self, path: Path, layout: _Layout) -> None:
        import av

        self.path = path
        try:
            self._container: Any = av.open(str(path))
        except Exception as exc:
            raise DecodeError(f"{str(path)!r} is not a readable video: {exc}") from exc
        try:
            self._init(layout)
        except BaseException:
            self._container.close()
            raise

    def _init(self, layout: _Layout) -> None:
        streams = self._container.streams.video
        if not streams:
            raise DecodeError(f"{str(self.path)!r} has no video stream")
        self._stream = stream = streams[0]
        ctx = stream.codec_context
        self.canonical = str(ctx.codec.canonical_name)
        self.pix_fmt: str | None = ctx.pix_fmt
        self.time_base = Fraction(stream.time_base)
        extradata = bytes(ctx.extradata) if ctx.extradata else None
        self._bsf: Any = None
        if self.canonical in ("h264", "hevc") and extradata and extradata[0] == 1:
            # Containers hold H.264/H.265 as length-prefixed NAL units with the parameter sets
            # in the header (avcC/hvcC); recordings hold Annex B with them in the stream.
            from av.bitstream import BitStreamFilterContext

            self._bsf = BitStreamFilterContext(f"{self.canonical}_mp4toannexb", in_stream=stream)
            extradata = None
        self.extradata = extradata
        self._origin = layout.time_origin_ns
        # The pts in frames.json are in the time base it names; a remuxed video may differ.
        json_base = layout.time_base or self.time_base
        #: frame index by video pts
        self.frame_of: dict[int, int] = {}
        for f in layout.frames:
            assert f.pts is not None
            pts = round(f.pts * json_base / self.time_base)
            if pts in self.frame_of:
                raise _bad(
                    layout.path,
                    f"frames[{f.index}].pts",
                    f"{f.pts} is also the pts of frame {self.frame_of[pts]}",
                )
            self.frame_of[pts] = f.index
        self.color_only = {round(p * json_base / self.time_base) for p in layout.color_only_pts}
        self._timestamps = [f.timestamp_ns for f in layout.frames]
        self._json = layout.path

    def timestamp(self, pts: int) -> int:
        """The frame's own timestamp for a listed pts; else the pts on the layout's clock."""
        index = self.frame_of.get(pts)
        if index is not None:
            return self._timestamps[index]
        return self._origin + round(pts * self.time_base * _NS)

    def _raw(self) -> Iterator[tuple[bytes, int, bool]]:
        """(data, video pts, keyframe) of each packet in decode order."""
        try:
            for avp in self._container.demux(self._stream):
                if avp.size == 0:  # the end-of-stream marker
                    continue
                out = self._bsf.filter(avp) if self._bsf is not None else [avp]
                for p in out:
                    if p.pts is None:
                        raise DecodeError(f"{str(self.path)!r}: a video packet has no pts")
                    yield bytes(p), int(p.pts), bool(p.is_keyframe)
            if self._bsf is not None:
                for p in self._bsf.filter(None):
                    yield bytes(p), int(p.pts), bool(p.is_keyframe)
        except PcdcodecError:
            raise
        except Exception as exc:
            raise DecodeError(f"{str(self.path)!r} cannot be read: {exc}") from exc

    def packets(self) -> Iterator[tuple[int, Packet]]:
        """(video pts, packet with ns timestamps) in decode order.

        Containers such as Matroska keep no decoding timestamps, so they are rebuilt: each
        packet's is the smallest pts of the next few packets, never decreasing. For streams
        without B-frames that is the packet's own pts.
        """
        window: deque[tuple[bytes, int, bool]] = deque()
        last_dts = 0

        def emit() -> tuple[int, Packet]:
            nonlocal last_dts
            data, pts, key = window.popleft()
            ts = self.timestamp(pts)
            ahead = min((self.timestamp(p) for _, p, _ in window), default=ts)
            last_dts = max(last_dts, min(ts, ahead))
            if self.canonical == "av1" and data and (data[0] >> 3) & 0x0F != 2:
                # Matroska strips AV1's temporal delimiters; a raw AV1 stream starts each
                # temporal unit with one.
                data = b"\x12\x00" + data
            return pts, Packet.create(data, ts, last_dts, key)

        for item in self._raw():
            window.append(item)
            if len(window) > _REORDER_WINDOW:
                yield emit()
        while window:
            yield emit()

    def close(self) -> None:
        self._container.close()


def _color_codec(layout: _Layout, source: _VideoSource) -> PyAVCodec:
    """The recording's color codec: the config in frames.json, else the defaults for the
    video's bitstream."""
    video = str(source.path)
    if layout.color_codec is not None:
        try:
            codec = get_codec(layout.color_codec, kind="color")
        except PcdcodecError as exc:
            raise _bad(layout.path, "color_codec", f"is not usable: {exc}") from None
        if not isinstance(codec, PyAVCodec):
            raise _bad(layout.path, "color_codec", f"names {codec.name!r}, not a PyAV codec")
        if _canonical(codec) != source.canonical:
            raise _bad(
                layout.path,
                "color_codec",
                f"names {codec.name!r} ({_canonical(codec)}), but {video!r} holds "
                f"{source.canonical}",
            )
        return codec
    name = CODEC_IDS.get(source.canonical)
    if name is None:
        raise DecodeError(
            f"{video!r} holds {source.canonical}, which pcdcodec does not record; "
            f"known: {', '.join(sorted(CODEC_IDS))}"
        )
    cls = codec_class(name, "color")
    params: dict[str, Any] = {}
    pix_fmts: tuple[str, ...] = getattr(cls, "pix_fmts", ())
    if "pix_fmt" in cls.param_names() and source.pix_fmt in pix_fmts:
        params["pix_fmt"] = source.pix_fmt
    codec = get_codec(name, kind="color", **params)
    assert isinstance(codec, PyAVCodec)
    return codec


def _frame_groups(source: _VideoSource, n: int) -> Iterator[list[Packet]]:
    """The packets to write with each of the ``n`` frames, frame by frame.

    A packet goes with the latest frame (in display order) reached so far in decode order, so
    the frames' packets, taken in frame order, are the stream in decode order: a B-frame is
    written with the later frame it is decoded after, and packets that are no listed frame's
    go with the frame before them.
    """
    current = 0
    group: list[Packet] = []
    seen: set[int] = set()
    video, listing = str(source.path), str(source._json)
    for pts, packet in source.packets():
        k = source.frame_of.get(pts)
        if k is None and pts not in source.color_only:
            raise DecodeError(
                f"frame count mismatch: {video!r} has a frame at pts {pts} that {listing!r} "
                "does not list"
            )
        if k is not None:
            if k in seen:
                raise DecodeError(f"{video!r}: two packets have the pts {pts}")
            seen.add(k)
            while k > current:
                yield group
                current, group = current + 1, []
        group.append(packet)
    if len(seen) != n:
        missing = next(i for i in range(n) if i not in seen)
        raise DecodeError(
            f"frame count mismatch: {listing!r} lists {n} frames, {video!r} holds "
            f"{len(seen)} of them (none at the pts of frame {missing})"
        )
    while current < n:
        yield group
        current, group = current + 1, []


def import_paper(
    in_dir: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    depth: Any = DEFAULT_DEPTH_CODEC,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> int:
    """Read a paper layout (as :func:`export_paper` writes it) into a ``.pcdc`` recording.

    The video's packets are written into the recording as they are, never re-encoded; H.264
    and H.265 are turned back from the container's length-prefixed form into Annex B. The color
    codec recorded is the config in frames.json, or the default one for the video's bitstream
    (h264, hevc, av1, vp9, mjpeg, mpeg4, ffv1, huffyuv, ffvhuff). Each color frame goes with the
    frames.json frame of the same pts, and so with that frame's timestamp. Depth is read from
    the LZ4 frames that frames.json points at and encoded with ``depth`` (a codec name, config
    or codec). ``progress`` is called with the number of frames written so far. Returns the
    number of frames.

    The recording is written beside ``out_path`` and renamed at the end, so a failed import
    leaves nothing behind. Raises :class:`~pcdcodec.InputError` for a missing folder or file,
    or an existing ``out_path`` without ``overwrite``; :class:`~pcdcodec.DecodeError` for a
    malformed frames.json (naming the field), a damaged depth.lz4 or video, or a video whose
    frames do not match those frames.json lists.
    """
    folder = Path(in_dir)
    if not folder.is_dir():
        raise InputError(f"{str(folder)!r} is not a folder")
    layout = _read_layout(folder)
    out = Path(out_path)
    if out.is_dir():
        raise InputError(f"{str(out)!r} is a folder, not a file")
    if out.exists() and not overwrite:
        raise InputError(f"{str(out)!r} already exists; pass overwrite=True to replace it")
    if not out.parent.is_dir():
        raise InputError(f"folder {str(out.parent)!r} of {str(out)!r} does not exist")
    depth_path = folder / layout.depth_file
    if not depth_path.is_file():
        raise InputError(f"{str(depth_path)!r} does not exist")
    size = depth_path.stat().st_size
    for f in layout.frames:
        if f.depth_offset + f.depth_length > size:
            raise DecodeError(
                f"frame count mismatch: {str(layout.path)!r} puts frame {f.index} at bytes "
                f"{f.depth_offset}..{f.depth_offset + f.depth_length}, but {str(depth_path)!r} "
                f"has {size} bytes"
            )
    source: _VideoSource | None = None
    if layout.video_file is not None:
        video_path = folder / layout.video_file
        if not video_path.is_file():
            raise InputError(f"{str(video_path)!r} does not exist")
        source = _VideoSource(video_path, layout)
    tmp = out.with_name(f".{out.name}.import-{os.getpid()}")
    try:
        # The codec that wrote the packets is recorded; its encoder is never opened
        # (write_encoded), so a layout recorded with, say, NVENC imports anywhere.
        color = _color_codec(layout, source) if source is not None else None
        tmp.unlink(missing_ok=True)
        writer = RecordingWriter(
            tmp,
            intrinsics=layout.intrinsics,
            depth_scale=layout.depth_scale,
            color=color,
            depth=depth,
            fps=layout.fps,
        )
        try:
            with open(depth_path, "rb") as fh:
                _write_frames(writer, layout, fh, depth_path, source, progress)
            writer.close()
        except BaseException:
            writer.abort()
            raise
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
        if source is not None:
            source.close()
    return len(layout.frames)


def _write_frames(
    writer: RecordingWriter,
    layout: _Layout,
    fh: IO[bytes],
    depth_path: Path,
    source: _VideoSource | None,
    progress: Callable[[int], None] | None,
) -> None:
    n = len(layout.frames)
    groups = _frame_groups(source, n) if source is not None else None
    for f in layout.frames:
        image = _read_depth(fh, f, layout, depth_path)
        if groups is not None and source is not None:
            writer.write_encoded(next(groups), image, f.timestamp_ns, extradata=source.extradata)
        else:
            writer.write(None, image, f.timestamp_ns)
        if progress is not None:
            progress(f.index + 1)


def _read_depth(fh: IO[bytes], f: _Frame, layout: _Layout, path: Path) -> npt.NDArray[Any]:
    from ..depth.lz4 import lz4_decompress_bounded

    fh.seek(f.depth_offset)
    blob = fh.read(f.depth_length)
    where = f"{str(path)!r}: frame {f.index} (bytes {f.depth_offset}..+{f.depth_length})"
    expected = layout.width * layout.height * layout.depth_dtype.itemsize
    # Bounded by the layout's image size: a frame declaring or holding more is refused before
    # more than one image's worth of memory is allocated.
    try:
        raw = lz4_decompress_bounded(blob, expected)
    except DecodeError as exc:
        raise DecodeError(
            f"{where} is not an LZ4 frame of a {layout.width}x{layout.height} "
            f"{layout.depth_dtype.name} image: {exc}"
        ) from exc
    image: npt.NDArray[Any] = np.frombuffer(raw, layout.depth_dtype).reshape(
        layout.height, layout.width
    )
    return image
