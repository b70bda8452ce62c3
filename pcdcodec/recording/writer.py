"""Writing a ``.pcdc`` recording: the checks on what is handed in, and its way to the file.

:class:`RecordingWriter` checks each camera once (when it opens) and each frame once (when it is
handed in); its :class:`~pcdcodec.recording._pipeline.Pipeline` encodes the frames with the
codecs, and its :class:`~pcdcodec.recording._container.Container` writes what they made into the
file. The records the file starts with are defined in :mod:`pcdcodec.recording._header`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from .._validate import check_color, check_depth, check_depth_scale
from ..color import DEFAULT_COLOR_CODEC
from ..color.base import Packet, StreamCodec, VideoEncoder
from ..color.fork import check_not_inherited, inherited, keep_in_child
from ..depth import DEFAULT_DEPTH_CODEC
from ..depth.base import FrameCodec
from ..errors import InputError, InputTypeError, PcdcodecError
from ..geometry.projector import check_color_camera
from ..geometry.transform import as_rigid
from ..registry import as_codec
from ..ros.kept import KeptMessage, KeptTopic
from . import _header as header
from . import _index as fmt
from ._container import Container, SharedFile
from ._inputs import FrameInputs
from ._kept import KEPT_VERSION, KeptChannels
from ._kept_pack import kept_packer
from ._pipeline import Pipeline

__all__ = ["MAX_TIMESTAMP_NS", "RecordingWriter"]

_NS = 1_000_000_000
#: The latest timestamp a recording holds: the ROS messages it stores (camera calibration,
#: CompressedVideo) keep time as int32 seconds, so 2038-01-19 03:14:07.999999999 UTC.
MAX_TIMESTAMP_NS = fmt.MAX_TIMESTAMP_NS


def open_output(path: Path, overwrite: bool) -> tuple[Path, IO[bytes]]:
    """The file a writer writes ``path`` through, opened: ``path`` itself, or, when it
    replaces an existing file, a partial file beside it, swapped in by :func:`end_close`, so the
    old file survives until the new one is complete."""
    if path.exists() and not overwrite:
        raise InputError(f"{str(path)!r} already exists; pass overwrite=True to replace it")
    if path.is_dir():
        raise InputError(f"{str(path)!r} is a folder, not a file")
    from .._atomic import is_partial, named_output_errors, partial_path  # not loaded at import

    writing = partial_path(path) if path.exists() else path
    mode = "xb" if writing == path else "wb"
    if is_partial(path.name):  # the caller's output, written beside it: the caller names it
        return writing, open(writing, mode)
    with named_output_errors(path):  # a folder not writable is said of `path`, not a partial
        return writing, open(writing, mode)


def end_close(
    errors: list[BaseException], broken: BaseException | None, writing: Path, target: Path
) -> None:
    """The end of a writer's close: raise the first error (or, when none was raised in the
    close, the failure that broke the file earlier), keeping a replaced file as it was; else
    swap the new file in."""
    if broken is not None and not errors:
        # Raised before, by the call it failed in: the file is still unfinished.
        unfinished = PcdcodecError(
            f"{str(writing)!r} was left unfinished: writing it failed before ({broken!r}); "
            "its frames before the failure read, and `pcdcodec recover` gives it an index"
        )
        unfinished.__cause__ = broken  # what broke it: a full disk, say
        errors.append(unfinished)
    if errors:
        add_note = getattr(errors[0], "add_note", None)  # Python 3.11+
        if writing != target and add_note is not None:
            add_note(
                f"{str(target)!r} was left as it was; the frames written are in {str(writing)!r}"
            )
        raise errors[0]
    if writing != target:
        os.replace(writing, target)


_STAMP_NAMES = ("color_timestamp", "depth_timestamp")


def _own_stamp(value: Any, name: str) -> int | None:
    """An image's own time (ns) as :meth:`RecordingWriter.write` takes it, checked."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{name} must be an int (ns), got {type(value).__name__}")
    if not 0 <= int(value) <= MAX_TIMESTAMP_NS:
        raise InputError(f"{name} {int(value)} ns is outside 0 to {MAX_TIMESTAMP_NS} ns")
    return int(value)


def _checked_packet(k: int, packet: Any) -> Packet:
    """Packet ``k`` of a group for :meth:`RecordingWriter.write_encoded`, checked on the
    caller's thread: a value the file cannot hold, met on the writing thread, would be raised
    only later, after part of the frame was written."""
    if not isinstance(packet, Packet):
        raise InputTypeError(f"packet {k} is a {type(packet).__name__}, expected a Packet")
    data = packet.data
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise InputTypeError(f"packet {k}: data is a {type(data).__name__}, expected bytes")
    for name, value, low in (("pts", packet.pts, 0), ("dts", packet.dts, -MAX_TIMESTAMP_NS)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise InputTypeError(
                f"packet {k}: {name} is a {type(value).__name__}, expected an int (ns)"
            )
        if not low <= int(value) <= MAX_TIMESTAMP_NS:
            raise InputError(
                f"packet {k}: {name} {int(value)} ns is outside what a recording holds "
                f"({low} to {MAX_TIMESTAMP_NS} ns)"
            )
    if not isinstance(packet.keyframe, (bool, np.bool_)):
        raise InputTypeError(
            f"packet {k}: keyframe is a {type(packet.keyframe).__name__}, expected a bool"
        )
    if isinstance(data, bytes) and all(
        type(v) is t for v, t in ((packet.pts, int), (packet.dts, int), (packet.keyframe, bool))
    ):
        return packet
    return Packet(
        bytes(data), int(packet.pts), int(packet.dts), bool(packet.keyframe), packet.checksum
    )


class RecordingWriter(FrameInputs):
    """Writes RGB-D frames into a ``.pcdc`` file (an MCAP file; see ``docs/format.md``).

    Use :func:`pcdcodec.open` with mode ``"w"`` rather than this class directly. Color and depth
    of each frame are encoded on two threads while the caller prepares the next frame, and a
    third thread writes each frame to the file, in the order handed in, as soon as both are
    encoded, whether or not more frames follow: an idle writer has everything handed in
    written and flushed within milliseconds. When the caller hands in frames faster than the
    codecs encode them, at most ``in_flight`` frames wait in memory and :meth:`write` blocks
    until one is written, so memory stays bounded however long the recording. If the process
    dies, every frame whose messages were written (``frames_complete``) can be read back, and
    ``pcdcodec recover`` rewrites the file with an index. Lost are only the frames not yet
    encoded (at 30 fps with the default codecs, at most the frame being handed in, from the
    first frame on: the codecs are made ready while the writer opens, see :attr:`ready`) and
    those a video encoder holds back, which at the codecs' defaults (``low_delay=True``) is
    none, except for AV1 (about 55; see ``docs/format.md``). An error while encoding or
    writing a frame in the background is raised by the next :meth:`write`, :meth:`flush` or
    :meth:`close`.
    """

    _file: IO[bytes]
    _container: Container

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        intrinsics: Any,
        depth_scale: float | None = None,
        color: Any = DEFAULT_COLOR_CODEC,
        depth: Any = DEFAULT_DEPTH_CODEC,
        fps: float = 30.0,
        metadata: dict[str, Any] | None = None,
        overwrite: bool = False,
        in_flight: int = 4,
        frame_id: str = "camera",
        color_intrinsics: Any = None,
        depth_to_color: Any = None,
        world_frame_id: str = "world",
        kept_topics: Sequence[KeptTopic] = (),
        kept_images: str = "lossless",
        _shared: SharedFile | None = None,
        _camera: str | None = None,
    ) -> None:
        self.path = Path(path)
        self.intrinsics = header.writer_camera(intrinsics)
        self.color_intrinsics, self.depth_to_color = check_color_camera(
            None if color_intrinsics is None else header.writer_camera(color_intrinsics),
            depth_to_color,
        )
        self.world_frame_id = world_frame_id
        # float32 depth is metres only at depth_scale 1.0: the uint16 default (1000, millimetres)
        # would put its points 1000x too near the camera, so float32 frames need it given.
        self._scale_given = depth_scale is not None
        self.depth_scale = check_depth_scale(1000.0 if depth_scale is None else depth_scale)
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 1000:
            raise InputError(f"fps must be a number in (0, 1000], got {fps!r}")
        self.fps = float(fps)
        if not isinstance(in_flight, int) or in_flight < 1:
            raise InputError(f"in_flight must be a positive int, got {in_flight!r}")
        if not isinstance(frame_id, str):
            raise InputTypeError(f"frame_id must be a str, got {frame_id!r}")
        self.frame_id = frame_id
        depth_codec = as_codec(depth, "depth")
        if not isinstance(depth_codec, FrameCodec):
            raise InputTypeError(f"depth codec {depth_codec.name!r} is not a frame codec")
        self.depth_codec = depth_codec
        # Each frame is checked once, where it is handed in; the built-in codecs then take the
        # checked image. A codec that overrides encode() gets every frame through it.
        self._encode_depth = (
            depth_codec.encode_checked
            if type(depth_codec).encode is FrameCodec.encode
            else depth_codec.encode
        )
        self.color_codec: StreamCodec | None = None
        if color is not None:
            color_codec = as_codec(color, "color")
            if not isinstance(color_codec, StreamCodec):
                raise InputError(
                    f"color codec {color_codec.name!r} writes whole video files, not packets; "
                    "recordings need a stream codec such as 'h264' or 'ffv1'"
                )
            self.color_codec = color_codec
        self.depth_codec._require_available()
        user = header.user_metadata(metadata)
        two_cameras = self.color_intrinsics is not None
        packer = kept_packer(kept_images, depth_codec, self.intrinsics, self.depth_scale)
        kept = KeptChannels(kept_topics, packer) if kept_topics else None
        if kept is not None and _shared is not None:
            raise InputError("a camera of a rig keeps no topics of its own")
        self._settings = header.Settings(
            KEPT_VERSION
            if kept is not None
            else header.Settings.version_for(self.intrinsics, two_cameras),
            self.intrinsics,
            self.depth_scale,
            self.fps,
            self.depth_codec.stored_config(),
            self.color_codec.stored_config() if self.color_codec else None,
            self.frame_id,
            self.color_intrinsics,
            self.depth_to_color,
        )

        video_format = self.color_codec.video_format if self.color_codec else None
        keep_in_child(self)  # a forked process never frees or finishes it (color/fork.py)
        #: Whether this writer has the file alone (else it is one camera of a rig's file).
        self._owns_file = _shared is None
        if _shared is not None:
            # One camera of a rig (:class:`~pcdcodec.recording.rig.RigWriter`), which opened
            # the file, writes its records and finishes it.
            self._target = self._writing = _shared.writing
            self._file = _shared.file
            self._container = Container(
                _shared.file,
                _shared.writing,
                self._settings,
                video_format=video_format,
                world_frame_id=world_frame_id,
                camera=_camera,
                shared=_shared,
            )
        else:
            self._open_file(overwrite, video_format, user, kept)
        self._encoder: VideoEncoder | None = None
        self._pipeline = Pipeline(in_flight, lambda: self._drain_one())
        # The codecs are made ready now: depthac's compiled loops loaded, the video encoder
        # open, the threads running. Else the first frames wait for them (most of a second),
        # and a kill then loses every frame handed in meanwhile.
        shape = (self.intrinsics.height, self.intrinsics.width)
        try:
            self._pipeline.start(lambda: self.depth_codec.warm_up(shape), self._open_encoder)
        except BaseException:  # interrupted: no thread runs on, and no file is left behind
            self._pipeline.abort()
            if self._owns_file:
                self._file.close()
                self._writing.unlink(missing_ok=True)
            raise
        self._shape: tuple[int, int] | None = None
        self._depth_dtype: np.dtype[Any] | None = None
        self._last_ts: int | None = None
        self._sync: Any = None
        self._poses: dict[int, npt.NDArray[np.float64]] = {}
        self._stamps: dict[int, tuple[int, int]] = {}
        self._mode: str | None = None  # "frames" (write) or "encoded" (write_encoded)
        self._closed = False

    def _open_file(
        self,
        overwrite: bool,
        video_format: str | None,
        user: dict[str, str],
        kept: KeptChannels | None = None,
    ) -> None:
        """Create the file (beside an existing one it replaces) and write its records."""
        self._target = self.path
        self._writing, self._file = open_output(self.path, overwrite)
        self._container = Container(
            self._file,
            self._writing,
            self._settings,
            video_format=video_format,
            world_frame_id=self.world_frame_id,
            kept=kept,
        )
        try:
            self._start(user)
        except BaseException:
            # A writer that never started leaves nothing behind, so a retry finds no file.
            self._file.close()
            self._writing.unlink(missing_ok=True)
            raise

    def _start(self, user: dict[str, str]) -> None:
        """Write the file's header and metadata."""
        self._container.start(user)

    @property
    def _mcap(self) -> Any:
        """The MCAP writer of the file."""
        return self._container.mcap

    # -- what was written ------------------------------------------------------------------

    @property
    def frames_complete(self) -> int:
        """Frames whose messages are all written: readable even if the process dies now."""
        return self._container.frames_complete

    @property
    def frames_written(self) -> int:
        """Frames whose depth and digest are written (their color may follow)."""
        return self._container.frames_written

    @property
    def bytes_color(self) -> int:
        """Bytes of color packets written."""
        return self._container.bytes_color

    @property
    def bytes_depth(self) -> int:
        """Bytes of encoded depth written."""
        return self._container.bytes_depth

    @property
    def poses_written(self) -> int:
        """Frames written with a pose."""
        return self._container.poses_written

    # -- writing -----------------------------------------------------------------------

    @property
    def color_shape(self) -> tuple[int, int]:
        """``(height, width)`` of the color images: the color camera's, else the depth's."""
        return self._settings.color_shape

    def _start_stream(
        self,
        height: int,
        width: int,
        timestamp: int,
        *,
        encoded: bool = False,
        extradata: bytes | None = None,
    ) -> None:
        if (width, height) != (self.intrinsics.width, self.intrinsics.height):
            raise InputError(
                f"frames are {width}x{height}, but the intrinsics are for "
                f"{self.intrinsics.width}x{self.intrinsics.height} (width x height)"
            )
        if encoded:
            self._encoder = None  # packets encoded elsewhere: the one opened is not used
        elif self.color_codec is not None:
            if self._encoder is None:  # it did not open with the writer: say why now
                self._encoder = self._new_encoder(self.color_codec)
            extradata = self._encoder.extradata
        # Through to_file: nothing is written once the file is broken (another camera of a rig
        # failed part way through a record), and a failure here stops every camera.
        container = self._container
        container.to_file(lambda: container.start_streams(height, width, timestamp, extradata))
        self._shape = (height, width)

    def _new_encoder(self, codec: StreamCodec) -> VideoEncoder:
        codec._require_available()
        ch, cw = self.color_shape
        return codec.encoder(cw, ch, self.fps)

    def _open_encoder(self) -> None:
        """Open the video encoder ahead of the first frame, where it opens: a writer given
        encoded packets (:meth:`write_encoded`) needs neither it nor its library, so a codec
        that cannot open here says so at the first :meth:`write`, as before."""
        if self.color_codec is not None and self.color_codec.is_available():
            try:
                self._encoder = self._new_encoder(self.color_codec)
            except PcdcodecError:
                self._encoder = None

    @property
    def ready(self) -> bool:
        """Whether the codecs are ready for frames: the depth codec's start-up paid (see
        :meth:`~pcdcodec.depth.base.FrameCodec.warm_up`), the video encoder open (where the
        recording encodes color) and the threads running. True once the writer has opened,
        unless the encoder could not open (the first :meth:`write` then says why)."""
        return self._pipeline.started and (
            self.color_codec is None or self._encoder is not None or self._mode == "encoded"
        )

    def write(
        self,
        color: Any,
        depth: Any,
        timestamp: int | None = None,
        *,
        pose: Any = None,
        color_timestamp: int | None = None,
        depth_timestamp: int | None = None,
    ) -> None:
        """Add one frame: ``color`` H×W×3 uint8 RGB (``None`` when recording depth only) and
        ``depth`` H×W uint16 depth units (or float32 metres where the depth codec takes it).
        With a color camera apart from depth, ``color`` is of the color camera's size.

        ``timestamp`` is in nanoseconds and must increase; without it, frames are spaced at
        ``1/fps`` from 0. ``pose`` is the camera-to-world pose of the depth camera at this
        frame, a rigid 4 × 4 transform in metres, stored as a ``FrameTransform`` from
        ``world_frame_id`` to ``frame_id`` on ``/camera/pose``. ``color_timestamp`` and
        ``depth_timestamp`` (ns) are each image's own time where the input stamps them apart
        from the frame's (TUM lists); they are kept (``/camera/stamps``) and read back as
        ``frame.color_timestamp_ns`` and ``frame.depth_timestamp_ns``. Raises
        :class:`~pcdcodec.InputError` for frames of another size than the first, color of
        another size than the color camera's, timestamps that do not increase, a pose that is
        not a rigid 4 × 4 transform, or bad arrays; the frames already written stay intact.

        The frame is encoded and written in the background; ``write()`` returns at once unless
        ``in_flight`` frames already wait, and then blocks until one is written. An error met
        encoding or writing an earlier frame is raised here, before this frame is taken (call
        again to hand it in); the frames handed in after the failed one are still written.
        """
        check_not_inherited(self, f"the writer of {str(self.path)!r}")
        self._check_open()
        self._raise_background_error()
        self._take(color, depth, timestamp, pose, (color_timestamp, depth_timestamp))

    @property
    def kept_topics(self) -> list[KeptTopic]:
        """The other topics of the input this recording keeps as they came."""
        kept = self._container.kept
        return [] if kept is None else list(kept.topics)

    @property
    def kept_written(self) -> dict[str, tuple[int, int]]:
        """Kept messages written so far, per topic: ``(messages, bytes)``."""
        kept = self._container.kept
        return {} if kept is None else {t: (n, b) for t, (n, b) in kept.written.items()}

    def write_message(self, message: KeptMessage) -> None:
        """Keep one message of a kept topic (one of ``kept_topics``, given when opening) as it
        came: its bytes, log and publish time. Messages are gathered into zstd chunks of about
        1 MiB (:data:`~pcdcodec.recording._kept.CHUNK_BYTES`), written as each fills and on
        :meth:`close`. Images and organized clouds are packed where they rebuild exactly
        (``kept_images``, ``docs/bags.md``). Raises :class:`~pcdcodec.InputError` for a topic
        not given."""
        check_not_inherited(self, f"the writer of {str(self.path)!r}")
        self._check_open()
        self._container.add_kept(message)

    def _check_float_scale(self, depth: npt.NDArray[Any]) -> None:
        if depth.dtype == np.float32 and not self._scale_given:
            raise InputError(
                "float32 depth needs depth_scale given when the recording is opened: 1.0 for "
                "metres (as ROS 32FC1), else its units per metre; the default, 1000, is for "
                "uint16 millimetres and would scale float metres 1000x too small"
            )

    def _take(
        self,
        color: Any,
        depth: Any,
        timestamp: int | None,
        pose: Any,
        stamps: tuple[int | None, int | None] = (None, None),
    ) -> None:
        """:meth:`write` past its checks for an open writer and earlier errors."""
        rigid = None if pose is None else as_rigid(pose, "pose")
        if self._mode == "encoded":
            raise InputError("this recording takes encoded color (write_encoded), not images")
        timestamp = self._next_timestamp(timestamp)
        own = [_own_stamp(t, name) for t, name in zip(stamps, _STAMP_NAMES, strict=True)]
        d = check_depth(depth, allowed=self.depth_codec.dtypes, name="depth")
        self._check_float_scale(d)
        rgb: npt.NDArray[np.uint8] | None = None
        if self.color_codec is None and color is not None:
            raise InputError(
                "this recording is depth only (color=None); pass None as color, or open it "
                "with a color codec to keep the color images"
            )
        if self.color_codec is not None:
            if color is None:
                raise InputError("this recording has color: pass a color image with each frame")
            if self.color_intrinsics is None:
                rgb = check_color(color, d.shape, name="color")
            else:
                rgb = check_color(
                    color, self.color_shape, name="color", expected="the color camera's size"
                )
        self._check_shape(d, timestamp)
        self._mode = "frames"
        self._last_ts = timestamp
        # Copies: the caller may reuse its buffers while the threads encode.
        fut_color = (
            self._pipeline.encode_color(self._encode_color, rgb.copy(), timestamp)
            if rgb is not None
            else None
        )
        if color is None:
            own[0] = None  # no color image, no color time
        self._keep_pose_and_stamps(timestamp, rigid, own)
        self._enqueue(timestamp, fut_color, d)

    def _keep_pose_and_stamps(
        self, timestamp: int, rigid: npt.NDArray[np.float64] | None, own: list[int | None]
    ) -> None:
        """Keep a frame's pose and the (color, depth) images' own times that differ from it."""
        if rigid is not None:
            self._poses[timestamp] = rigid
        if any(t is not None and t != timestamp for t in own):
            self._stamps[timestamp] = (
                timestamp if own[0] is None else own[0],
                timestamp if own[1] is None else own[1],
            )

    def write_encoded(
        self,
        packets: Sequence[Packet],
        depth: Any,
        timestamp: int,
        *,
        extradata: bytes | None = None,
        pose: Any = None,
        color_timestamp: int | None = None,
        depth_timestamp: int | None = None,
    ) -> None:
        """Add a frame whose color is already encoded: the muxing half of the writer.

        ``packets`` are the color packets to store with this frame, in decode order, as this
        recording's color codec (whose config is recorded) would have written them: usually
        the frame's own packet, none for a frame whose packet came earlier, or several when a
        B-frame arrives with a later frame. ``depth``, ``timestamp``, ``pose``,
        ``color_timestamp`` and ``depth_timestamp`` are as for :meth:`write`; ``extradata``
        (the decoder's set-up bytes) is taken with the first frame. The codec's encoder is
        never opened, so packets from hardware encoders, other files or ROS bags go in
        unchanged. A recording takes either :meth:`write` frames or encoded ones, not both.
        Raises :class:`~pcdcodec.InputError` for a recording without color, items that are not
        :class:`~pcdcodec.color.base.Packet`, or the errors of :meth:`write`; like it, writes
        in the background and blocks while ``in_flight`` frames wait.
        """
        self._check_open()
        self._raise_background_error()
        if self.color_codec is None:
            raise InputError("this recording has no color codec: open it with the codec whose "
                             "packets these are")  # fmt: skip
        if self._mode == "frames":
            raise InputError("this recording encodes images (write); it cannot take packets too")
        group = [_checked_packet(k, p) for k, p in enumerate(packets)]
        rigid = None if pose is None else as_rigid(pose, "pose")
        own = [
            _own_stamp(t, name)
            for t, name in zip((color_timestamp, depth_timestamp), _STAMP_NAMES, strict=True)
        ]
        timestamp = self._next_timestamp(timestamp)
        d = check_depth(depth, allowed=self.depth_codec.dtypes, name="depth")
        self._check_float_scale(d)
        self._check_shape(d, timestamp, encoded=True, extradata=extradata)
        self._mode = "encoded"
        self._last_ts = timestamp
        self._keep_pose_and_stamps(timestamp, rigid, own)
        done: Future[list[Packet]] = Future()
        done.set_result(group)
        self._enqueue(timestamp, done, d)

    def _next_timestamp(self, timestamp: Any) -> int:
        if timestamp is None:
            timestamp = 0 if self._last_ts is None else self._last_ts + round(_NS / self.fps)
        if isinstance(timestamp, bool) or not isinstance(timestamp, (int, np.integer)):
            raise InputTypeError(f"timestamp must be an int (ns), got {type(timestamp).__name__}")
        ts = int(timestamp)
        if ts < 0:
            raise InputError(f"timestamp must not be negative, got {ts}")
        if ts > MAX_TIMESTAMP_NS:
            raise InputError(
                f"timestamp {ts} ns is later than a recording can hold: at most "
                f"{MAX_TIMESTAMP_NS} ns (2038-01-19 03:14:07 UTC; ROS time has int32 seconds)"
            )
        if self._last_ts is not None and ts <= self._last_ts:
            raise InputError(
                f"timestamp {ts} ns does not increase (previous frame: {self._last_ts} ns)"
            )
        return ts

    def _check_shape(
        self,
        d: npt.NDArray[Any],
        timestamp: int,
        *,
        encoded: bool = False,
        extradata: bytes | None = None,
    ) -> None:
        if self._shape is None:
            self._start_stream(
                d.shape[0], d.shape[1], timestamp, encoded=encoded, extradata=extradata
            )
            self._depth_dtype = d.dtype
        elif d.shape != self._shape:
            raise InputError(
                f"depth is {d.shape[1]}x{d.shape[0]}, but this recording's frames are "
                f"{self._shape[1]}x{self._shape[0]} (width x height)"
            )
        elif d.dtype != self._depth_dtype:
            # One depth_scale holds for the whole recording: uint16 units and float32 values
            # mixed would read back with one of them scaled wrong.
            raise InputError(
                f"depth is {d.dtype}, but this recording's frames are {self._depth_dtype}: "
                "one recording holds one depth type (convert with as_uint16_depth, or "
                "astype(np.float32), before writing)"
            )

    def _enqueue(
        self, timestamp: int, fut_color: Future[list[Packet]] | None, d: npt.NDArray[Any]
    ) -> None:
        # A copy: the caller may reuse its buffer while the thread encodes.
        self._pipeline.submit(timestamp, fut_color, self._encode_depth, d.copy())
        if self._container.kept is not None:  # kept images and clouds may refer to it
            self._container.kept.saw_frame(timestamp, d)

    def _raise_background_error(self) -> None:
        """Raise the first error met writing earlier frames; each is raised once."""
        self._pipeline.raise_error()

    @property
    def in_flight(self) -> int:
        """How many frames may wait to be written before :meth:`write` blocks."""
        return self._pipeline.in_flight

    @in_flight.setter
    def in_flight(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(f"in_flight must be a positive int, got {value!r}")
        self._pipeline.in_flight = value

    def flush(self) -> None:
        """Wait until every frame handed in is encoded, written and flushed to the file.

        Frames are written without it, each as soon as it is encoded; this waits for that.
        Frames a video encoder holds back (``low_delay=False``, AV1's default) stay held until
        :meth:`close`. Raises the first error met encoding or writing a frame since the last
        call that raised one; the frames handed in after a failed one are still written.
        """
        self._check_open()
        self._pipeline.wait()
        self._raise_background_error()

    def _encode_color(self, rgb: npt.NDArray[np.uint8], timestamp: int) -> list[Packet]:
        assert self._encoder is not None
        if type(self._encoder).encode is not VideoEncoder.encode:
            return self._encoder.encode(rgb, timestamp)  # an encoder of its own way in
        return self._encoder.encode_checked(rgb, timestamp)  # checked where it was handed in

    def _drain_one(self) -> None:
        """Write the next frame handed in (on the writing thread, once it is encoded)."""
        timestamp, fut_color, fut_depth = self._pipeline.next()
        if fut_color is not None:
            # Written even when the depth failed: later frames' packets may refer to these.
            self._container.write_packets(fut_color.result())
        data = fut_depth.result()
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise PcdcodecError(
                f"depth codec {self.depth_codec.name!r} returned a {type(data).__name__} for "
                f"the frame at {timestamp} ns, expected bytes"
            )
        depth = data if isinstance(data, bytes) else bytes(data)
        self._container.write_frame(
            timestamp, depth, self._poses.pop(timestamp, None), self._stamps.pop(timestamp, None)
        )

    # -- closing -------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise InputError(f"recording {str(self.path)!r} is closed")

    def close(self) -> None:
        """Write what is still pending, the index and the summary, and close the file.

        Every step is tried even when an earlier one fails (a frame that cannot be encoded, a
        full disk), so the frames already written stay readable and the file gets its index
        whenever it can; the first error is raised at the end. When replacing a file, the old
        one is kept unless the new one closed without error (the new one's frames then stay in
        the partial file the error names).
        """
        if self._closed or inherited(self):  # in a forked process: the parent's file
            self._closed = True
            return
        errors: list[BaseException] = []

        def attempt(step: Callable[[], Any]) -> None:
            try:
                step()
            except BaseException as exc:  # every step is tried; the first error is raised
                errors.append(exc)

        def flush_sync() -> None:
            self._write_pairs(self._sync.flush())

        if self._sync is not None:
            attempt(flush_sync)
        self._closed = True
        # The writing thread gives every frame handed in one try; its errors come first.
        errors.extend(self._pipeline.finish())
        container = self._container
        encoder = self._encoder if self._shape is not None else None  # none unless it ran
        if encoder is not None and container.broken is None:
            attempt(lambda: container.write_packets(encoder.flush()))
        if container.broken is None:
            attempt(lambda: container.to_file(container.seal))
        if container.broken is None and self._owns_file:
            attempt(lambda: container.to_file(self._mcap.finish))
        if self._owns_file:
            attempt(self._file.close)
        end_close(errors, container.broken, self._writing, self._target)

    def abort(self) -> None:
        """Stop without finishing: what was written stays readable, as after a crash."""
        if inherited(self):  # in a forked process: the parent's file and threads
            self._closed = True
            return
        self._closed = True
        self._pipeline.abort()
        if self._owns_file:
            self._file.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        # On an error inside the block the frames written so far are still closed properly.
        self.close()
