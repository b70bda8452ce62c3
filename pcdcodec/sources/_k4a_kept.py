"""The tracks and attachments of an Azure Kinect ``.mkv`` that a recording keeps beside its
frames (``docs/ingest.md``), as kept topics of pcdcodec's own making:

* the ``IR`` track (16-bit, ``b16g``) on ``/k4a/ir``: message encoding ``pcdcodec.depth``, each
  message one IR image in the encoded depth frame container (``docs/format.md``), written with
  a lossless depth codec (the recording's depth codec where it is lossless, else ``depthac``),
  so it decodes bit-exact (:meth:`pcdcodec.Recording.kept_images`);
* the ``IMU`` track on ``/k4a/imu``: message encoding ``k4a.imu_sample``, each message one
  block as the file holds it (k4arecorder writes one sample a block, 40 bytes little-endian:
  u64 accelerometer time ns, 3 float32 m/s², u64 gyroscope time ns, 3 float32 rad/s);
* any other track not made into frames (the ``COLOR`` track of a depth-only reading, a track
  of another tool) on ``/k4a/<name>``: message encoding ``matroska.block``, its blocks as they
  are;
* every attachment (``calibration.json``, ...) on ``/k4a/attachment/<file name>``: message
  encoding ``matroska.attachment``, one message holding the file, at the recording's start.

None has a schema; each topic's metadata names the track or file it came from. A block's log
time is the frames' clock: ``K4A_START_OFFSET_NS`` plus its timestamp.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DecodeError, InputError, PcdcodecError
from ..ros.kept import IMAGE_ENCODING, KeptMessage, KeptTopic, TopicFilter
from ._mkv import packets, track_name

__all__ = [
    "ATTACHMENT_ENCODING",
    "BLOCK_ENCODING",
    "IMU_ENCODING",
    "IMU_SAMPLE",
    "IR_ENCODING",
    "K4aKeptTracks",
    "imu_samples",
]

IR_ENCODING = IMAGE_ENCODING
IMU_ENCODING = "k4a.imu_sample"
BLOCK_ENCODING = "matroska.block"
ATTACHMENT_ENCODING = "matroska.attachment"
#: The k4a IMU sample of a block, as a numpy dtype (``imu_samples``).
IMU_SAMPLE = np.dtype(
    [("acc_timestamp_ns", "<u8"), ("acc", "<f4", 3), ("gyro_timestamp_ns", "<u8"),
     ("gyro", "<f4", 3)]
)  # fmt: skip


def imu_samples(data: bytes) -> np.ndarray[Any, np.dtype[Any]]:
    """The IMU samples of a ``/k4a/imu`` message (a structured array of :data:`IMU_SAMPLE`:
    ``acc_timestamp_ns``, ``acc`` m/s², ``gyro_timestamp_ns``, ``gyro`` rad/s). Raises
    :class:`~pcdcodec.DecodeError` when its length is not a whole number of samples."""
    if len(data) % IMU_SAMPLE.itemsize:
        raise DecodeError(
            f"an IMU block of {len(data)} bytes is not a whole number of "
            f"{IMU_SAMPLE.itemsize}-byte k4a IMU samples"
        )
    return np.frombuffer(data, IMU_SAMPLE)


@dataclass(frozen=True)
class _Kept:
    """A track or attachment kept: its PyAV stream index, its name in the file, and its topic."""

    index: int
    name: str
    topic: KeptTopic
    shape: tuple[int, int] | None = None  # (height, width) of an IR track


def _topic_name(prefix: str, name: str, taken: set[str]) -> str:
    """``prefix`` and ``name`` made a topic name (``IR`` -> ``/k4a/ir``), not one of ``taken``."""
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", name.strip()).strip("_").lower() or "track"
    topic, n = f"{prefix}{slug}", 2
    while topic in taken:
        topic, n = f"{prefix}{slug}_{n}", n + 1
    taken.add(topic)
    return topic


class K4aKeptTracks:
    """The kept-topic half of :class:`~pcdcodec.sources.azure_kinect.AzureKinectSource`."""

    path: Any
    topic_filter: TopicFilter
    _start_ns: int
    _kept: list[_Kept]

    def _note_kept(self, streams: Any, frames: set[int], ir_codec: Any) -> None:
        """Note the tracks (those not read as frames: ``frames`` are their stream indices) and
        the attachments of an open file, before the first is read; ``ir_codec`` is the IR
        images' codec (``None``: the recording's where lossless, else ``depthac``)."""
        self._ir_spec = ir_codec
        self._ir_codec: Any = None
        if ir_codec is not None:
            self._ir_codec = self._lossless_codec(ir_codec, "ir_codec")
        kept: list[_Kept] = []
        taken: set[str] = set()
        for s in streams:
            if s.index in frames:
                continue
            meta = {str(k): str(v) for k, v in dict(s.metadata).items()}
            if s.type == "attachment":
                name = meta.get("filename", "") or f"attachment {s.index + 1}"
                topic = _topic_name("/k4a/attachment/", name, taken)
                facts = {"filename": name, "mimetype": meta.get("mimetype", "")}
                kept.append(_Kept(s.index, name, self._topic(topic, ATTACHMENT_ENCODING, facts)))
                continue
            name = track_name(s)
            ctx = s.codec_context
            tag = str(getattr(ctx, "codec_tag", "") or "") if ctx is not None else ""
            facts = {"track": name, **{k: v for k, v in meta.items() if k.startswith("K4A_")}}
            topic = _topic_name("/k4a/", name, taken)
            if s.type == "video" and tag == "b16g" and ctx.width and ctx.height:
                shape = (int(ctx.height), int(ctx.width))
                facts.update(width=str(shape[1]), height=str(shape[0]), dtype="uint16")
                kept.append(_Kept(s.index, name, self._topic(topic, IR_ENCODING, facts), shape))
            elif name == "IMU" or "K4A_IMU_MODE" in meta:
                kept.append(_Kept(s.index, name, self._topic(topic, IMU_ENCODING, facts)))
            else:
                codec = tag or str(getattr(ctx, "name", "") or "")
                facts.update(kind=str(s.type), codec=codec)
                kept.append(_Kept(s.index, name, self._topic(topic, BLOCK_ENCODING, facts)))
        self._kept = [k for k in kept if self.topic_filter(k.topic.topic)]

    @staticmethod
    def _topic(topic: str, encoding: str, facts: dict[str, str]) -> KeptTopic:
        return KeptTopic(topic, "", "", "", encoding, facts)

    @staticmethod
    def _lossless_codec(spec: Any, name: str) -> Any:
        from ..registry import as_codec, get_codec

        codec = as_codec(spec, "depth")
        if not getattr(codec, "lossless", False):
            raise InputError(
                f"{name} {codec.name!r} is lossy; the IR images are kept losslessly: give a "
                "lossless depth codec (depthac, rvl, png16, zstd, lz4, ...)"
            )
        return get_codec(codec.get_config(), kind="depth")  # an instance of its own

    def use_depth_codec(self, depth: Any) -> None:
        """Keep the IR images with ``depth`` (the recording's depth codec) where it is lossless
        and no ``ir_codec`` was given; else they stay with ``depthac``."""
        if self._ir_spec is not None:
            return
        try:
            self._ir_codec = self._lossless_codec(depth, "depth")
        except InputError:
            self._ir_codec = None

    def kept_topics(self) -> list[KeptTopic]:
        """The tracks and attachments kept (see :mod:`pcdcodec.sources._k4a_kept`)."""
        return [k.topic for k in self._kept]

    def kept_streams(self) -> dict[str, str]:
        """The name of each kept track or attachment (as :meth:`input_streams` lists it) ->
        its topic."""
        return {k.name: k.topic.topic for k in self._kept}

    def kept_count(self, topic: str, blocks: dict[str, int | None]) -> int | None:
        """The messages a kept topic will have: an attachment's one, a track's blocks (from
        ``blocks``, the block count of each track by name; ``None`` where not known)."""
        for k in self._kept:
            if k.topic.topic == topic:
                if k.topic.message_encoding == ATTACHMENT_ENCODING:
                    return 1
                return blocks.get(k.name)
        return None

    def kept_messages(self) -> Iterator[KeptMessage]:
        """The attachments (at the recording's start), then the kept tracks' blocks in file
        order, IR images encoded. Raises :class:`~pcdcodec.DecodeError` naming the file for a
        file that no longer reads or an IR block of the wrong size."""
        if not self._kept:
            return
        import av

        where = repr(str(self.path))
        codec = self._ir_codec
        if codec is None and any(k.shape for k in self._kept):
            from ..registry import get_codec

            codec = self._ir_codec = get_codec("depthac", kind="depth")
        try:
            container = av.open(str(self.path))
        except (av.error.FFmpegError, OSError, UnicodeDecodeError) as exc:
            raise DecodeError(f"{where} is not a readable Matroska file: {exc}") from exc
        try:
            by_index = {k.index: k for k in self._kept}
            tracks = []
            s: Any
            for s in container.streams:
                k = by_index.get(s.index)
                if k is None:
                    continue
                if k.topic.message_encoding == ATTACHMENT_ENCODING:
                    yield KeptMessage(k.topic, self._start_ns, bytes(s.data))
                else:
                    tracks.append(s)
            if not tracks:
                return
            for packet in packets(container, tracks, where):
                k = by_index[packet.stream.index]
                pts = int(packet.pts if packet.pts is not None else packet.dts or 0)
                tb = packet.stream.time_base
                ns = self._start_ns + round(pts * (float(tb * 1_000_000_000) if tb else 1000.0))
                data = bytes(packet)
                if k.shape is not None:
                    data = self._ir(data, k, pts, codec, where)
                yield KeptMessage(k.topic, max(ns, 0), data)
        except PcdcodecError:
            raise
        except Exception as exc:
            raise DecodeError(f"{where}: the kept tracks do not read: {exc}") from exc
        finally:
            container.close()

    @staticmethod
    def _ir(data: bytes, kept: _Kept, pts: int, codec: Any, where: str) -> bytes:
        """An IR block (16-bit big-endian) as an encoded depth frame."""
        assert kept.shape is not None
        h, w = kept.shape
        if len(data) != 2 * w * h:
            raise DecodeError(
                f"{where}: {kept.name} block at pts {pts} holds {len(data)} bytes, expected "
                f"{2 * w * h} for {w}x{h} 16-bit images (exclude_topics={kept.topic.topic!r} "
                "records the rest)"
            )
        image = np.frombuffer(data, ">u2").reshape(h, w).astype(np.uint16)
        return bytes(codec.encode(image))
