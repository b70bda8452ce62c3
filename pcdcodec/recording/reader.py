"""Reading a ``.pcdc`` recording: random access through MCAP's index, sequential decoding."""

from __future__ import annotations

import base64
import bisect
import json
import os
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..camera import CameraIntrinsics
from ..color.base import Packet, StreamCodec, VideoDecoder
from ..depth.base import FrameCodec
from ..errors import DecodeError, InputError, InputTypeError, PcdcodecError, UnknownCodecError
from ..frame import Frame
from ..projector import Projector
from ..registry import get_codec
from . import _index as fmt
from ._ros import CompressedVideo

__all__ = ["Frame", "Recording", "VerifyReport"]


@dataclass
class VerifyReport:
    """What :meth:`Recording.verify` found: per-frame problems, empty when all is well."""

    frames: int
    errors: list[str]
    indexed: bool
    truncated_at: int | None

    @property
    def ok(self) -> bool:
        return not self.errors


class Recording:
    """A ``.pcdc`` recording opened for reading. Use :func:`pcdcodec.open`.

    ``len(rec)``, ``rec[i]``, ``rec[a:b]`` (a list), iteration, ``rec.nearest(t)`` and
    ``rec.play()`` give :class:`Frame` objects. Random access reads only the frame's own messages,
    plus the color packets from the keyframe before it; iteration decodes each packet once.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise InputError(f"recording {str(self.path)!r} does not exist")
        if self.path.is_dir():
            raise InputError(f"{str(self.path)!r} is a folder, not a recording")
        self._file: IO[bytes] = open(self.path, "rb")  # noqa: SIM115 - closed by close()
        self._lock = threading.RLock()
        try:
            self._load()
        except BaseException:
            self._file.close()
            raise

    def _load(self) -> None:
        name = str(self.path)
        head = self._file.read(8)
        if head != fmt.MAGIC:
            raise DecodeError(f"{name!r} is not a pcdcodec recording (not an MCAP file)")
        self._file.seek(0)
        index = fmt.from_summary(self._file) or fmt.scan(self._file)
        self.index = index
        meta = index.metadata.get(fmt.METADATA_NAME)
        if index.profile != fmt.PROFILE or meta is None:
            raise DecodeError(
                f"{name!r} is an MCAP file but not a pcdcodec recording "
                f"(profile {index.profile!r}, no {fmt.METADATA_NAME!r} metadata)"
            )
        try:
            version = int(meta.get("format_version", ""))
        except ValueError:
            raise DecodeError(f"{name!r} has no valid format_version") from None
        if version > fmt.FORMAT_VERSION:
            raise DecodeError(
                f"{name!r} is format version {version}, newer than this pcdcodec reads "
                f"(version {fmt.FORMAT_VERSION}); upgrade pcdcodec to read it"
            )
        self.format_version = version
        self.intrinsics = CameraIntrinsics.from_dict(json.loads(meta["intrinsics"]))
        self.depth_scale = float(meta["depth_scale"])
        self.fps = float(meta.get("fps", "30"))
        self.metadata: dict[str, str] = dict(index.metadata.get(fmt.USER_METADATA_NAME, {}))
        try:
            depth_codec = get_codec(json.loads(meta["depth_codec"]), kind="depth")
            color_codec = (
                get_codec(json.loads(meta["color_codec"]), kind="color")
                if meta.get("color_codec")
                else None
            )
        except UnknownCodecError as exc:
            raise UnknownCodecError(
                f"{name!r} was written with a codec not available here: {exc}"
            ) from None
        assert isinstance(depth_codec, FrameCodec)
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
            if channel is not None and channel.metadata.get("extradata"):
                self._extradata = base64.b64decode(channel.metadata["extradata"])
            self._is_cdr = channel is not None and channel.encoding == "cdr"
            # A frame exists when both its depth and a decodable color packet were written.
            first_key = self._packet_pts[self._keyframes[0]] if self._keyframes else None
            keep = [
                i
                for i, t in enumerate(d_times.tolist())
                if t in self._packet_of_pts
                and first_key is not None
                and self._packet_of_pts[t] >= self._keyframes[0]
            ]
            d_times, d_offsets = d_times[keep], d_offsets[keep]
        self._times = d_times
        self._offsets = d_offsets
        self._decoder: VideoDecoder | None = None
        self._next_packet = 0
        self._decoded: dict[int, npt.NDArray[np.uint8]] = {}
        self._projector: Projector | None = None

    # -- description ---------------------------------------------------------------------

    @property
    def codecs(self) -> dict[str, dict[str, Any] | None]:
        """The configs of the codecs that wrote the recording."""
        return {
            "color": self.color_codec.get_config() if self.color_codec else None,
            "depth": self.depth_codec.get_config(),
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
    def projector(self) -> Projector:
        """The :class:`~pcdcodec.Projector` for this recording's camera and depth scale."""
        if self._projector is None:
            self._projector = Projector(self.intrinsics, depth_scale=self.depth_scale)
        return self._projector

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

    # -- frames ----------------------------------------------------------------------------

    def _depth(self, i: int) -> npt.NDArray[Any]:
        offset = int(self._offsets[i])
        ts = int(self._times[i])
        with self._lock:
            messages = fmt.read_chunk_messages(self._file, offset, what=f"frame {i} depth")
        channel = self.index.channel(fmt.TOPIC_DEPTH)
        for m in messages:
            if channel is not None and m.channel_id == channel.id and m.log_time == ts:
                try:
                    return self.depth_codec.decode(m.data)
                except DecodeError as exc:
                    raise DecodeError(
                        f"frame {i} (t={ts} ns): depth at byte offset {offset}: {exc}"
                    ) from exc
        raise DecodeError(f"frame {i}: no depth message at byte offset {offset}")

    def _packet(self, j: int) -> Packet:
        offset = int(self._packet_offsets[j])
        pts = int(self._packet_pts[j])
        with self._lock:
            messages = fmt.read_chunk_messages(self._file, offset, what=f"color packet {j}")
        channel = self.index.channel(fmt.TOPIC_COLOR)
        for m in messages:
            if channel is not None and m.channel_id == channel.id and m.log_time == pts:
                data = CompressedVideo.decode(m.data).data if self._is_cdr else m.data
                keyframe = j in self._keyframe_set
                return Packet(data, pts, int(m.publish_time), keyframe)
        raise DecodeError(f"color packet {j}: no color message at byte offset {offset}")

    def _color(self, i: int) -> npt.NDArray[np.uint8] | None:
        if self.color_codec is None:
            return None
        ts = int(self._times[i])
        j = self._packet_of_pts[ts]
        with self._lock:
            if ts in self._decoded:
                return self._decoded.pop(ts)
            k = self._keyframes[bisect.bisect_right(self._keyframes, j) - 1]
            if self._decoder is None or self._next_packet > j or k > self._next_packet:
                self._decoder = self.color_codec.decoder(
                    self.intrinsics.width, self.intrinsics.height, self._extradata
                )
                self._next_packet = k
                self._decoded.clear()
            while ts not in self._decoded:
                if self._next_packet < len(self._packet_pts):
                    j_next = self._next_packet
                    self._next_packet += 1
                    try:
                        out = self._decoder.decode(self._packet(j_next))
                    except DecodeError as exc:
                        self._decoder = None  # its state is unknown now: start afresh next time
                        raise DecodeError(
                            f"frame {i} (t={ts} ns): color packet at byte offset "
                            f"{int(self._packet_offsets[j_next])}: {exc}"
                        ) from exc
                else:
                    out = self._decoder.flush()
                    if not out:
                        raise DecodeError(f"frame {i} (t={ts} ns): its color frame never decoded")
                for f in out:
                    self._decoded[f.timestamp] = f.rgb
            # Frames before this one will not be asked for in order: drop them.
            for old in [t for t in self._decoded if t <= ts]:
                rgb = self._decoded.pop(old)
                if old == ts:
                    result = rgb
            return result

    def frame(self, i: int) -> Frame:
        """Frame ``i`` (negative counts from the end)."""
        n = len(self)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise InputTypeError(f"frame index must be an int, got {type(i).__name__}")
        if not -n <= i < n:
            raise IndexError(f"frame index {i} is out of range for {n} frames")
        i = int(i) % n
        return Frame(
            self._color(i), self._depth(i), int(self._times[i]), index=i, projector=self.projector
        )

    def __getitem__(self, key: int | slice) -> Any:
        if isinstance(key, slice):
            return [self.frame(i) for i in range(*key.indices(len(self)))]
        return self.frame(key)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(len(self)):
            yield self.frame(i)

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
        for i in range(start, len(self)):
            due = t0 + (int(self._times[i]) - first) / 1e9 / rate
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            yield self.frame(i)

    def verify(self) -> VerifyReport:
        """Decode every frame and check every checksum; report problems by frame and offset."""
        errors: list[str] = []
        if self.index.truncated_at is not None:
            errors.append(
                f"the file is cut short: records end at byte offset {self.index.truncated_at}"
            )
        for i in range(len(self)):
            try:
                self.frame(i)
            except PcdcodecError as exc:
                errors.append(str(exc))
                with self._lock:
                    self._decoder = None
        return VerifyReport(len(self), errors, self.index.indexed, self.index.truncated_at)

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
