"""Export of a recording as the paper layout: the color packets muxed into a video, the depth
as LZ4 frames, and frames.json describing both (:mod:`.paper_layout`).

Color is muxed as it is, never re-encoded, and the video is then decoded in full to check that
every frame plays at its pts. The layout is described in :mod:`pcdcodec.convert.paper`.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path
from typing import Any

from .._atomic import named_output_errors, partial_path
from .._validate import check_depth
from ..color.base import StreamCodec
from ..color.ffmpeg import ffmpeg_packet
from ..color.pyav import PyAVCodec
from ..errors import CodecUnavailableError, DecodeError, InputError, PcdcodecError
from ..recording.reader import Recording
from .paper_layout import (
    AVI_CODECS,
    DEPTH_FILE,
    FRAMES_FILE,
    NS_PER_S,
    VIDEO_FILES,
    bitstream_name,
    frames_document,
)

__all__ = ["export_paper"]


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
    float recordings); ``frames.json`` describes both (see :mod:`pcdcodec.convert.paper`). Files are
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
    # A folder made here goes again when the export fails: nothing is left behind.
    made = not out.exists()
    try:
        return _export(recording_path, out, progress)
    except BaseException:
        if made and out.is_dir():
            with contextlib.suppress(OSError):
                out.rmdir()  # only when empty: the partial files are gone by now
        raise


def _export(
    recording_path: str | os.PathLike[str],
    out: Path,
    progress: Callable[[int], None] | None,
) -> dict[str, Any]:
    """:func:`export_paper` past its checks of ``out``."""
    # An error writing the output names the folder, not a partial file in it.
    with named_output_errors(out), Recording(recording_path) as rec:
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
            doc = frames_document(rec, spans, dtype, video, pts_of)
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
    return "avi" if bitstream_name(codec) in AVI_CODECS else "matroska"


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
    canonical = bitstream_name(codec)
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
            last = pts_of[t] = max(round(Fraction(t - origin, NS_PER_S) / time_base), last + 1)
    color_height, color_width = rec.color_shape  # the color camera's, where it is apart
    width, height = codec.padded_size(color_width, color_height)

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
                dts = min(pts, round(Fraction(packet.dts - origin, NS_PER_S) / time_base))
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
