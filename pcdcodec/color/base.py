"""The color codec interfaces: packet streams (:class:`StreamCodec`) and whole video files
(:class:`FileVideoCodec`).

A color codec (:class:`StreamCodec`) is a factory: :meth:`StreamCodec.encoder` starts a stream of
RGB frames and :meth:`StreamCodec.decoder` starts reading one. Encoders keep state across frames
(reference frames, rate control, B-frame reordering), so a frame in does not always give a packet
out at once: :meth:`VideoEncoder.flush` returns the rest at the end.

Timestamps are integer nanoseconds throughout. A :class:`Packet` carries the presentation
timestamp (``pts``) of the frame it shows, the decoding timestamp (``dts``), whether decoding can
start at it (``keyframe``) and a CRC-32 of its data, which decoders check, so damaged packets
raise :class:`~pcdcodec.DecodeError` instead of decoding into wrong pixels.

A file codec (:class:`FileVideoCodec`) writes a whole video file frame by frame
(:class:`VideoFileWriter`) and reads one back (:class:`VideoFileReader`); frame ``i`` of such a
file is shown at ``i / fps``. Both kinds check frame sizes and rates the same way, here.
"""

from __future__ import annotations

import os
import zlib
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from .._validate import check_color
from ..codec import ColorCodec
from ..errors import DecodeError, InputError, InputTypeError

__all__ = [
    "DecodedFrame",
    "DecodedPicture",
    "FileVideoCodec",
    "Packet",
    "PathArg",
    "StreamCodec",
    "VideoDecoder",
    "VideoEncoder",
    "VideoFileReader",
    "VideoFileWriter",
    "decode_packets",
    "default_keyframe_interval",
    "encode_frames",
]

#: A file path argument.
PathArg = str | os.PathLike[str]


@dataclass(frozen=True)
class Packet:
    """One encoded unit of a color stream.

    ``data`` is the codec's own bitstream (Annex B for H.264/H.265, a JPEG for MJPEG, …);
    ``pts`` and ``dts`` are nanoseconds; ``checksum`` is the CRC-32 of ``data``, or ``None``
    for packets from elsewhere (then only the decoder library can notice damage).
    """

    data: bytes
    pts: int
    dts: int
    keyframe: bool
    checksum: int | None = None

    @classmethod
    def create(cls, data: bytes, pts: int, dts: int, keyframe: bool) -> Packet:
        """A packet with its checksum filled in."""
        return cls(data, pts, dts, keyframe, zlib.crc32(data))

    def verify(self) -> None:
        """Raise :class:`~pcdcodec.DecodeError` when ``data`` does not match ``checksum``."""
        if self.checksum is not None and zlib.crc32(self.data) != self.checksum:
            raise DecodeError(
                f"color packet at pts {self.pts} ns is corrupt: CRC-32 of its {len(self.data)} "
                f"bytes is {zlib.crc32(self.data):#010x}, expected {self.checksum:#010x}"
            )


@dataclass(frozen=True)
class DecodedFrame:
    """One picture out of a video decoder: RGB (H×W×3 uint8) and its pts in nanoseconds.

    Color only, on the codec level; the RGB-D frame of sources and recordings is
    :class:`pcdcodec.Frame`.
    """

    rgb: npt.NDArray[np.uint8]
    timestamp: int

    @property
    def timestamp_ns(self) -> int:
        """The same as ``timestamp``, under the name :class:`pcdcodec.Frame` uses."""
        return self.timestamp

    def __iter__(self) -> Any:
        return iter((self.rgb, self.timestamp))


class DecodedPicture:
    """One picture out of a video decoder, not yet converted to RGB: its pts in nanoseconds,
    and :meth:`rgb`, which converts it on each call (a new array each time).

    Seeking decodes every frame from the keyframe before the one asked for, but shows only that
    one: the others are needed as references, never as RGB, so they are not converted.
    ``nbytes`` is about the memory the picture holds while it is kept.
    """

    __slots__ = ("_convert", "nbytes", "timestamp")

    def __init__(
        self, timestamp: int, convert: Callable[[], npt.NDArray[np.uint8]], nbytes: int
    ) -> None:
        self.timestamp = timestamp
        self.nbytes = nbytes
        self._convert = convert

    @classmethod
    def of(cls, frame: DecodedFrame) -> DecodedPicture:
        """A picture of a frame already in RGB (a decoder that cannot put off converting)."""
        rgb = frame.rgb
        return cls(frame.timestamp, rgb.copy, rgb.nbytes)

    def rgb(self) -> npt.NDArray[np.uint8]:
        """The picture as a new H×W×3 uint8 RGB image."""
        return self._convert()


def _check_size(width: Any, height: Any) -> tuple[int, int]:
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise InputTypeError(f"{name} must be an int, got {type(value).__name__}")
        if not 1 <= value <= 16384:
            raise InputError(f"{name} must be in 1..16384 pixels, got {value}")
    return int(width), int(height)


def _check_fps(fps: Any) -> float:
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 1000:
        raise InputError(f"fps must be a number in (0, 1000], got {fps!r}")
    return float(fps)


def _keep_in_child(stream: object) -> None:
    """A stream (FFmpeg's or OpenCV's, with their threads) is never freed by a forked child."""
    from .fork import keep_in_child  # loaded with the first stream, not by ``import pcdcodec``

    keep_in_child(stream)


def _inherited(stream: object) -> bool:
    from .fork import inherited

    return inherited(stream)


def _check_ours(stream: object, what: str) -> None:
    from .fork import check_not_inherited

    check_not_inherited(stream, what)


class VideoEncoder(ABC):
    """Turns RGB frames of one size into packets. Use one encoder per stream."""

    def __init__(self, codec: StreamCodec, width: int, height: int, fps: float) -> None:
        self.codec = codec
        self.width, self.height = _check_size(width, height)
        self.fps = _check_fps(fps)
        self.frames_in = 0
        self._last_timestamp: int | None = None
        self._flushed = False
        _keep_in_child(self)

    @property
    def extradata(self) -> bytes | None:
        """Codec set-up bytes a decoder needs (some lossless codecs), or ``None``."""
        return None

    def encode(self, rgb: npt.ArrayLike, timestamp: int) -> list[Packet]:
        """Encode one H×W×3 uint8 RGB frame shown at ``timestamp`` ns; return ready packets.

        Timestamps must increase. Raises :class:`~pcdcodec.InputError` for a frame of another
        size, RGBA or gray input, a non-uint8 dtype, or a timestamp that does not increase.
        """
        if self._flushed:
            raise InputError("encoder was flushed; start a new encoder for a new stream")
        frame = check_color(rgb, name="color frame")
        if frame.shape[:2] != (self.height, self.width):
            raise InputError(
                f"color frame is {frame.shape[1]}x{frame.shape[0]}, but this stream is "
                f"{self.width}x{self.height} (width x height); the size cannot change mid-stream"
            )
        if isinstance(timestamp, bool) or not isinstance(timestamp, (int, np.integer)):
            raise InputTypeError(f"timestamp must be an int (ns), got {type(timestamp).__name__}")
        timestamp = int(timestamp)
        if self._last_timestamp is not None and timestamp <= self._last_timestamp:
            raise InputError(
                f"timestamp {timestamp} ns does not increase (previous frame: "
                f"{self._last_timestamp} ns)"
            )
        return self.encode_checked(frame, timestamp)

    def encode_checked(self, frame: npt.NDArray[np.uint8], timestamp: int) -> list[Packet]:
        """:meth:`encode` past its checks, for a caller that checked the frame already: ``frame``
        is a C-contiguous H×W×3 uint8 image of this stream's size, ``timestamp`` an int later
        than the last frame's. A recording's writer checks each frame once, where it is handed
        in, and encodes it with this."""
        if self._flushed:
            raise InputError("encoder was flushed; start a new encoder for a new stream")
        _check_ours(self, f"the {self.codec.name} encoder")
        self._last_timestamp = timestamp
        packets = self._encode(frame, timestamp)
        self.frames_in += 1
        return packets

    def flush(self) -> list[Packet]:
        """End the stream and return the packets still held by the encoder."""
        if self._flushed:
            return []
        _check_ours(self, f"the {self.codec.name} encoder")
        self._flushed = True
        return self._flush()

    @abstractmethod
    def _encode(self, rgb: npt.NDArray[np.uint8], timestamp: int) -> list[Packet]: ...

    @abstractmethod
    def _flush(self) -> list[Packet]: ...


class VideoDecoder(ABC):
    """Turns packets back into RGB frames in display order."""

    def __init__(
        self, codec: StreamCodec, width: int, height: int, extradata: bytes | None = None
    ) -> None:
        self.codec = codec
        self.width, self.height = _check_size(width, height)
        self.extradata = extradata
        _keep_in_child(self)

    def decode(self, packet: Packet) -> list[DecodedFrame]:
        """Decode one packet; return the frames that became ready, in display order.

        Raises :class:`~pcdcodec.DecodeError` for a damaged packet or a stream the codec
        cannot decode.
        """
        if not isinstance(packet, Packet):
            raise InputTypeError(f"decode expects a Packet, got {type(packet).__name__}")
        packet.verify()
        _check_ours(self, f"the {self.codec.name} decoder")
        return self._decode(packet)

    def flush(self) -> list[DecodedFrame]:
        """Return the frames still held by the decoder at the end of the stream."""
        _check_ours(self, f"the {self.codec.name} decoder")
        return self._flush()

    def decode_pictures(self, packet: Packet) -> list[DecodedPicture]:
        """:meth:`decode`, but each frame is converted to RGB only when asked
        (:meth:`DecodedPicture.rgb`): for a reader that decodes frames it will not show."""
        if not isinstance(packet, Packet):
            raise InputTypeError(f"decode expects a Packet, got {type(packet).__name__}")
        packet.verify()
        _check_ours(self, f"the {self.codec.name} decoder")
        return self._decode_pictures(packet)

    def flush_pictures(self) -> list[DecodedPicture]:
        """:meth:`flush`, with the frames as in :meth:`decode_pictures`."""
        _check_ours(self, f"the {self.codec.name} decoder")
        return self._flush_pictures()

    @abstractmethod
    def _decode(self, packet: Packet) -> list[DecodedFrame]: ...

    @abstractmethod
    def _flush(self) -> list[DecodedFrame]: ...

    # A decoder that can put off the conversion to RGB replaces these two.
    def _decode_pictures(self, packet: Packet) -> list[DecodedPicture]:
        return [DecodedPicture.of(f) for f in self._decode(packet)]

    def _flush_pictures(self) -> list[DecodedPicture]:
        return [DecodedPicture.of(f) for f in self._flush()]


#: The default keyframe interval of the video codecs, in seconds of frames. A third of a second
#: keeps ``rec[i]`` at random within 2× the time of reading in order (it decodes, on average,
#: half an interval of color before its frame) for about 2.5 % more bytes than one second
#: (``docs/recording.md``).
DEFAULT_KEYFRAME_SECONDS = 1 / 3


def default_keyframe_interval(fps: float) -> int:
    """The default keyframe interval at ``fps`` frames/s: :data:`DEFAULT_KEYFRAME_SECONDS` of
    frames, at least 1 (10 at 30 fps)."""
    return max(1, round(fps * DEFAULT_KEYFRAME_SECONDS))


class StreamCodec(ColorCodec):
    """A color codec whose streams are packets (as opposed to whole video files).

    ``video_format`` names the bitstream for ``foxglove_msgs/CompressedVideo`` (``"h264"``,
    ``"h265"``, ``"av1"``, ``"vp9"``) when the codec writes one of those, else ``None``:
    recordings store such packets as CompressedVideo messages, others as raw packets.
    """

    video_format: ClassVar[str | None] = None

    @abstractmethod
    def encoder(self, width: int, height: int, fps: float = 30.0) -> VideoEncoder:
        """Start a stream of ``width`` × ``height`` RGB frames at about ``fps`` frames/s."""

    @abstractmethod
    def decoder(self, width: int, height: int, extradata: bytes | None = None) -> VideoDecoder:
        """Start decoding a stream of ``width`` × ``height`` frames written by :meth:`encoder`."""


def encode_frames(
    codec: StreamCodec,
    frames: Iterable[npt.ArrayLike],
    timestamps: Iterable[int] | None = None,
    fps: float = 30.0,
) -> tuple[list[Packet], bytes | None]:
    """Encode a whole sequence of RGB frames; return its packets and the decoder's extradata.

    Without ``timestamps``, frame ``i`` is shown at ``i / fps`` seconds.
    """
    encoder: VideoEncoder | None = None
    packets: list[Packet] = []
    stamps = iter(timestamps) if timestamps is not None else None
    for i, frame in enumerate(frames):
        rgb = check_color(frame, name=f"color frame {i}")
        if encoder is None:
            encoder = codec.encoder(rgb.shape[1], rgb.shape[0], fps)
        stamp = next(stamps, None) if stamps is not None else round(i * 1e9 / fps)
        if stamp is None:
            raise InputError(f"fewer timestamps than frames: none left for frame {i}")
        packets += encoder.encode(rgb, stamp)
    if encoder is None:
        raise InputError("no frames to encode")
    packets += encoder.flush()
    return packets, encoder.extradata


def decode_packets(
    codec: StreamCodec,
    packets: Sequence[Packet],
    width: int,
    height: int,
    extradata: bytes | None = None,
) -> list[DecodedFrame]:
    """Decode a sequence of packets (from a keyframe on) into frames in display order."""
    decoder = codec.decoder(width, height, extradata)
    frames: list[DecodedFrame] = []
    for packet in packets:
        frames += decoder.decode(packet)
    frames += decoder.flush()
    return frames


# -- whole video files ---------------------------------------------------------------------------


class VideoFileWriter(ABC):
    """Writes RGB frames of one size into a video file; a context manager.

    The file appears at :attr:`path` only when :meth:`close` succeeds. Leaving the ``with``
    block by an exception discards what was written, so a failed recording never looks valid.
    """

    def __init__(
        self, codec: FileVideoCodec, path: Path, width: int, height: int, fps: float
    ) -> None:
        self.codec = codec
        self.path = path
        self.width, self.height = _check_size(width, height)
        self.fps = _check_fps(fps)
        self.frames_written = 0
        self._closed = False
        _keep_in_child(self)

    def write(self, rgb: npt.ArrayLike) -> None:
        """Append one H×W×3 uint8 RGB frame.

        Raises :class:`~pcdcodec.InputError` for a frame of another size (the size cannot change
        mid-file), RGBA or gray input, a non-uint8 dtype, or a closed writer.
        """
        if self._closed:
            raise InputError(f"writer of {str(self.path)!r} is closed; open a new one")
        frame = check_color(rgb, name="color frame")
        if frame.shape[:2] != (self.height, self.width):
            raise InputError(
                f"color frame is {frame.shape[1]}x{frame.shape[0]}, but {str(self.path)!r} is "
                f"{self.width}x{self.height} (width x height); the size cannot change mid-file"
            )
        self._write(frame)
        self.frames_written += 1

    def close(self) -> None:
        """Finish the file and move it into place at :attr:`path`. Closing twice is harmless."""
        if self._closed or _inherited(self):  # a forked process leaves the parent's file
            self._closed = True
            return
        self._closed = True
        self._close()

    def abort(self) -> None:
        """Stop writing and delete what was written; nothing appears at :attr:`path`."""
        if self._closed or _inherited(self):  # a forked process leaves the parent's file
            self._closed = True
            return
        self._closed = True
        self._abort()

    def __enter__(self) -> VideoFileWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    @abstractmethod
    def _write(self, rgb: npt.NDArray[np.uint8]) -> None: ...

    @abstractmethod
    def _close(self) -> None: ...

    @abstractmethod
    def _abort(self) -> None: ...


class VideoFileReader(ABC):
    """Reads a video file back as H×W×3 uint8 RGB frames; iterable, sized, a context manager.

    Each ``for`` loop starts again at the first frame. Frame ``i`` was shown at ``i / fps``
    seconds: files written this way keep no per-frame timestamps.
    """

    def __init__(self, codec: FileVideoCodec, path: Path) -> None:
        self.codec = codec
        self.path = path
        _keep_in_child(self)

    @property
    @abstractmethod
    def width(self) -> int:
        """Frame width in pixels."""

    @property
    @abstractmethod
    def height(self) -> int:
        """Frame height in pixels."""

    @property
    @abstractmethod
    def fps(self) -> float:
        """The frame rate stored in the file, frames per second."""

    @abstractmethod
    def __len__(self) -> int: ...

    @abstractmethod
    def __iter__(self) -> Iterator[npt.NDArray[np.uint8]]: ...

    @abstractmethod
    def close(self) -> None:
        """Release the file. Iterating afterwards opens it again."""

    def __enter__(self) -> VideoFileReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class FileVideoCodec(ColorCodec):
    """A color codec whose unit is a whole video file (as opposed to a stream of packets)."""

    @property
    @abstractmethod
    def suffix(self) -> str:
        """The file extension this codec writes, with its dot (``".avi"``)."""

    @abstractmethod
    def writer(
        self, path: PathArg, width: int, height: int, fps: float = 30.0, *, overwrite: bool = False
    ) -> VideoFileWriter:
        """Start writing ``width`` × ``height`` RGB frames at ``fps`` frames/s into ``path``."""

    @abstractmethod
    def reader(self, path: PathArg) -> VideoFileReader:
        """Open the video file at ``path`` for reading."""
