"""The encoded streams of a recording as written, and the frame digests that vouch for them.

:class:`PacketAccess` gives :class:`~pcdcodec.Recording` its packet level (the counterpart of
:meth:`~pcdcodec.RecordingWriter.write_encoded`): the color packets in decode order, each read
from its chunk, and the check of every group of packets, depth message and pose against the
frame's digest message (``docs/format.md``).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..color.base import Packet, StreamCodec
from ..errors import DecodeError
from ..ros.foxglove import CompressedVideo
from . import _index as fmt


class PacketAccess:
    """Color packets and frame digests of a :class:`~pcdcodec.Recording`."""

    path: Path
    index: fmt.FileIndex
    integrity: int
    color_codec: StreamCodec | None
    _file: IO[bytes]
    _lock: threading.RLock
    _seal: dict[str, str] | None
    _times: npt.NDArray[np.int64]
    _extradata: bytes | None
    _is_cdr: bool
    _keyframes: list[int]
    _keyframe_set: set[int]
    _packet_pts: npt.NDArray[np.int64]
    _packet_of_pts: dict[int, int]
    _packet_offsets: npt.NDArray[np.int64]
    _packet_group: npt.NDArray[np.int64]
    #: The color packets that can be read: all but, in a file the writer did not close, the
    #: last ones, written before their frame's digest.
    _readable_packets: int = 0
    _packet_cache: dict[int, Any]
    _groups_checked: set[int]
    _records: dict[int, tuple[int, bytes, bytes, bytes]]
    _digest_times: npt.NDArray[np.int64]
    _digest_offsets: npt.NDArray[np.int64]
    _digest_of_time: dict[int, int]
    _pose_at: dict[int, int]
    _pose_matrix_at: dict[int, int]
    _color_missing: frozenset[int]

    @property
    def pose_timestamps(self) -> npt.NDArray[np.int64]:
        """The timestamps (ns) of the frames written with a pose, in order, from the index
        (no pose is read)."""
        posed = set(self._pose_at) | set(self._pose_matrix_at)
        times = [t for t in self._times.tolist() if int(t) in posed]
        return np.asarray(times, np.int64)

    #: The images' own times by frame time, once read (:meth:`_own_stamps`).
    _stamps_read: dict[int, tuple[int, int]] | None = None

    def _message_at(self, offset: int, topic: str, ts: int, what: str) -> bytes | None:
        """The data of the ``topic`` message at time ``ts`` in the chunk at ``offset`` (``None``
        where the chunk holds none); ``what`` names it in the errors of reading the chunk."""
        with self._lock:
            messages = fmt.read_chunk_messages(
                self._file, offset, what=what, size=self.index.size or None
            )
        channel = self.index.channel(topic)
        if channel is None:
            return None
        return next(
            (bytes(m.data) for m in messages if m.channel_id == channel.id and m.log_time == ts),
            None,
        )

    def _pose_messages(self, i: int, ts: int) -> dict[str, bytes]:
        """The frame's pose messages by topic, each read once, checked against its digest."""
        what = f"{str(self.path)!r}: frame {i} (t={ts} ns) pose"
        found: dict[str, bytes] = {}
        for topic, at in (
            (fmt.TOPIC_POSE, self._pose_at),
            (fmt.TOPIC_POSE_MATRIX, self._pose_matrix_at),
        ):
            offset = at.get(ts)
            if offset is None:
                continue
            data = self._message_at(offset, topic, ts, what)
            if data is None:
                raise DecodeError(f"{what}: no {topic} message at byte offset {offset}")
            found[topic] = data
        record = self._frame_record(i, what)
        digest = fmt.data_digest(*found.values()) if found else fmt.NO_POSE
        if record is not None and digest != record[3]:
            raise DecodeError(
                f"{what} does not match the frame's digest: its pose messages were changed, "
                "added or removed"
            )
        return found

    @property
    def extradata(self) -> bytes | None:
        """The color decoder's set-up bytes (FFV1, HuffYUV), or ``None``."""
        return self._extradata

    @property
    def packet_timestamps(self) -> npt.NDArray[np.int64]:
        """The pts (ns) of every color packet, in decode (file) order; empty without color.

        Of a file cut short (or whose writer was stopped), the last packets the writer wrote
        before their frames' digest are left out, as those frames are: every packet listed
        can be read."""
        if self.color_codec is None:
            return np.zeros(0, np.int64)
        readable = self._packet_pts[: self._readable_packets]
        out: npt.NDArray[np.int64] = np.asarray(readable, np.int64).copy()
        return out

    @property
    def keyframes(self) -> list[int]:
        """Indices (into :attr:`packet_timestamps`) of the color packets decoding can start at."""
        return [j for j in self._keyframes if j < self._readable_packets]

    def packet(self, j: int) -> Packet:
        """Color packet ``j`` in decode order, as written (``checksum`` is ``None``)."""
        n = len(self.packet_timestamps)
        if isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 0 <= j < n:
            raise IndexError(f"packet index {j!r} is out of range for {n} packets")
        j = int(j)
        with self._lock:
            self._check_packets(j, j, f"{str(self.path)!r}: color packet {j}")
        return self._packet(j)

    def packets(self, start: int = 0) -> Iterator[Packet]:
        """The color packets from ``start`` on, in decode order, each read once: with
        :attr:`extradata`, what a decoder (or a muxer) needs to play the color stream."""
        for j in range(start, len(self.packet_timestamps)):
            with self._lock:
                self._check_packets(j, j, f"{str(self.path)!r}: color packet {j}")
            yield self._packet(j)

    def _packet(self, j: int) -> Packet:
        m = self._packet_message(j)
        data = CompressedVideo.decode(m.data).data if self._is_cdr else m.data
        keyframe = j in self._keyframe_set
        return Packet(data, int(m.log_time), int(m.publish_time), keyframe)

    def _packet_message(self, j: int) -> Any:
        """The MCAP message of color packet ``j``, as stored."""
        cached = self._packet_cache.pop(j, None)
        if cached is not None:
            return cached
        offset = int(self._packet_offsets[j])
        pts = int(self._packet_pts[j])
        what = f"{str(self.path)!r}: color packet {j} (pts {pts}) at byte offset {offset}"
        with self._lock:
            messages = fmt.read_chunk_messages(
                self._file, offset, what=what, size=self.index.size or None
            )
        channel = self.index.channel(fmt.TOPIC_COLOR)
        for m in messages:
            if channel is not None and m.channel_id == channel.id and m.log_time == pts:
                return m
        raise DecodeError(f"{what}: no color message with that time in the chunk there")

    def _check_packets(self, first: int, last: int, what: str) -> None:
        """Check the digests of the groups holding color packets ``first`` … ``last``.

        Files without color digests (written before them) are not checked. Raises
        :class:`DecodeError` starting with ``what`` when a group's packets (their data, times,
        keyframe flags, number or order) differ from its digest.
        """
        if not self.integrity or last < first:
            return
        groups = self._packet_group
        for g in range(int(groups[first]), int(groups[last]) + 1):
            if g in self._groups_checked:
                continue
            try:
                problem = self._group_problem(g)
            except DecodeError as exc:
                raise DecodeError(f"{what}: {exc}") from exc
            if problem:
                raise DecodeError(f"{what}: {problem}")
            self._groups_checked.add(g)

    def _record(self, g: int) -> tuple[int, bytes, bytes, bytes]:
        """Frame digest message ``g`` (in file order): packets, color, depth and pose digests."""
        if g in self._records:
            return self._records[g]
        offset, ts = int(self._digest_offsets[g]), int(self._digest_times[g])
        where = f"{str(self.path)!r}: the frame digest at byte offset {offset}"
        data = self._message_at(offset, fmt.TOPIC_FRAME_DIGEST, ts, where)
        if data is None or len(data) != fmt.DIGEST_RECORD.size:
            raise DecodeError(f"{where}: no frame digest message of {fmt.DIGEST_RECORD.size} bytes")
        record: tuple[int, bytes, bytes, bytes] = fmt.DIGEST_RECORD.unpack(data)
        self._records[g] = record
        return record

    def _frame_record(self, i: int, what: str) -> tuple[int, bytes, bytes, bytes] | None:
        """The digest message of frame ``i``; ``None`` in files written without them."""
        if not self.integrity:
            return None
        g = self._digest_of_time.get(int(self._times[i]))
        if g is None:
            raise DecodeError(f"{what}: the frame has no digest message")
        return self._record(g)

    def _group_problem(self, g: int) -> str:
        """Why the color packets of digest group ``g`` differ from their digest, or ``""``."""
        lo, hi = np.searchsorted(self._packet_group, [g, g + 1], side="left").tolist()
        sealer = fmt.Sealer()
        for j in range(lo, hi):
            m = self._packet_message(j)
            sealer.packet(int(m.log_time), int(m.publish_time), j in self._keyframe_set, m.data)
            if len(self._packet_cache) < 64:  # decoding usually reads them next: once is enough
                self._packet_cache[j] = m
        count, digest = sealer.group()
        if g < len(self._digest_offsets):
            where = f"the frame digest at byte offset {int(self._digest_offsets[g])}"
            want_count, want, _, _ = self._record(g)
        elif self._seal is not None:
            where = f"the seal's digest of the last {hi - lo} color packet(s)"
            try:
                want_count = int(self._seal.get("tail_packets", ""))
                want = bytes.fromhex(self._seal.get("tail_digest", "").removeprefix("sha256:"))
            except ValueError:
                return "the seal's tail_packets/tail_digest are not a count and a digest"
        else:
            return f"the last {hi - lo} color packet(s) have no digest (the writer stopped first)"
        if (count, digest) != (want_count, want):
            found = (
                f"the {count} color packet(s) from byte offset {int(self._packet_offsets[lo])}"
                if hi > lo
                else "no color packet"
            )
            return (
                f"{found} do not match {where} "
                f"({want_count} packet(s)): the color packets were changed, reordered, added or "
                "removed"
            )
        return ""

    def image_timestamps(self) -> list[tuple[int, int]]:
        """``(color, depth)``: each frame's images' own times (ns), as
        ``frame.color_timestamp_ns`` and ``frame.depth_timestamp_ns`` give them (the frame's
        time where they were not stamped apart), read without decoding an image."""
        own = self._own_stamps()
        return [own.get(int(t), (int(t), int(t))) for t in self._times]

    def _own_stamps(self) -> dict[int, tuple[int, int]]:
        """The color and depth images' own times (ns) by frame time, for the frames whose
        images were stamped apart from the frame (``/camera/stamps``); read once, all at a
        time, and checked against the seal in a sealed file."""
        if self._stamps_read is not None:
            return self._stamps_read
        name = repr(str(self.path))
        entries = zip(
            self.index.times.get(fmt.TOPIC_STAMPS, []),
            self.index.offsets.get(fmt.TOPIC_STAMPS, []),
            strict=True,
        )
        out: dict[int, tuple[int, int]] = {}
        sealer = fmt.Sealer()
        for t, offset in sorted(entries, key=lambda e: e[1]):  # file order
            where = f"{name}: the {fmt.TOPIC_STAMPS} message at byte offset {offset}"
            data = self._message_at(offset, fmt.TOPIC_STAMPS, int(t), where)
            if data is None or len(data) != fmt.STAMPS_RECORD.size:
                raise DecodeError(
                    f"{where}: no message of {fmt.STAMPS_RECORD.size} bytes at {t} ns there"
                )
            stamps: tuple[int, int] = fmt.STAMPS_RECORD.unpack(data)
            if not all(0 <= v <= fmt.MAX_TIMESTAMP_NS for v in stamps):
                raise DecodeError(f"{where}: times {stamps} ns are not times a recording holds")
            sealer.note(fmt.TOPIC_STAMPS, int(t), data)
            out[int(t)] = stamps
        if self._seal is not None:
            sealed = tuple(self._seal.get(k) for k in fmt.SEAL_STAMPS_KEYS)
            found = sealer.stamps_seal() if out else (None, None)
            if sealed != found:
                raise DecodeError(
                    f"{name}: the {fmt.TOPIC_STAMPS} messages (each image's own time) do not "
                    f"match the seal (sealed {sealed[0] or 0}, found {len(out)}): they were "
                    "changed, added or removed"
                )
        self._stamps_read = out
        return out
