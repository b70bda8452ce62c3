"""Reading a ``.pcdc`` recording: random access through MCAP's index, sequential decoding."""

from __future__ import annotations

import os
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..color.base import StreamCodec
from ..color.fork import check_not_inherited, inherited, keep_in_child
from ..depth.base import FrameCodec, read_header
from ..errors import DecodeError, InputError, InputTypeError, PcdcodecError, UnknownCodecError
from ..frame import Frame
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import Projector
from . import _header as header
from . import _index as fmt
from ._kept import KeptAccess, kept_problems
from ._packets import PacketAccess
from ._readahead import (
    KEEP_PICTURES,
    ColorStream,
    ReadAhead,
    ThreadsError,
    codec_with_threads,
    with_threads,
)
from .framesets import OneCamera
from .verify import VerifyReport, verify_recording

__all__ = ["Frame", "Recording", "VerifyReport"]

#: Frames decoded ahead of the one in use, per thread, when reading in order on threads: a
#: deeper window lets the color and depth threads drift apart without waiting (measured with
#: ``benchmarks/read_threads.py``: 2 per thread left the second core idle more often).
READ_AHEAD = 6


class SeveralCamerasError(InputError):
    """A recording of several cameras was opened as a one-camera :class:`Recording`."""

    def __init__(self, name: str, cameras: list[str], index: fmt.FileIndex) -> None:
        super().__init__(
            f"{name!r} holds {len(cameras)} cameras ({', '.join(cameras)}): open it with "
            "pcdcodec.open(), which gives a RigRecording, and pick a camera with "
            "rec.frames(camera=...)"
        )
        #: the file's index, checked up to its records' digests
        self.index = index


class Recording(KeptAccess, PacketAccess, OneCamera):
    """A ``.pcdc`` recording opened for reading. Use :func:`pcdcodec.open`.

    ``len(rec)``, ``rec[i]``, ``rec[a:b]`` (a list), iteration, ``rec.nearest(t)`` and
    ``rec.play()`` give :class:`Frame` objects. Random access reads only the frame's own messages,
    plus the color packets from the keyframe before it, and converts only its own color to RGB;
    the group of pictures decoded last is kept, so frames read again or backwards within it are
    not decoded again (``docs/recording.md``). Iteration decodes each packet once.

    ``threads`` (``None``: each codec's default, one frame at a time; ``0``: the codecs choose)
    is how many cores reading may use. With 2 or more, iteration and :meth:`play` read ahead:
    while the caller holds frame ``i``, the next ``6 × threads`` frames decode on worker
    threads (the color stream on one, depth frames on ``threads`` others, several at once).
    Frames come out in order and identical, each checked as without threads, and an error is
    raised at the frame it belongs to. Leaving the loop or :meth:`close` stops the workers.
    Random access (``rec[i]``) decodes on the caller's thread either way. The codecs that take
    ``threads`` (``jpegxl``, the video codecs) are given it too, except the color decoder that
    reads ahead, which gets half (slice threads add little when whole frames run in parallel).
    """

    def __init__(self, path: str | os.PathLike[str], *, threads: int | None = None) -> None:
        if threads is not None and (  # more threads than 256 only start idle ones, GBs ahead
            isinstance(threads, bool) or not isinstance(threads, int) or not 0 <= threads <= 256
        ):
            raise InputError(f"threads must be an int in 0..256 (0: automatic), got {threads!r}")
        #: Decoder threads per codec chosen by this reader (``None``: each codec's default).
        self.threads = threads
        self.path = Path(path)
        if not self.path.exists():
            raise InputError(f"recording {str(self.path)!r} does not exist")
        if self.path.is_dir():
            raise InputError(f"{str(self.path)!r} is a folder, not a recording")
        self._file: IO[bytes] = open(self.path, "rb")  # noqa: SIM115 - closed by close()
        keep_in_child(self)  # a forked process never frees it (color/fork.py)
        self._lock = threading.RLock()
        self._read_aheads: weakref.WeakSet[ReadAhead[Frame]] = weakref.WeakSet()
        try:
            self._load()
        except PcdcodecError:
            self._file.close()
            raise
        except Exception as exc:  # whatever damaged bytes make a parser raise
            self._file.close()
            raise DecodeError(
                f"{str(self.path)!r} could not be read ({type(exc).__name__}: {exc})"
            ) from exc
        except BaseException:
            self._file.close()
            raise
        try:
            if self.camera is None:  # (a rig's reader says it once, for every camera)
                fmt.warn_if_incomplete(self.index, str(self.path), lambda: f"{len(self)} frames")
        except BaseException:  # a filter that turns the warning into an error
            self._file.close()
            raise

    #: The camera of a rig's file this reads (``None``: a one-camera file).
    camera: str | None = None
    #: Of a camera of a rig's file: the chunks (byte offsets) of the other cameras.
    other_chunks: frozenset[int] = frozenset()

    def _read_index(self, name: str) -> fmt.FileIndex:
        """The index of the file, as a one-camera file's."""
        header.check_magic(self._file, name)
        try:
            return fmt.load(self._file)
        except DecodeError as exc:
            raise DecodeError(f"{name!r}: {exc}") from exc
        except Exception as exc:  # whatever a damaged file makes the MCAP records raise
            raise DecodeError(f"{name!r} could not be read ({type(exc).__name__}: {exc})") from exc

    def _load(self) -> None:
        name = str(self.path)
        index = self._read_index(name)
        self.index = index
        if index.damaged_at is not None:
            summary = f"; its summary is unusable: {index.summary_problem}" * bool(
                index.summary_problem
            )
            raise DecodeError(
                f"{name!r} is damaged at byte offset {index.damaged_at}: {index.damage}{summary}; "
                "`pcdcodec recover` copies the frames before the damage into a new file"
            )
        if index.loose_messages:
            raise DecodeError(
                f"{name!r} holds {index.loose_messages} message(s) outside chunks (an unchunked "
                "MCAP file): pcdcodec reads recordings whose messages sit in CRC-checked chunks, "
                "as its writer makes them"
            )
        meta = index.metadata.get(fmt.METADATA_NAME)
        if not header.is_recording(index) or meta is None:
            raise header.not_a_recording(self._file, index, name)
        fmt.check_metadata(index, repr(name))
        cameras = fmt.rig_cameras(index, repr(name))
        if cameras is not None:
            raise SeveralCamerasError(name, cameras, index)
        #: 1 for files with frame digests and a seal (``docs/format.md``), 0 for earlier ones.
        self.integrity = fmt.integrity_version(index, repr(name))
        seal_record = fmt.SEAL_NAME if self.camera is None else fmt.camera_seal(self.camera)
        seal = index.metadata.get(fmt.SEAL_NAME)
        problems = fmt.seal_problems(index, repr(name), record=seal_record)
        problems += kept_problems(index, seal)
        if problems:
            raise DecodeError(
                f"{name!r} does not hold what its writer sealed when closing it: "
                + "; ".join(problems)
                + "; `pcdcodec recover` copies the frames it can read into a new file"
            )
        self._seal: dict[str, str] | None = seal if self.integrity else None
        record = fmt.METADATA_NAME if self.camera is None else fmt.camera_record(self.camera)
        where = f"{name!r}: the {record!r} metadata at byte offset " + str(
            index.metadata_offsets.get(fmt.METADATA_NAME)
        )
        settings = header.Settings.parse(meta, name, where)
        self.format_version = settings.format_version
        #: The camera's frame name (also its name in :attr:`cameras`).
        self.frame_id = settings.frame_id
        #: The color camera when it is apart from the depth camera (format version 2), else None.
        self.color_intrinsics: CameraIntrinsics | None = settings.color_intrinsics
        #: The rigid 4 × 4 transform from the depth to the color camera frame, or None.
        self.depth_to_color: npt.NDArray[np.float64] | None = settings.depth_to_color
        self.intrinsics = settings.intrinsics
        self.depth_scale = settings.depth_scale
        self.fps = settings.fps
        depth_config, color_config = settings.depth_codec, settings.color_codec
        self.metadata: dict[str, str] = header.read_user_metadata(index)
        try:
            depth_codec = codec_with_threads(depth_config, "depth", self.threads)
            color_codec = (
                codec_with_threads(color_config, "color", self.threads) if color_config else None
            )
        except ThreadsError:
            raise
        except UnknownCodecError as exc:
            raise UnknownCodecError(
                f"{name!r} was written with a codec not available here: {exc}"
            ) from None
        except PcdcodecError as exc:
            raise DecodeError(f"{where} names codecs that cannot be made: {exc}") from exc
        except Exception as exc:
            raise DecodeError(
                f"{where} names codecs that cannot be made ({type(exc).__name__}: {exc})"
            ) from exc
        header.check_channels(index, name, settings, self.camera)
        if fmt.DIGEST_KEY not in meta:
            # Written before digests: the CRC-checked calibration message vouches for the camera.
            with self._lock:
                wrong = header.calibration_problems(
                    self._file, index, self.intrinsics, readable_only=True
                )
            if wrong:
                raise DecodeError(f"{name!r}: {wrong[0]}")
        if not isinstance(depth_codec, FrameCodec):
            raise DecodeError(f"{where}: depth codec {depth_codec.name!r} is not a frame codec")
        self.depth_codec = depth_codec
        if color_codec is not None and not isinstance(color_codec, StreamCodec):
            raise DecodeError(
                f"{name!r} names color codec {color_codec.name!r}, not a stream codec"
            )
        self.color_codec: StreamCodec | None = color_codec

        d_times, d_offsets = index.arrays(fmt.TOPIC_DEPTH)
        order = np.argsort(d_times, kind="stable")
        d_times, d_offsets = d_times[order], d_offsets[order]
        self._extradata: bytes | None = None
        self._keyframes: list[int] = []
        self._keyframe_set: set[int] = set()
        # Frame digests: the digest messages' offsets in file order, and each color packet's
        # group (the index of the first digest message after it; len(offsets) for the tail).
        self._digest_times, self._digest_offsets = index.arrays(fmt.TOPIC_FRAME_DIGEST)
        order = np.argsort(self._digest_offsets, kind="stable")
        self._digest_times = self._digest_times[order]
        self._digest_offsets = self._digest_offsets[order]
        self._digest_of_time = {int(t): g for g, t in enumerate(self._digest_times.tolist())}
        self._records: dict[int, tuple[int, bytes, bytes, bytes]] = {}
        self._packet_group: npt.NDArray[np.int64] = np.zeros(0, np.int64)
        self._groups_checked: set[int] = set()
        self._packet_cache: dict[int, Any] = {}
        #: Frames ``recover`` kept without their color (lost to damage): their color is None.
        self._color_missing = fmt.color_missing(index, repr(name)) if color_codec else frozenset()
        if self.integrity and self._seal is None:
            # Written before the writer stopped: a frame is complete with its digest message.
            has = [i for i, t in enumerate(d_times.tolist()) if int(t) in self._digest_of_time]
            keep_done = list(range(has[-1] + 1)) if has else []
            d_times, d_offsets = d_times[keep_done], d_offsets[keep_done]
        if color_codec is not None:
            c_pts, c_offsets = index.arrays(fmt.TOPIC_COLOR)
            k_times, _ = index.arrays(fmt.TOPIC_KEYFRAMES)
            self._packet_pts = c_pts  # decode order (file order)
            self._packet_offsets = c_offsets
            self._packet_of_pts = {int(t): i for i, t in enumerate(c_pts)}
            keyset = set(k_times.tolist())
            self._keyframes = [i for i, t in enumerate(c_pts.tolist()) if t in keyset]
            self._keyframe_set = set(self._keyframes)
            channel = index.channel(fmt.TOPIC_COLOR)
            self._extradata = header.extradata_of(index)
            self._is_cdr = channel is not None and channel.encoding == "cdr"
            self._packet_group = np.searchsorted(
                self._digest_offsets, np.asarray(c_offsets, np.int64), side="right"
            ).astype(np.int64)
            # Packets after the last digest of a file without a seal have no digest yet: the
            # writer stopped before their frame was complete.
            unchecked = len(self._digest_offsets) if self.integrity and self._seal is None else -1
            # Nor can those packets be read (groups grow in file order: they are the last).
            last = len(c_pts) if unchecked < 0 else np.searchsorted(self._packet_group, unchecked)
            self._readable_packets = int(last)
            # A frame exists when both its depth and a decodable color packet were written.
            first_key = self._packet_pts[self._keyframes[0]] if self._keyframes else None
            good = [
                i
                for i, t in enumerate(d_times.tolist())
                if t in self._color_missing
                or (
                    t in self._packet_of_pts
                    and first_key is not None
                    and self._packet_of_pts[t] >= self._keyframes[0]
                    and self._packet_group[self._packet_of_pts[t]] != unchecked
                )
            ]
            # Frames after the last complete one were in flight when the writer stopped. One
            # missing its packet before that is damage: it stays, and reading it fails. In a
            # sealed file none was in flight: every frame stays.
            keep = list(range(good[-1] + 1)) if good else []
            if self._seal is not None:
                keep = list(range(len(d_times)))
            d_times, d_offsets = d_times[keep], d_offsets[keep]
        self._times = d_times
        self._offsets = d_offsets
        depth_messages = len(index.times.get(fmt.TOPIC_DEPTH, []))
        if index.indexed and depth_messages and not len(d_times):
            raise DecodeError(
                f"{name!r} holds {depth_messages} depth message(s), but no frame has a "
                "decodable color packet (no keyframe before them, or no packet at their time)"
            )
        p_times, p_offsets = index.arrays(fmt.TOPIC_POSE)
        self._pose_at = {
            int(t): int(o) for t, o in zip(p_times.tolist(), p_offsets.tolist(), strict=True)
        }
        m_times, m_offsets = index.arrays(fmt.TOPIC_POSE_MATRIX)
        self._pose_matrix_at = {
            int(t): int(o) for t, o in zip(m_times.tolist(), m_offsets.tolist(), strict=True)
        }
        self._stream = ColorStream(self, self.color_shape, keep=KEEP_PICTURES)
        self._projector: Projector | None = None

    # -- description ---------------------------------------------------------------------

    @property
    def codecs(self) -> dict[str, dict[str, Any] | None]:
        """The configs of the codecs that wrote the recording (as stored: without the reader's
        own settings such as ``threads``)."""
        return {
            "color": self.color_codec.stored_config() if self.color_codec else None,
            "depth": self.depth_codec.stored_config(),
        }

    @property
    def timestamps(self) -> npt.NDArray[np.int64]:
        """Frame timestamps in nanoseconds, increasing."""
        out: npt.NDArray[np.int64] = self._times.copy()
        return out

    @property
    def indexed(self) -> bool:
        """False for a file whose writer did not finish (read by scanning; see ``recover``)."""
        return self.index.indexed

    @property
    def color_missing(self) -> list[int]:
        """The frames ``recover`` kept without their color, lost to damage (``color`` None)."""
        return [i for i, t in enumerate(self._times.tolist()) if t in self._color_missing]

    @property
    def complete(self) -> bool:
        """False for a file that ends before its writer closed it (cut short, or its writer
        stopped): opening it warned (``IncompleteRecordingWarning``); see ``recover``."""
        return fmt.ends_early(self.index) is None

    @property
    def projector(self) -> Projector:
        """The :class:`~pcdcodec.Projector` for this recording's camera and depth scale."""
        if self._projector is None:
            self._projector = Projector(
                self.intrinsics,
                depth_scale=self.depth_scale,
                color_intrinsics=self.color_intrinsics,
                depth_to_color=self.depth_to_color,
            )
        return self._projector

    @property
    def color_shape(self) -> tuple[int, int]:
        """``(height, width)`` of the color images: the color camera's, else the depth's."""
        return (self.color_intrinsics or self.intrinsics).shape

    @property
    def has_poses(self) -> bool:
        """Whether frames were written with a pose."""
        return bool(self._pose_at)

    def _pose(self, i: int) -> npt.NDArray[np.float64] | None:
        ts = int(self._times[i])
        found = self._pose_messages(i, ts)
        try:
            if fmt.TOPIC_POSE_MATRIX in found:
                offset = self._pose_matrix_at[ts]
                return header.parse_pose_matrix(found[fmt.TOPIC_POSE_MATRIX], i, offset)
            if fmt.TOPIC_POSE not in found:
                return None
            with np.errstate(all="ignore"):
                pose = header.transform_matrix(found[fmt.TOPIC_POSE])
            if not np.isfinite(pose).all():
                raise DecodeError(f"its {fmt.TOPIC_POSE} message is not finite")
            return pose
        except PcdcodecError as exc:  # a damaged message in a file without digests
            raise DecodeError(f"{str(self.path)!r}: frame {i} (t={ts} ns) pose: {exc}") from None

    def poses(self) -> list[npt.NDArray[np.float64] | None]:
        """The pose of every frame (``None`` for frames written without one)."""
        return [self._pose(i) for i in range(len(self))]

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return float(self._times[-1] - self._times[0]) / 1e9 if len(self._times) > 1 else 0.0

    def __len__(self) -> int:
        return int(self._times.size)

    def __repr__(self) -> str:
        return (
            f"<pcdcodec.Recording {str(self.path)!r}: {len(self)} frames, "
            f"{self.intrinsics.width}x{self.intrinsics.height}, codecs {self.codecs}>"
        )

    # -- depth alone ---------------------------------------------------------------------

    def _index_of(self, i: int) -> int:
        """Frame ``i`` as an index from 0, checked (once per call from outside)."""
        check_not_inherited(self, f"the reader of {str(self.path)!r}")
        n = len(self)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise InputTypeError(f"frame index must be an int, got {type(i).__name__}")
        if not -n <= i < n:
            raise IndexError(f"frame index {i} is out of range for {n} frames")
        return int(i) % n

    def depth_bytes(self, i: int) -> bytes:
        """The encoded depth of frame ``i``, exactly as its depth codec wrote it (see
        :func:`pcdcodec.decode_depth`). Raises :class:`~pcdcodec.DecodeError` when the file
        there is damaged."""
        return self._depth_bytes(self._index_of(i))

    def _depth_bytes(self, i: int) -> bytes:
        offset = int(self._offsets[i])
        ts = int(self._times[i])
        what = f"{str(self.path)!r}: frame {i} (t={ts} ns): depth at byte offset {offset}"
        with self._lock:
            messages = fmt.read_chunk_messages(
                self._file, offset, what=what, size=self.index.size or None
            )
        channel = self.index.channel(fmt.TOPIC_DEPTH)
        for m in messages:
            if channel is not None and m.channel_id == channel.id and m.log_time == ts:
                data = bytes(m.data)
                record = self._frame_record(i, what)
                if record is not None and fmt.data_digest(data) != record[2]:
                    raise DecodeError(
                        f"{what} does not match the frame's digest: the depth message was "
                        "changed, or belongs to another frame"
                    )
                return data
        raise DecodeError(f"{what}: no depth message with that time in the chunk there")

    def depth(self, i: int) -> npt.NDArray[Any]:
        """The depth image of frame ``i`` alone, without decoding its color."""
        return self._depth(self._index_of(i))

    def _depth(self, i: int) -> npt.NDArray[Any]:
        data = self._depth_bytes(i)
        what = (
            f"{str(self.path)!r}: frame {i} (t={int(self._times[i])} ns): depth at byte offset "
            f"{int(self._offsets[i])}"
        )
        try:
            # Checked before decoding, so a frame that claims to be huge is never made.
            header = read_header(data)
            cam = self.intrinsics
            if header.shape != (cam.height, cam.width):
                raise DecodeError(
                    f"the frame is {header.width}x{header.height}, but the recording's "
                    f"camera is {cam.width}x{cam.height}"
                )
            if header.dtype.name not in self.depth_codec.dtypes:
                raise DecodeError(
                    f"the frame is {header.dtype}, but {self.depth_codec.name!r} writes "
                    f"{' or '.join(str(d) for d in self.depth_codec.dtypes)}"
                )
            # The camera bounds the frame; no further pixel limit applies.
            depth = self.depth_codec.decode(data, max_pixels=None)
            if depth.shape != header.shape or depth.dtype != header.dtype:
                raise DecodeError(
                    f"decoded to {depth.dtype} {depth.shape}, expected "
                    f"{header.dtype} {header.shape}"
                )
            return depth
        except DecodeError as exc:
            raise DecodeError(f"{what}: {exc}") from exc

    # -- frames ----------------------------------------------------------------------------

    def _color(self, i: int) -> npt.NDArray[np.uint8] | None:
        with self._lock:
            return self._stream.color(i)

    def frame(self, i: int) -> Frame:
        """Frame ``i`` (negative counts from the end)."""
        i = self._index_of(i)
        return self._build(i, lambda: self._color(i), lambda: self._depth_and_pose(i))

    def _depth_and_pose(self, i: int) -> tuple[npt.NDArray[Any], npt.NDArray[np.float64] | None]:
        return self._depth(i), self._pose(i)

    def _build(
        self,
        i: int,
        color_of: Callable[[], npt.NDArray[np.uint8] | None],
        rest_of: Callable[[], tuple[npt.NDArray[Any], npt.NDArray[np.float64] | None]],
    ) -> Frame:
        """Frame ``i`` from its color, then its depth and pose (each raising what it raised)."""
        try:
            color = color_of()
            ch, cw = self.color_shape
            if color is not None and color.shape != (ch, cw, 3):
                raise DecodeError(
                    f"{str(self.path)!r}: frame {i}: color decoded to {color.shape}, expected "
                    f"({ch}, {cw}, 3) for the recording's color camera"
                )
            depth, pose = rest_of()
            ts = int(self._times[i])
            own = self._own_stamps().get(ts, (ts, ts))
            return Frame(
                color,
                depth,
                ts,
                index=i,
                pose=pose,
                projector=self.projector,
                color_timestamp_ns=own[0],
                depth_timestamp_ns=own[1],
            )
        except PcdcodecError:
            raise
        except Exception as exc:  # a backend or a record parser meeting damaged bytes
            raise DecodeError(
                f"{str(self.path)!r}: frame {i} (t={int(self._times[i])} ns) could not be "
                f"decoded ({type(exc).__name__}: {exc})"
            ) from exc

    def __getitem__(self, key: int | slice) -> Any:
        if isinstance(key, slice):
            return [self.frame(i) for i in range(*key.indices(len(self)))]
        return self.frame(key)

    def __iter__(self) -> Iterator[Frame]:
        return self._in_order(0)

    def _in_order(self, start: int) -> Iterator[Frame]:
        """Frames ``start`` … in order: read ahead on threads when ``threads`` is 2 or more."""
        workers = self.threads or 1
        if workers < 2 or start < 0 or len(self) - start < 2:
            for i in range(start, len(self)):
                yield self.frame(i)
            return
        stream = ColorStream(self, self.color_shape, with_threads(self.color_codec, workers // 2))
        ahead = ReadAhead(
            start,
            len(self),
            color=stream.color,
            rest=self._depth_and_pose,
            build=self._build,
            workers=workers,
            ahead=READ_AHEAD * workers,
        )
        self._read_aheads.add(ahead)
        try:
            yield from ahead
        finally:
            ahead.close()
            self._read_aheads.discard(ahead)

    def nearest(self, timestamp: int) -> Frame:
        """The frame whose timestamp is nearest ``timestamp`` (ns)."""
        if len(self) == 0:
            raise InputError(f"recording {str(self.path)!r} has no frames")
        i = int(np.searchsorted(self._times, timestamp))
        candidates = [c for c in (i - 1, i) if 0 <= c < len(self)]
        best = min(candidates, key=lambda c: abs(int(self._times[c]) - timestamp))
        return self.frame(best)

    def play(self, rate: float = 1.0, *, start: int = 0) -> Iterator[Frame]:
        """Yield frames paced at their recorded times (``rate`` 2.0 plays twice as fast).

        A frame that cannot be decoded in time is still yielded, late; playback never skips.
        """
        if not rate > 0:
            raise InputError(f"rate must be positive, got {rate}")
        if len(self) == 0:
            return
        t0 = time.perf_counter()
        first = int(self._times[start]) if start < len(self) else 0
        for i, frame in enumerate(self._in_order(start), start):
            due = t0 + (int(self._times[i]) - first) / 1e9 / rate
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            yield frame

    def verify(self) -> VerifyReport:
        """Check the whole file and decode every frame; report problems by frame and offset.

        Besides decoding each frame (which checks every CRC on its way), the file is read from
        start to end without the summary, and what that finds (channels, messages, their times,
        the data section's CRC, the metadata) is compared with what the index said. In files
        with frame digests and a seal, what the scan finds is compared with the seal too, and
        every group of color packets with its digest (``docs/format.md``).
        """
        return verify_recording(self)

    def close(self) -> None:
        """Stop the threads reading ahead (if any), then close the file."""
        if inherited(self):  # in a forked process: the parent's threads are not here
            return
        for ahead in list(self._read_aheads):
            ahead.close()
        self._file.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
