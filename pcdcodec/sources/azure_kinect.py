"""Azure Kinect ``.mkv`` recordings (``k4arecorder``, pyk4a) as a :class:`Source`.

A k4a recording is a Matroska file, read here with PyAV (no Azure Kinect SDK needed):

* a ``COLOR`` track (MJPEG, or raw NV12 / YUY2 / BGRA), a ``DEPTH`` track of raw 16-bit
  big-endian millimetres (``b16g``), an ``IR`` track and an ``IMU`` track; the captures'
  color and depth share a timestamp;
* tags ``K4A_DEPTH_MODE`` and ``K4A_COLOR_MODE`` on the tracks, ``K4A_DEVICE_SERIAL_NUMBER``
  and ``K4A_START_OFFSET_NS`` on the file;
* a ``calibration.json`` attachment: per camera the unitised Brown-Conrady intrinsics of the
  full sensor (``cx, cy, fx, fy, k1 … k6, codx, cody, p2, p1``, as fractions of the sensor
  size, 0 at the corner of the top-left pixel) and ``Rt``, the transform from the depth camera
  to that camera (rotation row-major, translation in metres).

The intrinsics of a depth mode or color resolution are those of the full sensor binned and
cropped to the mode's image, then moved so that pixel centres are whole numbers: the rule of
the Azure Kinect SDK's mode-specific calibration. The lens model is OpenCV's rational model.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError
from ..geometry.camera import CameraIntrinsics, as_intrinsics
from ..ros.kept import TopicFilter
from ..sync import MAX_DIFFERENCE, Synchronizer, as_max_difference
from . import _k4a_calibration as k4a
from ._k4a_kept import IMU_SAMPLE, K4aKeptTracks, imu_samples
from ._mkv import (
    EBML_MAGIC,
    blocks_by_track,
    declared_tag,
    has_cluster,
    list_tracks,
    packets,
    walk_blocks,
)
from ._mkv import track_name as _name
from .base import InputStream, Source, read_magic, register_source

__all__ = ["DEPTH_MODES", "IMU_SAMPLE", "AzureKinectSource", "imu_samples", "open_azure_kinect"]

_NS = 1_000_000_000

#: Depth mode -> (binned sensor resolution, crop offset, output size), all (x, y) in pixels.
DEPTH_MODES: dict[str, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    "NFOV_2X2BINNED": ((512, 512), (96, 90), (320, 288)),
    "NFOV_UNBINNED": ((1024, 1024), (192, 180), (640, 576)),
    "WFOV_2X2BINNED": ((512, 512), (0, 0), (512, 512)),
    "WFOV_UNBINNED": ((1024, 1024), (0, 0), (1024, 1024)),
    "PASSIVE_IR": ((1024, 1024), (0, 0), (1024, 1024)),
}
#: Color image height -> (sensor resolution scaled to 4:3, crop offset, output size).
COLOR_MODES: dict[int, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    720: ((1280, 960), (0, 120), (1280, 720)),
    1080: ((1920, 1440), (0, 180), (1920, 1080)),
    1440: ((2560, 1920), (0, 240), (2560, 1440)),
    1536: ((2048, 1536), (0, 0), (2048, 1536)),
    2160: ((3840, 2880), (0, 360), (3840, 2160)),
    3072: ((4096, 3072), (0, 0), (4096, 3072)),
}


#: color track FOURCC -> what it holds (k4arecorder's MJPEG, NV12 and YUY2 color modes)
_COLOR_FORMATS = {"MJPG": "mjpeg", "NV12": "nv12", "YUY2": "yuyv422"}
#: bytes of a raw color image of width w and height h
_RAW_BYTES = {"nv12": lambda w, h: w * h * 3 // 2, "yuyv422": lambda w, h: w * h * 2}


def _is_azure_kinect(path: Path) -> bool:
    if not path.is_file() or read_magic(path, 4) != EBML_MAGIC:
        return False
    with path.open("rb") as f:
        head = f.read(1 << 16)
    return b"K4A_" in head


def _start_offset(tags: dict[str, Any], where: str) -> int:
    """The ``K4A_START_OFFSET_NS`` tag: the device time of the file's time 0, in ns."""
    text = str(tags.get("K4A_START_OFFSET_NS", "") or "0").strip()
    if not text.isdigit() or len(text) > 18:
        raise InputError(
            f"{where}: tag K4A_START_OFFSET_NS is {text[:40]!r}; expected a whole number of "
            "nanoseconds, 0 to 10^18"
        )
    return int(text)


class AzureKinectSource(K4aKeptTracks, Source):
    """Frames of an Azure Kinect ``.mkv``: depth in millimetres (depth scale 1000) with the
    depth camera's intrinsics, color with the color camera's, and ``depth_to_color``.

    ``max_frames`` stops early; ``intrinsics`` replaces the calibrated depth camera;
    ``color=False`` reads the depth track alone (the COLOR track is then left out).
    ``metadata`` holds the serial number, the depth and color modes and the firmware versions.

    The other tracks and the attachments are kept (:meth:`kept_topics`, see
    :mod:`pcdcodec.sources._k4a_kept`): the IR images on ``/k4a/ir``, compressed losslessly
    with ``ir_codec`` (default: the recording's depth codec where it is lossless, else
    ``depthac``), the IMU blocks on ``/k4a/imu``, ``calibration.json`` and any other
    attachment on ``/k4a/attachment/<name>``; ``keep_topics``, ``include_topics`` and
    ``exclude_topics`` choose them by topic, as for a bag.

    A capture is a frame only when its color and depth images are both there and whole (each
    MJPEG packet is checked whole and of the color camera's size before it is decoded), paired
    by the rule of every reader (:mod:`pcdcodec.sync`: each image once, within
    ``max_difference`` ns, default 20 ms; the images of one capture share a timestamp). Other
    captures are dropped and reported: :attr:`dropped` counts their images by stream,
    :attr:`drop_reasons` the captures by reason, and :meth:`describe` gives both with the pts
    of the first few. With ``strict=True`` a damaged image raises
    :class:`~pcdcodec.DecodeError` naming the file and pts instead.

    Raises :class:`~pcdcodec.InputError` naming the file for a file without a depth track,
    without the ``calibration.json`` attachment or with a malformed one (naming the field),
    with an unknown depth mode or color resolution, a bad ``K4A_START_OFFSET_NS`` tag, a
    color track whose codec cannot be read, or without clusters (no captures).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        max_frames: int | None = None,
        intrinsics: CameraIntrinsics | None = None,
        strict: bool = False,
        max_difference: int = MAX_DIFFERENCE,
        color: bool = True,
        keep_topics: bool = True,
        include_topics: Sequence[str] | str | None = None,
        exclude_topics: Sequence[str] | str | None = None,
        ir_codec: Any = None,
    ) -> None:
        import av

        self.path = Path(path)
        self.max_frames = max_frames
        self.max_difference = as_max_difference(max_difference)
        self.strict = strict
        self.topic_filter = TopicFilter.of(include_topics, exclude_topics, keep_topics)
        self._dropped = {"color": 0, "depth": 0}
        #: why captures were dropped while reading: reason -> count
        self.drop_reasons: dict[str, int] = {}
        self._drop_pts: dict[str, list[int]] = {}
        self._damaged: dict[int, str] = {}
        self._drop_detail: dict[str, str] = {}
        #: what reading found wrong with the file's structure, or ``None``
        self.damage: str | None = None
        name = str(self.path)
        try:
            container = av.open(name)
        except UnicodeDecodeError as exc:
            raise InputError(f"{name!r}: a tag or track name is not UTF-8 text: {exc}") from None
        except (av.error.FFmpegError, OSError) as exc:
            if _is_azure_kinect(self.path) and not has_cluster(self.path):
                raise InputError(
                    f"{name!r} holds no clusters (no recorded captures): the recording stopped "
                    "before its first capture, or the file was cut short"
                ) from exc
            raise InputError(f"{name!r} is not a readable Matroska file: {exc}") from exc
        try:
            self._read_header(container, name, color)
            frames = {i for i in (self._depth_index, self._color_index) if i is not None}
            self._note_kept(container.streams, frames, ir_codec)
        except UnicodeDecodeError as exc:
            raise InputError(f"{name!r}: a tag or track name is not UTF-8 text: {exc}") from None
        finally:
            container.close()
        if intrinsics is not None:
            own = self.intrinsics  # a bare matrix takes the recorded depth camera's size
            size = (own.width, own.height) if own is not None else (None, None)
            self.intrinsics = as_intrinsics(intrinsics, "intrinsics", *size)

    def _read_header(self, container: Any, name: str, with_color: bool) -> None:
        where = repr(name)
        tags = dict(container.metadata)
        depth = color = None
        attachment = None
        for s in container.streams:
            meta = dict(s.metadata)
            # The K4A mode tags say what a track holds; the track name only without them.
            tagged = "K4A_DEPTH_MODE" in meta or "K4A_COLOR_MODE" in meta
            is_depth = "K4A_DEPTH_MODE" in meta or (not tagged and meta.get("title") == "DEPTH")
            is_color = "K4A_COLOR_MODE" in meta or (not tagged and meta.get("title") == "COLOR")
            prior: Any = depth if is_depth else color if is_color else None
            if prior is not None:
                raise InputError(
                    f"{name!r} has two {'DEPTH' if is_depth else 'COLOR'} tracks (tracks "
                    f"{prior.index + 1} and {s.index + 1})"
                )
            if (is_depth or is_color) and s.type != "video":
                # A camera track that does not read as video: refused, not left out.
                raise InputError(
                    f"{name!r}: the {'DEPTH' if is_depth else 'COLOR'} track (track "
                    f"{s.index + 1}) does not read as video (it reads as {s.type}); its CodecID "
                    "or CodecPrivate is damaged"
                )
            if is_depth:
                depth = s
            elif is_color:
                color = s
            elif s.type == "attachment" and meta.get("filename") == "calibration.json":
                attachment = s
        if depth is None:
            raise InputError(f"{name!r} has no Azure Kinect DEPTH track")
        if color is None and declared_tag(self.path, b"K4A_COLOR_MODE") not in (None, b"OFF"):
            raise InputError(
                f"{name!r} declares a color mode (tag K4A_COLOR_MODE) but its COLOR track does "
                "not read: its CodecID or CodecPrivate is damaged"
            )
        if not with_color:
            color = None  # depth only: the COLOR track is left out, and listed as such
        if attachment is None:
            raise InputError(
                f"{name!r} has no calibration.json attachment: the cameras' intrinsics and "
                "extrinsics cannot be known"
            )
        try:
            calibration = json.loads(bytes(attachment.data))
        except (ValueError, TypeError, AttributeError) as exc:
            raise InputError(f"{name!r}: calibration.json is not JSON: {exc}") from None
        cameras = k4a.field(calibration, ("CalibrationInformation", "Cameras"), where)
        if not isinstance(cameras, list) or not all(isinstance(c, dict) for c in cameras):
            raise InputError(
                f"{where}: calibration.json CalibrationInformation.Cameras is not a list of cameras"
            )
        by_purpose = {str(c.get("Purpose")): c for c in cameras}
        depth_cal = by_purpose.get("CALIBRATION_CameraPurposeDepth")
        if depth_cal is None:
            raise InputError(
                f"{where}: calibration.json has no camera of Purpose CALIBRATION_CameraPurposeDepth"
            )
        depth_mode = str(dict(depth.metadata).get("K4A_DEPTH_MODE", ""))
        if depth_mode not in DEPTH_MODES:
            raise InputError(
                f"{name!r} has depth mode {depth_mode!r}; expected one of {list(DEPTH_MODES)}"
            )
        mode = DEPTH_MODES[depth_mode]
        depth_ctx = depth.codec_context
        tag = str(getattr(depth_ctx, "codec_tag", "") or "") if depth_ctx is not None else ""
        if depth_ctx is None or tag != "b16g":
            raise InputError(
                f"{name!r}: the DEPTH track holds {tag or 'no known codec'!r}; expected raw "
                "16-bit big-endian depth (b16g)"
            )
        if (depth_ctx.width, depth_ctx.height) != mode[2]:
            raise InputError(
                f"{name!r}: depth mode {depth_mode} is {mode[2][0]}x{mode[2][1]}, but its track "
                f"is {depth_ctx.width}x{depth_ctx.height}"
            )
        self.intrinsics: CameraIntrinsics | None = k4a.camera_of(
            depth_cal, mode, "depth camera", where
        )
        self._depth_shape = (mode[2][1], mode[2][0])
        self.depth_scale = 1000.0
        self._depth_index = depth.index
        self._color_index: int | None = None
        self._color_format = ""
        self.metadata = {
            "source": "azure_kinect",
            "device": "Azure Kinect",
            "depth_mode": depth_mode,
        }
        for key, label in (
            ("K4A_DEVICE_SERIAL_NUMBER", "serial"),
            ("K4A_DEPTH_FIRMWARE_VERSION", "depth_firmware"),
            ("K4A_COLOR_FIRMWARE_VERSION", "color_firmware"),
        ):
            if key in tags:
                self.metadata[label] = str(tags[key])
        self._start_ns = _start_offset(tags, where)
        if color is not None:
            color_cal = by_purpose.get("CALIBRATION_CameraPurposePhotoVideo")
            if color_cal is None:
                raise InputError(f"{name!r}: calibration.json has no color camera")
            sw, sh = (color_cal.get(k) for k in ("SensorWidth", "SensorHeight"))
            if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (sw, sh)):
                raise InputError(
                    f"{where}: calibration.json color camera SensorWidth/SensorHeight are "
                    f"{sw!r}, {sh!r}; expected whole numbers of pixels"
                )
            if sw * 3 != sh * 4:
                raise InputError(
                    f"{name!r}: color calibration of a {sw}x{sh} sensor; only 4:3 calibrations "
                    "are supported"
                )
            ctx = color.codec_context
            fmt = "" if ctx is None or ctx.codec is None else str(ctx.codec.name)
            tag = str(getattr(ctx, "codec_tag", "") or "") if ctx is not None else ""
            fmt = _COLOR_FORMATS.get(tag, fmt if fmt == "mjpeg" else "")
            if not fmt:
                raise InputError(
                    f"{name!r}: the COLOR track holds {tag or 'no known codec'!r}; expected "
                    f"one of {', '.join(sorted(_COLOR_FORMATS))} (its CodecPrivate is damaged "
                    "or missing)"
                )
            w, h = int(ctx.width or 0), int(ctx.height or 0)
            if h not in COLOR_MODES or COLOR_MODES[h][2][0] != w:
                sizes = ", ".join(f"{m[2][0]}x{m[2][1]}" for m in COLOR_MODES.values())
                raise InputError(
                    f"{name!r}: color track is {w}x{h}, not an Azure Kinect color resolution "
                    f"({sizes})"
                )
            self.color_intrinsics = k4a.camera_of(color_cal, COLOR_MODES[h], "color camera", where)
            self.depth_to_color = k4a.rt(color_cal, "color camera", where) @ np.linalg.inv(
                k4a.rt(depth_cal, "depth camera", where)
            )
            self._color_index = color.index
            self._color_format = fmt
            self.metadata["color_mode"] = str(dict(color.metadata).get("K4A_COLOR_MODE", ""))
        self.has_color = color is not None
        self._count = int(depth.frames or 0)
        # Every track and attachment (their block counts read when first asked for).
        self._tracks = list_tracks(container.streams)
        self._recorded = {_name(t) for t in (depth, color) if t is not None} | {"calibration.json"}
        self._blocks: dict[int, int] | None = None

    def _block_counts(self) -> dict[int, int]:
        """The blocks each track holds, from the element heads (read once), or none when the
        file's structure is damaged (its counts would not be the captures')."""
        if self._blocks is None:
            counts, problem = blocks_by_track(self.path)
            self._blocks = {} if problem else counts
        return self._blocks

    def input_streams(self) -> list[InputStream]:
        """Every track (COLOR, DEPTH, IR, IMU) with its block count, and every attachment."""
        blocks = self._block_counts()
        return [
            InputStream(name, kind, None if number is None else blocks.get(number))
            for number, name, kind in self._tracks
        ]

    def recorded_streams(self) -> set[str]:
        """The DEPTH and COLOR tracks and the calibration, and the tracks and attachments kept
        (:meth:`kept_streams`)."""
        return set(self._recorded) | set(self.kept_streams())

    @property
    def dropped(self) -> dict[str, int]:
        """Images read but not made into frames so far, by stream (see :attr:`drop_reasons`)."""
        return dict(self._dropped)

    def describe(self) -> dict[str, Any]:
        out = super().describe()
        blocks = {i.name: i.count for i in self.input_streams()}
        for item in out["kept"]:
            item["messages"] = self.kept_count(item["name"], blocks)
        out["dropped"] = self.dropped
        out["notes"] = [
            f"dropped {n} capture(s): {reason} (first at pts "
            f"{', '.join(map(str, self._drop_pts[reason]))})"
            + (f": {self._drop_detail[reason]}" if reason in self._drop_detail else "")
            for reason, n in self.drop_reasons.items()
        ] + ([self.damage] if self.damage else [])
        return out

    def __len__(self) -> int:
        count = self._count
        if not count:
            # Unstated by the container: a capture is a depth block (and a color block).
            tracks = (self._depth_index, self._color_index)
            count = min(self._block_counts().get(t + 1, 0) for t in tracks if t is not None)
        if not count:
            raise TypeError("the depth track does not state its frame count")
        return count if self.max_frames is None else min(count, self.max_frames)

    def _drop(self, reason: str, pts: int, color: int, depth: int) -> None:
        self.drop_reasons[reason] = self.drop_reasons.get(reason, 0) + 1
        first = self._drop_pts.setdefault(reason, [])
        if len(first) < 3:
            first.append(pts)
        self._dropped["color"] += color
        self._dropped["depth"] += depth

    def _color(self, packet: Any, pts: int, where: str) -> npt.NDArray[np.uint8] | str:
        """The RGB image of a color packet, or why it is damaged: an MJPEG image is checked
        whole and of the camera's size before it is decoded, a raw one by its length."""
        import av

        from ..color.images import check_compressed

        assert self.color_intrinsics is not None
        h, w = self.color_intrinsics.shape
        data = bytes(packet)
        try:
            if self._color_format == "mjpeg":
                check_compressed(data, f"{where}: color packet at pts {pts}", (h, w))
            elif len(data) != _RAW_BYTES[self._color_format](w, h):
                return (
                    f"color packet at pts {pts} holds {len(data)} bytes, expected "
                    f"{_RAW_BYTES[self._color_format](w, h)} for {w}x{h} {self._color_format}"
                )
        except DecodeError as exc:
            return str(exc)
        try:
            frames = list(packet.decode())
            if len(frames) != 1:
                return f"color packet at pts {pts} decodes to {len(frames)} images"
            img = np.asarray(frames[0].to_ndarray(format="rgb24"), dtype=np.uint8)
        except (av.error.FFmpegError, ValueError) as exc:
            return f"color packet at pts {pts} does not decode: {exc}"
        if img.shape != (h, w, 3):
            return f"color packet at pts {pts} decodes to {img.shape}, expected {(h, w, 3)}"
        return img

    def __iter__(self) -> Iterator[Any]:
        import av

        from ..frame import Frame as RGBDFrame

        name = str(self.path)
        where = repr(name)
        self._dropped = {"color": 0, "depth": 0}
        self._counted = {"color": 0, "depth": 0}  # the stamps the pairing dropped, counted
        self.drop_reasons = {}
        self._drop_pts = {}
        self._damaged = {}
        self._drop_detail = {}
        self.damage = None
        try:
            container = av.open(name)
        except (av.error.FFmpegError, OSError, UnicodeDecodeError) as exc:
            raise DecodeError(f"{where} is not a readable Matroska file: {exc}") from exc
        try:
            depth_stream = container.streams[self._depth_index]
            streams = [depth_stream]
            has_color = self._color_index is not None
            if self._color_index is not None:
                streams.append(container.streams[self._color_index])
            h, w = self._depth_shape
            # Color and depth pair by the rule of every reader (pcdcodec.sync): the images of
            # one capture share a timestamp, so few wait; one whose partner has not come once
            # the other stream has passed it by max_difference never will, and is counted.
            sync: Synchronizer[Any, Any] = Synchronizer(
                max_difference=self.max_difference, max_queue=8
            )
            last = {"color": -1, "depth": -1}
            pts_of: dict[tuple[str, int], int] = {}
            emitted = 0
            seen = 0
            tb = depth_stream.time_base
            tb_ns = float(tb * _NS) if tb is not None else 1000.0
            # Every track is demuxed, so that the packets can be counted against the blocks.
            wanted = {s.index for s in streams}
            delivered = 0
            for packet in packets(container, None, where):
                delivered += 1
                if packet.pts is None or packet.stream.index not in wanted:
                    continue
                seen += 1
                pts = int(packet.pts)
                kind = "depth" if packet.stream.index == self._depth_index else "color"
                item: Any
                if kind == "depth":
                    raw = bytes(packet)
                    if len(raw) != 2 * w * h:
                        self._fail(
                            f"depth packet at pts {pts} holds {len(raw)} bytes, expected "
                            f"{2 * w * h} for {w}x{h} 16-bit depth",
                            "damaged depth",
                            pts,
                            0,
                            1,
                        )
                        continue
                    item = np.frombuffer(raw, dtype=">u2").reshape(h, w).astype(np.uint16)
                else:
                    item = self._color(packet, pts, where)
                    if isinstance(item, str):
                        self._fail(item, "damaged color", pts, 1, 0)
                        continue
                ns = self._start_ns + round(pts * tb_ns)
                if ns <= last[kind]:
                    why = "with one timestamp" if ns == last[kind] else "out of time order"
                    self._drop(f"two {kind} images {why}", pts, *_one(kind))
                    continue
                last[kind] = ns
                pts_of[(kind, ns)] = pts
                if not has_color:
                    ready = [(ns, None, ns, item)]
                elif kind == "depth":
                    ready = sync.add_depth(ns, item)
                else:
                    ready = sync.add_color(ns, item)
                self._unpaired(sync, pts_of)
                for cts, color, dts, depth in ready:
                    pts_of.pop(("color", cts), None)
                    pts_of.pop(("depth", dts), None)
                    yield RGBDFrame(color, depth, dts, color_timestamp_ns=cts)
                    emitted += 1
                    if self.max_frames is not None and emitted >= self.max_frames:
                        return
            for cts, color, dts, depth in sync.flush():
                yield RGBDFrame(color, depth, dts, color_timestamp_ns=cts)
                emitted += 1
                if self.max_frames is not None and emitted >= self.max_frames:
                    return
            self._unpaired(sync, pts_of)
            self._check_structure(delivered)
            if seen == 0:
                raise InputError(
                    f"{name!r} holds no captures (no clusters with color or depth data)"
                )
        finally:
            container.close()

    def _check_structure(self, delivered: int) -> None:
        """Compare the blocks the file's clusters hold with the packets the demuxer gave: FFmpeg
        skips a damaged cluster, and stops at a cut, without a word. What it lost is reported
        in :attr:`damage` and the notes (an error with ``strict``)."""
        blocks, problem = walk_blocks(self.path)
        why = []
        if problem:
            why.append(problem)
        if blocks > delivered:
            why.append(f"{blocks - delivered} of its {blocks} blocks could not be read")
        if not why:
            return
        self.damage = f"the file is damaged: {'; '.join(why)}: captures in it may be lost"
        if self.strict:
            raise DecodeError(f"{str(self.path)!r}: {self.damage}")

    def _unpaired(self, sync: Synchronizer[Any, Any], pts_of: dict[tuple[str, int], int]) -> None:
        """Count the images ``sync`` dropped since last asked, each under its reason (the
        partner of a damaged image is counted there, without a reason of its own)."""
        for kind, stamps in (("depth", sync.dropped_depth), ("color", sync.dropped_color)):
            for ns in stamps[self._counted[kind] :]:
                pts = pts_of.pop((kind, ns))
                if pts in self._damaged:
                    self._dropped[kind] += 1
                    continue
                other = "color" if kind == "depth" else "depth"
                self._drop(f"a {kind} image without its {other} image", pts, *_one(kind))
            self._counted[kind] = len(stamps)

    def _fail(self, why: str, reason: str, pts: int, color: int, depth: int) -> None:
        """A damaged image: an error naming the file in strict mode, else a dropped capture."""
        if self.strict:
            raise DecodeError(f"{str(self.path)!r}: {why}")
        self._damaged[pts] = why
        self._drop_detail.setdefault(reason, why.replace(f"{str(self.path)!r}: ", ""))
        self._drop(reason, pts, color, depth)


def _one(kind: str) -> tuple[int, int]:
    """(color, depth) counts of one image of ``kind``."""
    return int(kind == "color"), int(kind == "depth")


def open_azure_kinect(path: str | Path, **options: Any) -> AzureKinectSource:
    """Open an Azure Kinect ``.mkv`` (see :class:`AzureKinectSource` for the options)."""
    return AzureKinectSource(path, **options)


register_source(
    "azure_kinect",
    _is_azure_kinect,
    open_azure_kinect,
    "an Azure Kinect .mkv from k4arecorder (Matroska with K4A tags)",
)
