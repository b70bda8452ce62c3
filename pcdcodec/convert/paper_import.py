"""Import of the paper layout: its video and LZ4 depth back into a ``.pcdc`` recording.

The video's packets are demuxed and written into the recording as they are; H.264 and H.265
are turned back from the container's length-prefixed form into Annex B, and decoding
timestamps, which containers such as Matroska do not keep, are rebuilt. Each packet goes with
the frames.json frame of its pts (:mod:`.paper_layout` reads frames.json).
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from .._atomic import atomic_output
from ..color.base import Packet
from ..color.pyav import PyAVCodec
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import DecodeError, InputError, PcdcodecError
from ..recording.writer import RecordingWriter
from ..registry import codec_class, get_codec
from .paper_layout import (
    CODEC_IDS,
    NS_PER_S,
    Layout,
    LayoutFrame,
    bitstream_name,
    field_error,
    read_layout,
)

__all__ = ["import_paper"]

#: Packets looked ahead to give imported packets decoding timestamps (H.264's deepest reorder).
_REORDER_WINDOW = 16


class _VideoSource:
    """The color packets of a paper layout's video, demuxed in decode order, times in ns."""

    def __init__(self, path: Path, layout: Layout) -> None:
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

    def _init(self, layout: Layout) -> None:
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
                raise field_error(
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
        return self._origin + round(pts * self.time_base * NS_PER_S)

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


def _color_codec(layout: Layout, source: _VideoSource) -> PyAVCodec:
    """The recording's color codec: the config in frames.json, else the defaults for the
    video's bitstream."""
    video = str(source.path)
    if layout.color_codec is not None:
        try:
            codec = get_codec(layout.color_codec, kind="color")
        except PcdcodecError as exc:
            raise field_error(layout.path, "color_codec", f"is not usable: {exc}") from None
        if not isinstance(codec, PyAVCodec):
            raise field_error(layout.path, "color_codec", f"names {codec.name!r}, not a PyAV codec")
        if bitstream_name(codec) != source.canonical:
            raise field_error(
                layout.path,
                "color_codec",
                f"names {codec.name!r} ({bitstream_name(codec)}), but {video!r} holds "
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
    layout = read_layout(folder)
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
    try:
        # The codec that wrote the packets is recorded; its encoder is never opened
        # (write_encoded), so a layout recorded with, say, NVENC imports anywhere.
        color = _color_codec(layout, source) if source is not None else None
        with atomic_output(out) as tmp:
            writer = RecordingWriter(
                tmp,
                intrinsics=layout.intrinsics,
                depth_scale=layout.depth_scale,
                color=color,
                depth=depth,
                fps=layout.fps,
                metadata=layout.metadata,
                frame_id=layout.frame_id,
                color_intrinsics=layout.color_intrinsics,
                depth_to_color=layout.depth_to_color,
            )
            try:
                with open(depth_path, "rb") as fh:
                    _write_frames(writer, layout, fh, depth_path, source, progress)
                writer.close()
            except BaseException:
                writer.abort()
                raise
    finally:
        if source is not None:
            source.close()
    return len(layout.frames)


def _write_frames(
    writer: RecordingWriter,
    layout: Layout,
    fh: IO[bytes],
    depth_path: Path,
    source: _VideoSource | None,
    progress: Callable[[int], None] | None,
) -> None:
    n = len(layout.frames)
    groups = _frame_groups(source, n) if source is not None else None
    for f in layout.frames:
        image = _read_depth(fh, f, layout, depth_path)
        kept: dict[str, Any] = {
            "pose": f.pose,
            "color_timestamp": f.color_timestamp_ns,
            "depth_timestamp": f.depth_timestamp_ns,
        }
        if groups is not None and source is not None:
            writer.write_encoded(
                next(groups), image, f.timestamp_ns, extradata=source.extradata, **kept
            )
        else:
            writer.write(None, image, f.timestamp_ns, **kept)
        if progress is not None:
            progress(f.index + 1)


def _read_depth(fh: IO[bytes], f: LayoutFrame, layout: Layout, path: Path) -> npt.NDArray[Any]:
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
