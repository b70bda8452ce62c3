"""Writing a ``.pcdc`` recording: color and depth encoded in parallel, written as they finish."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import threading
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from .._validate import check_color, check_depth, check_depth_scale
from .._version import __version__
from ..color import DEFAULT_COLOR_CODEC
from ..color.base import Packet, StreamCodec, VideoEncoder
from ..depth import DEFAULT_DEPTH_CODEC
from ..depth.base import FrameCodec
from ..errors import InputError, InputTypeError, PcdcodecError
from ..frame import OPEN3D_DEPTH_SCALE
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import check_color_camera
from ..geometry.transform import as_rigid, matrix_to_quaternion
from ..registry import as_codec
from ..ros.foxglove import (
    CAMERA_CALIBRATION,
    CAMERA_CALIBRATION_SCHEMA,
    COMPRESSED_VIDEO,
    COMPRESSED_VIDEO_SCHEMA,
    FRAME_TRANSFORM,
    FRAME_TRANSFORM_SCHEMA,
    CameraCalibration,
    CompressedVideo,
    FrameTransform,
)
from ..sources.base import Source
from . import _index as fmt

__all__ = ["RecordingWriter"]

#: A frame handed in: its timestamp (ns) and the futures of its color packets and depth bytes.
_Pending = tuple[int, Future[list[Packet]] | None, Future[bytes]]

_NS = 1_000_000_000
#: The latest timestamp a recording holds: the ROS messages it stores (camera calibration,
#: CompressedVideo) keep time as int32 seconds, so 2038-01-19 03:14:07.999999999 UTC.
MAX_TIMESTAMP_NS = (2**31) * _NS - 1


def _user_metadata(metadata: Any) -> dict[str, str]:
    """User metadata as MCAP's str -> str map: strings kept, other values as JSON."""
    if metadata is None:
        return {}
    if not isinstance(metadata, dict):
        raise InputTypeError(f"metadata must be a dict, got {type(metadata).__name__}")
    out: dict[str, str] = {}
    for key, value in metadata.items():
        if not isinstance(key, str):
            raise InputTypeError(f"metadata key {key!r} must be a str, got {type(key).__name__}")
        if isinstance(value, str):
            out[key] = value
            continue
        try:
            out[key] = json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"metadata[{key!r}] = {value!r} is not a str and cannot be stored as JSON ({exc})"
            ) from None
    return out


def _calibration(intr: CameraIntrinsics, frame_id: str, timestamp: int) -> bytes:
    info = intr.to_camera_info()
    return CameraCalibration(
        timestamp,
        frame_id,
        intr.width,
        intr.height,
        info["distortion_model"],
        [float(v) for v in info["D"]],
        [float(v) for v in info["K"]],
        [float(v) for v in info["R"]],
        [float(v) for v in info["P"]],
    ).encode()


def _transform(matrix: npt.NDArray[np.float64], timestamp: int, parent: str, child: str) -> bytes:
    q = matrix_to_quaternion(matrix[:3, :3])
    t = matrix[:3, 3]
    return FrameTransform(
        timestamp,
        parent,
        child,
        (float(t[0]), float(t[1]), float(t[2])),
        (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
    ).encode()


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


def _intrinsics(value: Any) -> CameraIntrinsics:
    if value is None:
        raise InputError(
            "intrinsics are required to write a recording: pass "
            "intrinsics=pcdcodec.CameraIntrinsics(width, height, fx, fy, cx, cy)"
        )
    if isinstance(value, CameraIntrinsics):
        return value
    if isinstance(value, dict):
        return CameraIntrinsics.from_dict(value)
    if type(value).__name__ == "PinholeCameraIntrinsic":
        return CameraIntrinsics.from_open3d(value)
    raise InputTypeError(
        f"intrinsics must be a CameraIntrinsics, a dict or an Open3D PinholeCameraIntrinsic, "
        f"got {type(value).__name__}"
    )


class RecordingWriter:
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
    encoded (at 30 fps with the default codecs, at most the frame being handed in) and those a
    video encoder holds back, which at the codecs' defaults (``low_delay=True``) is none, except
    for AV1 (about 55; see ``docs/format.md``). An error while encoding or writing a frame in
    the background is raised by the next :meth:`write`, :meth:`flush` or :meth:`close`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        intrinsics: Any,
        depth_scale: float = 1000.0,
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
    ) -> None:
        self.path = Path(path)
        self.intrinsics = _intrinsics(intrinsics)
        self.color_intrinsics, self.depth_to_color = check_color_camera(
            None if color_intrinsics is None else _intrinsics(color_intrinsics), depth_to_color
        )
        self.world_frame_id = world_frame_id
        self.depth_scale = check_depth_scale(depth_scale)
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 1000:
            raise InputError(f"fps must be a number in (0, 1000], got {fps!r}")
        self.fps = float(fps)
        if not isinstance(in_flight, int) or in_flight < 1:
            raise InputError(f"in_flight must be a positive int, got {in_flight!r}")
        self.in_flight = in_flight
        if not isinstance(frame_id, str):
            raise InputTypeError(f"frame_id must be a str, got {frame_id!r}")
        self.frame_id = frame_id
        depth_codec = as_codec(depth, "depth")
        if not isinstance(depth_codec, FrameCodec):
            raise InputTypeError(f"depth codec {depth_codec.name!r} is not a frame codec")
        self.depth_codec = depth_codec
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
        user = _user_metadata(metadata)
        if fmt.DIGEST_KEY in user:
            raise InputError(f"metadata key {fmt.DIGEST_KEY!r} is reserved for the file's digest")

        if self.path.exists() and not overwrite:
            raise InputError(
                f"{str(self.path)!r} already exists; pass overwrite=True to replace it"
            )
        if self.path.is_dir():
            raise InputError(f"{str(self.path)!r} is a folder, not a file")
        # Replacing a file: write beside it and swap at the end, so the old one survives
        # until the new one is complete.
        from .._atomic import partial_path  # not loaded by `import pcdcodec`

        self._target = self.path
        self._writing = partial_path(self.path) if self.path.exists() else self.path
        mode = "xb" if self._writing == self.path else "wb"
        self._file: IO[bytes] = open(self._writing, mode)  # noqa: SIM115 - closed by close()
        try:
            self._start(user)
        except BaseException:
            # A writer that never started leaves nothing behind, so a retry finds no file.
            self._file.close()
            self._writing.unlink(missing_ok=True)
            raise
        self._encoder: VideoEncoder | None = None
        self._shape: tuple[int, int] | None = None
        self._last_ts: int | None = None
        self._pending: deque[_Pending] = deque()
        self._color_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-color")
        self._depth_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-depth")
        # One thread writes the file (the MCAP writer is not thread-safe), taking the frames in
        # the order handed in. The condition guards the count of frames handed in and not yet
        # written, and the errors met writing them, which the caller's thread raises.
        self._mux_pool = ThreadPoolExecutor(1, thread_name_prefix="pcdcodec-write")
        self._mux_state = threading.Condition()
        self._unwritten = 0
        self._errors: list[BaseException] = []
        self._aborted = False
        # The error that stopped the writing of the file part way through a record: MCAP's
        # writer may hold part of a message, so nothing more is written and the file is left
        # unfinished (every frame before stays readable) rather than sealed and damaged.
        self._broken: BaseException | None = None
        self._channels: dict[str, int] = {}
        self._sequence = 0
        # Frames count as complete once their depth and their color packet are both written.
        self._depth_written: deque[int] = deque()
        self._color_written: set[int] = set()
        # The color packets of the open digest group: readable once its digest is written.
        self._group_pts: list[int] = []
        self._sealer = fmt.Sealer()
        self.frames_complete = 0
        self.frames_written = 0
        self.bytes_color = 0
        self.bytes_depth = 0
        self._sync: Any = None
        self._poses: dict[int, npt.NDArray[np.float64]] = {}
        self.poses_written = 0
        self._mode: str | None = None  # "frames" (write) or "encoded" (write_encoded)
        self._closed = False

    def _start(self, user: dict[str, str]) -> None:
        """Write the file's header and metadata."""
        from mcap.writer import CompressionType, Writer

        # One chunk per message: each is on disk (with its CRC) as soon as it is written, and
        # MCAP's chunk index then gives every message's time and offset directly.
        self._mcap = Writer(
            self._file, chunk_size=0, compression=CompressionType.NONE, enable_data_crcs=True
        )
        self._mcap.start(profile=fmt.PROFILE, library=f"pcdcodec {__version__}")
        # Version 2 only where a version 1 reader would give wrong clouds: a color camera
        # apart from depth, or lens distortion. Everything else stays readable by version 1.
        two_cameras = self.color_intrinsics is not None
        version = 2 if two_cameras or self.intrinsics.has_distortion else 1
        cameras: dict[str, str] = {}
        if self.color_intrinsics is not None and self.depth_to_color is not None:
            cameras = {
                "color_intrinsics": json.dumps(self.color_intrinsics.to_dict()),
                "depth_to_color": json.dumps(self.depth_to_color.tolist()),
            }
        # The settings the file is read with; each record is sealed with its digest, and the
        # main record lists the others, so a reader notices any of them changed or missing.
        records: dict[str, dict[str, str]] = {
            fmt.METADATA_NAME: {
                "format_version": str(version),
                "library": f"pcdcodec {__version__}",
                "intrinsics": json.dumps(self.intrinsics.to_dict()),
                "depth_scale": repr(self.depth_scale),
                "fps": repr(self.fps),
                "depth_codec": json.dumps(self.depth_codec.stored_config()),
                "color_codec": json.dumps(self.color_codec.stored_config())
                if self.color_codec
                else "",
                "frame_id": self.frame_id,
                fmt.INTEGRITY_KEY: str(fmt.INTEGRITY_VERSION),
                **cameras,
            },
        }
        if user:
            records[fmt.USER_METADATA_NAME] = user
        records[fmt.METADATA_NAME][fmt.RECORDS_KEY] = json.dumps(
            [name for name in records if name != fmt.METADATA_NAME]
        )
        for name, data in records.items():
            self._mcap.add_metadata(name, fmt.seal(name, data))
        self._file.flush()

    # -- writing -----------------------------------------------------------------------

    @property
    def color_shape(self) -> tuple[int, int]:
        """``(height, width)`` of the color images: the color camera's, else the depth's."""
        return (self.color_intrinsics or self.intrinsics).shape

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
        mcap = self._mcap
        size = {"width": str(width), "height": str(height)}
        ch, cw = self.color_shape
        if self.color_codec is not None:
            if not encoded:
                # Packets encoded elsewhere need no encoder here (nor its library).
                self.color_codec._require_available()
                self._encoder = self.color_codec.encoder(cw, ch, self.fps)
                extradata = self._encoder.extradata
            meta = {
                "width": str(cw),
                "height": str(ch),
                "codec": json.dumps(self.color_codec.stored_config()),
                "extradata": base64.b64encode(extradata).decode() if extradata else "",
            }
            video_format = self.color_codec.video_format
            if video_format:
                sid = mcap.register_schema(COMPRESSED_VIDEO, "ros2msg", COMPRESSED_VIDEO_SCHEMA)
                meta["format"] = video_format
                self._channels["color"] = mcap.register_channel(fmt.TOPIC_COLOR, "cdr", sid, meta)
            else:
                self._channels["color"] = mcap.register_channel(
                    fmt.TOPIC_COLOR, fmt.ENCODING_COLOR, 0, meta
                )
            self._channels["key"] = mcap.register_channel(
                fmt.TOPIC_KEYFRAMES, fmt.ENCODING_KEYFRAME, 0, {}
            )
        self._channels["depth"] = mcap.register_channel(
            fmt.TOPIC_DEPTH,
            fmt.ENCODING_DEPTH,
            0,
            {
                **size,
                "codec": json.dumps(self.depth_codec.stored_config()),
                "depth_scale": repr(self.depth_scale),
            },
        )
        self._channels["digest"] = mcap.register_channel(
            fmt.TOPIC_FRAME_DIGEST, fmt.ENCODING_FRAME_DIGEST, 0, {}
        )
        sid = mcap.register_schema(CAMERA_CALIBRATION, "ros2msg", CAMERA_CALIBRATION_SCHEMA)
        cal = self._channels["cal"] = mcap.register_channel(fmt.TOPIC_CALIBRATION, "cdr", sid, {})
        mcap.add_message(
            cal, timestamp, _calibration(self.intrinsics, self.frame_id, timestamp), timestamp
        )
        self._sealer.note(fmt.TOPIC_CALIBRATION, timestamp)
        if self.color_intrinsics is not None and self.depth_to_color is not None:
            color_frame = f"{self.frame_id}_color"
            ccal = mcap.register_channel(fmt.TOPIC_COLOR_CALIBRATION, "cdr", sid, {})
            mcap.add_message(
                ccal,
                timestamp,
                _calibration(self.color_intrinsics, color_frame, timestamp),
                timestamp,
            )
            self._sealer.note(fmt.TOPIC_COLOR_CALIBRATION, timestamp)
            # The color camera's pose in the depth camera's frame: the inverse of depth_to_color.
            tid = self._transform_schema()
            ext = mcap.register_channel(fmt.TOPIC_EXTRINSICS, "cdr", tid, {})
            pose = np.asarray(np.linalg.inv(self.depth_to_color), dtype=np.float64)
            mcap.add_message(
                ext, timestamp, _transform(pose, timestamp, self.frame_id, color_frame), timestamp
            )
            self._sealer.note(fmt.TOPIC_EXTRINSICS, timestamp)
        self._shape = (height, width)

    def _transform_schema(self) -> int:
        if "transform_schema" not in self._channels:
            self._channels["transform_schema"] = self._mcap.register_schema(
                FRAME_TRANSFORM, "ros2msg", FRAME_TRANSFORM_SCHEMA
            )
        return self._channels["transform_schema"]

    def write(
        self, color: Any, depth: Any, timestamp: int | None = None, *, pose: Any = None
    ) -> None:
        """Add one frame: ``color`` H×W×3 uint8 RGB (``None`` when recording depth only) and
        ``depth`` H×W uint16 depth units (or float32 metres where the depth codec takes it).
        With a color camera apart from depth, ``color`` is of the color camera's size.

        ``timestamp`` is in nanoseconds and must increase; without it, frames are spaced at
        ``1/fps`` from 0. ``pose`` is the camera-to-world pose of the depth camera at this
        frame, a rigid 4 × 4 transform in metres, stored as a ``FrameTransform`` from
        ``world_frame_id`` to ``frame_id`` on ``/camera/pose``. Raises
        :class:`~pcdcodec.InputError` for frames of another size than the first, color of
        another size than the color camera's, timestamps that do not increase, a pose that is
        not a rigid 4 × 4 transform, or bad arrays; the frames already written stay intact.

        The frame is encoded and written in the background; ``write()`` returns at once unless
        ``in_flight`` frames already wait, and then blocks until one is written. An error met
        encoding or writing an earlier frame is raised here, before this frame is taken (call
        again to hand it in); the frames handed in after the failed one are still written.
        """
        self._check_open()
        self._raise_background_error()
        self._take(color, depth, timestamp, pose)

    def _take(self, color: Any, depth: Any, timestamp: int | None, pose: Any) -> None:
        """:meth:`write` past its checks for an open writer and earlier errors."""
        rigid = None if pose is None else as_rigid(pose, "pose")
        if self._mode == "encoded":
            raise InputError("this recording takes encoded color (write_encoded), not images")
        timestamp = self._next_timestamp(timestamp)
        d = check_depth(depth, allowed=self.depth_codec.dtypes, name="depth")
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
            self._color_pool.submit(self._encode_color, rgb.copy(), timestamp)
            if rgb is not None
            else None
        )
        if rigid is not None:
            self._poses[timestamp] = rigid
        self._enqueue(timestamp, fut_color, d)

    def write_encoded(
        self,
        packets: Sequence[Packet],
        depth: Any,
        timestamp: int,
        *,
        extradata: bytes | None = None,
    ) -> None:
        """Add a frame whose color is already encoded: the muxing half of the writer.

        ``packets`` are the color packets to store with this frame, in decode order, as this
        recording's color codec (whose config is recorded) would have written them: usually
        the frame's own packet, none for a frame whose packet came earlier, or several when a
        B-frame arrives with a later frame. ``depth`` and ``timestamp`` are as for
        :meth:`write`; ``extradata`` (the decoder's set-up bytes) is taken with the first
        frame. The codec's encoder is never opened, so packets from hardware encoders, other
        files or ROS bags go in unchanged. A recording takes either :meth:`write` frames or
        encoded ones, not both. Raises :class:`~pcdcodec.InputError` for a recording without
        color, items that are not :class:`~pcdcodec.color.base.Packet`, or the errors of
        :meth:`write`; like it, writes in the background and blocks while ``in_flight`` frames
        wait.
        """
        self._check_open()
        self._raise_background_error()
        if self.color_codec is None:
            raise InputError("this recording has no color codec: open it with the codec whose "
                             "packets these are")  # fmt: skip
        if self._mode == "frames":
            raise InputError("this recording encodes images (write); it cannot take packets too")
        group = [_checked_packet(k, p) for k, p in enumerate(packets)]
        timestamp = self._next_timestamp(timestamp)
        d = check_depth(depth, allowed=self.depth_codec.dtypes, name="depth")
        self._check_shape(d, timestamp, encoded=True, extradata=extradata)
        self._mode = "encoded"
        self._last_ts = timestamp
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
        elif d.shape != self._shape:
            raise InputError(
                f"depth is {d.shape[1]}x{d.shape[0]}, but this recording's frames are "
                f"{self._shape[1]}x{self._shape[0]} (width x height)"
            )

    def _enqueue(
        self, timestamp: int, fut_color: Future[list[Packet]] | None, d: npt.NDArray[Any]
    ) -> None:
        fut_depth = self._depth_pool.submit(self.depth_codec.encode, d.copy())
        entry = (timestamp, fut_color, fut_depth)
        with self._mux_state:
            self._pending.append(entry)
            self._unwritten += 1
        self._mux_pool.submit(self._mux_one, entry)
        # Memory stays bounded: wait while more than in_flight frames are not yet written.
        with self._mux_state:
            self._mux_state.wait_for(lambda: self._unwritten <= self.in_flight)

    def _mux_one(self, entry: _Pending) -> None:
        """Write one frame handed in, once encoded (on the writing thread, in order)."""
        timestamp, fut_color, fut_depth = entry
        try:
            # No lock is held while the encoders run: the caller keeps handing frames in.
            for future in (fut_color, fut_depth):
                if future is not None:
                    # exception() waits on the future's own condition, which cancel() wakes
                    # (futures.wait() would not: abort() cancels queued encodes).
                    with contextlib.suppress(CancelledError):
                        future.exception()
            if self._aborted:
                return
            try:
                self._drain_one()
            except BaseException as exc:  # kept for the caller's thread, which raises it
                add_note = getattr(exc, "add_note", None)  # Python 3.11+
                if add_note is not None:
                    add_note(f"(raised encoding or writing the frame at {timestamp} ns)")
                with self._mux_state:
                    self._errors.append(exc)
        finally:
            with self._mux_state:
                # Each frame gets one try, whether or not it was taken off the queue.
                if self._pending and self._pending[0] is entry:
                    self._pending.popleft()
                self._unwritten -= 1
                self._mux_state.notify_all()

    def _raise_background_error(self) -> None:
        """Raise the first error met writing earlier frames; each is raised once."""
        with self._mux_state:
            errors, self._errors = self._errors, []
        if errors:
            add_note = getattr(errors[0], "add_note", None)
            if len(errors) > 1 and add_note is not None:
                add_note(f"({len(errors) - 1} more frames failed after it)")
            raise errors[0]

    def flush(self) -> None:
        """Wait until every frame handed in is encoded, written and flushed to the file.

        Frames are written without it, each as soon as it is encoded; this waits for that.
        Frames a video encoder holds back (``low_delay=False``, AV1's default) stay held until
        :meth:`close`. Raises the first error met encoding or writing a frame since the last
        call that raised one; the frames handed in after a failed one are still written.
        """
        self._check_open()
        with self._mux_state:
            self._mux_state.wait_for(lambda: self._unwritten == 0)
        self._raise_background_error()

    def _encode_color(self, rgb: npt.NDArray[np.uint8], timestamp: int) -> list[Packet]:
        assert self._encoder is not None
        return self._encoder.encode(rgb, timestamp)

    def write_rgbd(
        self,
        rgbd: Any,
        timestamp: int | None = None,
        *,
        depth_scale: float = OPEN3D_DEPTH_SCALE,
    ) -> None:
        """Add an Open3D RGBDImage, legacy (``open3d.geometry``) or tensor (``open3d.t.geometry``).

        ``depth_scale`` is the one the image was made with, in Open3D's convention (the
        ``depth_scale`` given to ``create_from_color_and_depth``, or used with a tensor image;
        Open3D's default is 1000). Depth in depth units must be at this recording's own depth
        scale: a different one raises :class:`~pcdcodec.InputError` instead of storing depth
        rescaled. Tensor images with float32 depth are metres after division by
        ``depth_scale`` and need a depth codec that takes float32. Color must be 8-bit RGB
        (``convert_rgb_to_intensity=False``). Note that a legacy image has already lost the
        depth beyond its ``depth_trunc`` (Open3D's default 3 m).
        """
        self._write_rgbd(rgbd, timestamp, depth_scale, "depth_scale")

    def _write_rgbd(
        self, rgbd: Any, timestamp: int | None, depth_scale: float, keyword: str
    ) -> None:
        """:meth:`write_rgbd`, its errors naming the caller's keyword for the scale."""
        from ..frame import from_open3d_rgbd, open3d_rgbd_kind

        kind = open3d_rgbd_kind(rgbd)
        tensor_float = kind == "tensor" and str(rgbd.depth.dtype) == "Float32"
        scale = check_depth_scale(depth_scale, keyword)
        if kind is not None and not tensor_float and scale != self.depth_scale:
            raise InputError(
                f"this {kind} RGBDImage holds depth at {keyword}={float(depth_scale):g} "
                f"(Open3D's default is {OPEN3D_DEPTH_SCALE:g} unless another was passed), but "
                f"recording {str(self.path)!r} stores {self.depth_scale:g} units per metre; "
                f"pass {keyword}= with the scale the image was made with, or open the "
                f"recording with depth_scale={float(depth_scale):g}"
            )
        color, depth = from_open3d_rgbd(rgbd, depth_scale=depth_scale)
        # An RGBDImage always carries color; a depth-only recording keeps its depth only.
        self.write(color if self.color_codec is not None else None, depth, timestamp)

    def write_frames(
        self,
        frames: Iterable[Any],
        *,
        progress: Callable[[int], None] | None = None,
        rgbd_depth_scale: float = OPEN3D_DEPTH_SCALE,
    ) -> int:
        """Write every frame of an iterable and return how many were written.

        Items may be :class:`~pcdcodec.Frame` objects (from a source, :func:`pcdcodec.load_folder`
        or another recording), ``(color, depth)`` or ``(color, depth, timestamp)`` tuples, or
        Open3D RGBDImages, legacy or tensor, alone or as ``(rgbd, timestamp)`` tuples.
        ``rgbd_depth_scale`` is the depth scale the RGBDImages were made with (see
        :meth:`write_rgbd`). ``progress`` is called with the number of frames written so far.
        To record a whole source with its camera, use :meth:`write_source` (or
        :func:`pcdcodec.encode`).
        """
        from ..frame import Frame, open3d_rgbd_kind

        count = 0
        for item in frames:
            if isinstance(item, Frame):
                self.write(item.color, item.depth, item.timestamp_ns, pose=item.pose)
            elif open3d_rgbd_kind(item) is not None:
                self._write_rgbd(item, None, rgbd_depth_scale, "rgbd_depth_scale")
            elif (
                isinstance(item, tuple) and len(item) == 2 and open3d_rgbd_kind(item[0]) is not None
            ):
                self._write_rgbd(item[0], item[1], rgbd_depth_scale, "rgbd_depth_scale")
            elif isinstance(item, tuple) and len(item) in (2, 3):
                self.write(*item)
            else:
                raise InputTypeError(
                    f"frame {count} is a {type(item).__name__}; expected a pcdcodec.Frame, an "
                    "Open3D RGBDImage, an (rgbd, timestamp) or a (color, depth[, timestamp]) "
                    "tuple"
                )
            count += 1
            if progress is not None:
                progress(count)
        return count

    def write_source(self, source: Source, *, progress: Callable[[int], None] | None = None) -> int:
        """Write every frame of a :class:`~pcdcodec.Source` and return how many were written.

        The source's camera and depth scale must be this recording's (:func:`pcdcodec.encode`
        opens the writer from the source, so they are). A source without color
        (``source.has_color`` false) needs a writer opened with ``color=None``. Raises
        :class:`~pcdcodec.InputError` when they disagree; frames already written stay intact.
        """
        from ..sources.base import Source

        if not isinstance(source, Source):
            raise InputTypeError(
                f"write_source takes a pcdcodec.Source, got {type(source).__name__}; use "
                "write_frames for other iterables"
            )
        if source.intrinsics is not None and source.intrinsics != self.intrinsics:
            raise InputError(
                f"source {str(source.path)!r} has camera {source.intrinsics.to_dict()}, this "
                f"recording {self.intrinsics.to_dict()}"
            )
        if source.color_intrinsics != self.color_intrinsics or (
            source.depth_to_color is not None
            and self.depth_to_color is not None
            and not np.allclose(source.depth_to_color, self.depth_to_color, rtol=0, atol=1e-12)
        ):

            def show(cam: CameraIntrinsics | None, d2c: Any) -> str:
                t = None if d2c is None else np.round(np.asarray(d2c), 6).tolist()
                return f"color camera {cam.to_dict() if cam else None}, depth_to_color {t}"

            raise InputError(
                f"source {str(source.path)!r} has "
                f"{show(source.color_intrinsics, source.depth_to_color)}; this recording has "
                f"{show(self.color_intrinsics, self.depth_to_color)} "
                "(open the recording with the source's color_intrinsics and depth_to_color)"
            )
        if float(source.depth_scale) != self.depth_scale:
            raise InputError(
                f"source {str(source.path)!r} has depth scale {source.depth_scale} per metre, this "
                f"recording {self.depth_scale}"
            )
        if not source.has_color and self.color_codec is not None:
            raise InputError(
                f"source {str(source.path)!r} has no color; open the recording with color=None"
            )
        if source.has_color and self.color_codec is None:
            frames: Iterable[Any] = ((None, f.depth, f.timestamp_ns) for f in source)
        else:
            frames = source
        return self.write_frames(frames, progress=progress)

    def _synchronizer(self) -> Any:
        if self._sync is None:
            from ..sync import Synchronizer

            self._sync = Synchronizer(max_difference=self.max_sync_difference)
        return self._sync

    #: Largest color/depth time difference (ns) that :meth:`write_color`/:meth:`write_depth`
    #: pair into one frame, as TUM's associate.py (20 ms).
    max_sync_difference: int = 20_000_000

    def write_color(self, color: Any, timestamp: int) -> None:
        """Add a color image that arrives on its own; it is paired with the depth image nearest
        in time (within :attr:`max_sync_difference`) and written as one frame at the depth's
        timestamp. Images that find no partner are dropped and counted in :attr:`unpaired`.
        An error met encoding or writing an earlier frame is raised before the image is taken
        (call again to hand it in); the pairs it completes are all written, and the first
        error among them is raised after.
        """
        self._check_open()
        # Raised before the image is taken (call again to hand it in), not between the pairs
        # it completes: those are already out of the synchronizer.
        self._raise_background_error()
        self._write_pairs(self._synchronizer().add_color(timestamp, color))

    def write_depth(self, depth: Any, timestamp: int) -> None:
        """Add a depth image that arrives on its own (see :meth:`write_color`)."""
        self._check_open()
        self._raise_background_error()
        self._write_pairs(self._synchronizer().add_depth(timestamp, depth))

    def _write_pairs(self, pairs: Iterable[Any]) -> None:
        """Write the pairs a synchronizer made final, each of them whatever another raises
        (a pair not written is lost: it is in neither the file nor :attr:`unpaired`); the
        first error is raised at the end."""
        first: Exception | None = None
        for _, rgb, depth_ts, depth in pairs:
            try:
                self._take(rgb, depth, depth_ts, None)
            except Exception as exc:
                first = first or exc
        if first is not None:
            raise first

    @property
    def unpaired(self) -> dict[str, list[int]]:
        """Timestamps (ns) of the separately written images that found no partner."""
        if self._sync is None:
            return {"color": [], "depth": []}
        return {"color": list(self._sync.dropped_color), "depth": list(self._sync.dropped_depth)}

    def _color_messages(self, packets: list[Packet]) -> list[tuple[Packet, int, bytes]]:
        """Each packet with the publish time and data of its message, made before any is
        written (a packet that fails leaves no message of its group half written)."""
        video_format = self.color_codec.video_format if self.color_codec else None
        out = []
        for packet in packets:
            data = (
                CompressedVideo(packet.pts, self.frame_id, packet.data, video_format).encode()
                if video_format
                else bytes(packet.data)
            )
            # B-frames give the first packets decoding times before the first frame; MCAP times
            # are unsigned, so those are stored as 0 (decoders only need the order).
            out.append((packet, max(packet.dts, 0), data))
        return out

    def _to_file(self, step: Callable[[], None]) -> None:
        """Run ``step``, which writes to the file; an error in it stops all writing."""
        if self._broken is not None:
            raise PcdcodecError(
                f"{str(self._writing)!r} is not written further: writing it failed before "
                f"({self._broken!r})"
            )
        try:
            step()
        except BaseException as exc:
            self._broken = exc
            raise

    def _write_packets(self, packets: list[Packet]) -> None:
        messages = self._color_messages(packets)
        self._to_file(lambda: self._write_color(messages))

    def _write_color(self, messages: list[tuple[Packet, int, bytes]]) -> None:
        mcap = self._mcap
        for packet, dts, data in messages:
            if packet.keyframe:
                mcap.add_message(self._channels["key"], packet.pts, b"", dts, self._sequence)
                self._sealer.note(fmt.TOPIC_KEYFRAMES, packet.pts)
            mcap.add_message(self._channels["color"], packet.pts, data, dts, self._sequence)
            self._sealer.note(fmt.TOPIC_COLOR, packet.pts)
            self._sealer.packet(packet.pts, dts, packet.keyframe, data)
            self._sequence += 1
            self.bytes_color += len(packet.data)
            self._group_pts.append(packet.pts)

    def _count_complete(self) -> None:
        while self._depth_written and (
            self.color_codec is None or self._depth_written[0] in self._color_written
        ):
            self._color_written.discard(self._depth_written.popleft())
            self.frames_complete += 1

    def _drain_one(self) -> None:
        timestamp, fut_color, fut_depth = self._pending.popleft()
        if fut_color is not None:
            # Written even when the depth failed: later frames' packets may refer to these.
            self._write_packets(fut_color.result())
        data = fut_depth.result()
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise PcdcodecError(
                f"depth codec {self.depth_codec.name!r} returned a {type(data).__name__} for "
                f"the frame at {timestamp} ns, expected bytes"
            )
        depth = data if isinstance(data, bytes) else bytes(data)
        self._to_file(lambda: self._write_frame(timestamp, depth))

    def _write_frame(self, timestamp: int, data: bytes) -> None:
        """The rest of a frame after its color packets: depth, pose and digest."""
        self._mcap.add_message(
            self._channels["depth"], timestamp, data, timestamp, self.frames_written
        )
        self._sealer.note(fmt.TOPIC_DEPTH, timestamp)
        self.bytes_depth += len(data)
        pose = self._poses.pop(timestamp, None)
        pose_digest = fmt.NO_POSE
        if pose is not None:
            if "pose" not in self._channels:
                self._channels["pose"] = self._mcap.register_channel(
                    fmt.TOPIC_POSE, "cdr", self._transform_schema(), {}
                )
                self._channels["pose_matrix"] = self._mcap.register_channel(
                    fmt.TOPIC_POSE_MATRIX, fmt.ENCODING_POSE_MATRIX, 0, {}
                )
            msg = _transform(pose, timestamp, self.world_frame_id, self.frame_id)
            self._mcap.add_message(self._channels["pose"], timestamp, msg, timestamp)
            # The quaternion is a rounding away from the matrix given; keep that exactly too.
            exact = np.ascontiguousarray(pose, dtype="<f8").tobytes()
            self._mcap.add_message(self._channels["pose_matrix"], timestamp, exact, timestamp)
            self._sealer.note(fmt.TOPIC_POSE, timestamp)
            self._sealer.note(fmt.TOPIC_POSE_MATRIX, timestamp)
            pose_digest = fmt.data_digest(msg, exact)
            self.poses_written += 1
        # Last of the frame: the digests of the color packets written since the previous
        # frame's (its group), of its depth and of its pose; the frame is readable from here.
        record = self._sealer.frame_record(data, pose_digest)
        self._mcap.add_message(
            self._channels["digest"], timestamp, record, timestamp, self.frames_written
        )
        self._sealer.note(fmt.TOPIC_FRAME_DIGEST, timestamp)
        self._color_written.update(self._group_pts)
        self._group_pts.clear()
        self.frames_written += 1
        self._depth_written.append(timestamp)
        self._count_complete()
        self._file.flush()

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
        if self._closed:
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
        self._mux_pool.shutdown(wait=True)
        with self._mux_state:
            errors.extend(self._errors)
            self._errors = []
        self._pending.clear()
        # Wait for every encode still running (a frame whose write() failed part way may have
        # left one behind) before the encoder is flushed: an FFmpeg codec context used from
        # two threads at once crashes the process.
        self._color_pool.shutdown(wait=True)
        self._depth_pool.shutdown(wait=True)
        encoder = self._encoder
        if encoder is not None and self._broken is None:
            attempt(lambda: self._write_packets(encoder.flush()))
        if self._broken is None:
            attempt(lambda: self._to_file(self._seal))
        if self._broken is None:
            attempt(lambda: self._to_file(self._mcap.finish))
        attempt(self._file.close)
        if errors:
            add_note = getattr(errors[0], "add_note", None)  # Python 3.11+
            if self._writing != self._target and add_note is not None:
                add_note(
                    f"{str(self._target)!r} was left as it was; the frames written are in "
                    f"{str(self._writing)!r}"
                )
            raise errors[0]
        if self._writing != self._target:
            os.replace(self._writing, self._target)

    def _seal(self) -> None:
        """Write the seal: what the file holds, and the digest of the packets after the last
        frame's digest (the encoder's flush)."""
        self._mcap.add_metadata(fmt.SEAL_NAME, fmt.seal(fmt.SEAL_NAME, self._sealer.seal()))
        self._color_written.update(self._group_pts)
        self._group_pts.clear()
        self._count_complete()

    def abort(self) -> None:
        """Stop without finishing: what was written stays readable, as after a crash."""
        self._closed = True
        self._aborted = True
        # Queued frames are dropped; a frame being coded finishes first (milliseconds), so no
        # codec keeps running on a worker thread once abort() returns. The writing thread
        # writes nothing more, and is done before the file is closed.
        self._color_pool.shutdown(wait=True, cancel_futures=True)
        self._depth_pool.shutdown(wait=True, cancel_futures=True)
        self._mux_pool.shutdown(wait=True)
        self._file.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        # On an error inside the block the frames written so far are still closed properly.
        self.close()
