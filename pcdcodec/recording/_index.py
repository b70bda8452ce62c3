"""Finding messages in a ``.pcdc`` file: from MCAP's summary, or by scanning a damaged file.

A cleanly closed file ends with MCAP's summary, whose chunk indexes give every message's time,
channel and byte offset without reading the data. The summary is used only when its CRC (in
MCAP's footer) matches and what it says holds together (statistics, offsets, metadata records);
otherwise, and for a file whose writer died before writing one, every record is read from the
start. A scan stops at the first record that is cut short (an unfinished file) or damaged (a bad
CRC, an unknown record type, a record that does not parse), so every message that was completely
written before it is found, and says which of the two it was.

The settings a recording is read with (camera, depth scale, codecs, user metadata) live in MCAP
metadata records, which have no CRC of their own; each one carries a digest of its key/value
pairs instead (:func:`seal`, :func:`check_metadata`).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError

MAGIC = b"\x89MCAP0\r\n"
PROFILE = "pcdcodec"
#: The newest format version this pcdcodec reads and writes. Files that need nothing of a newer
#: version are written with the oldest one that holds them (see ``docs/format.md``).
FORMAT_VERSION = 2

TOPIC_COLOR = "/camera/color"
TOPIC_KEYFRAMES = "/camera/color/keyframes"
TOPIC_DEPTH = "/camera/depth"
TOPIC_CALIBRATION = "/camera/calibration"
TOPIC_COLOR_CALIBRATION = "/camera/color/calibration"  # a color camera apart from depth (v2)
TOPIC_EXTRINSICS = "/camera/extrinsics"  # where the color camera sits in the depth frame (v2)
TOPIC_POSE = "/camera/pose"  # camera-to-world pose per frame (FrameTransform)
TOPIC_POSE_MATRIX = "/camera/pose/matrix"  # the same pose, bit for bit: 16 float64 values
ENCODING_POSE_MATRIX = "pcdcodec.pose"  # 4 x 4 float64, row-major, little-endian, no schema

ENCODING_DEPTH = "pcdcodec.depth"  # one encoded depth frame (docs/format.md), no schema
ENCODING_COLOR = "pcdcodec.color"  # one raw codec packet, for codecs without a standard schema
ENCODING_KEYFRAME = "pcdcodec.keyframe"  # an empty marker at each keyframe's pts
#: One message per frame, the frame's last: digests of the color packets written since the
#: previous one, of the frame's depth message and of its pose messages (:data:`DIGEST_RECORD`).
TOPIC_FRAME_DIGEST = "/camera/frame_digest"
ENCODING_FRAME_DIGEST = "pcdcodec.frame_digest"

METADATA_NAME = "pcdcodec"
USER_METADATA_NAME = "user"
#: In every metadata record a writer makes: the digest of the record's other pairs (:func:`seal`).
DIGEST_KEY = "pcdcodec.digest"
#: In the ``pcdcodec`` record: JSON list of the other metadata records written with it.
RECORDS_KEY = "metadata_records"
#: In the ``pcdcodec`` record of files with color digests and a seal: their version, ``1``.
INTEGRITY_KEY = "integrity"
INTEGRITY_VERSION = 1
#: The metadata record written on close: what the file holds (:meth:`Sealer.seal`).
SEAL_NAME = "pcdcodec.seal"
#: The topics whose messages the seal counts and lists (other channels may come and go).
SEALED_TOPICS = (
    TOPIC_COLOR,
    TOPIC_KEYFRAMES,
    TOPIC_FRAME_DIGEST,
    TOPIC_DEPTH,
    TOPIC_CALIBRATION,
    TOPIC_COLOR_CALIBRATION,
    TOPIC_EXTRINSICS,
    TOPIC_POSE,
    TOPIC_POSE_MATRIX,
)

_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL = 0x01, 0x02, 0x03, 0x04
_OP_MESSAGE, _OP_CHUNK, _OP_MESSAGE_INDEX, _OP_CHUNK_INDEX = 0x05, 0x06, 0x07, 0x08
_OP_ATTACHMENT, _OP_ATTACHMENT_INDEX, _OP_STATISTICS = 0x09, 0x0A, 0x0B
_OP_METADATA, _OP_METADATA_INDEX, _OP_SUMMARY_OFFSET, _OP_DATA_END = 0x0C, 0x0D, 0x0E, 0x0F
#: Record types that may stand in the data section (anything else there is damage).
_DATA_OPCODES = {
    _OP_HEADER,
    _OP_SCHEMA,
    _OP_CHANNEL,
    _OP_MESSAGE,
    _OP_CHUNK,
    _OP_MESSAGE_INDEX,
    _OP_ATTACHMENT,
    _OP_METADATA,
    _OP_DATA_END,
}
_FOOTER = struct.Struct("<BQQQI")  # opcode, length (20), summary start, summary offsets, crc
_TAIL_SIZE = _FOOTER.size + len(MAGIC)


@dataclass
class ChannelInfo:
    id: int
    topic: str
    encoding: str
    metadata: dict[str, str]
    schema_name: str = ""


@dataclass
class FileIndex:
    """Where every message of a recording is, by channel, as numpy arrays."""

    profile: str = ""
    channels: dict[int, ChannelInfo] = field(default_factory=dict)
    #: schema id -> (name, encoding, data)
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    #: channel id -> schema id
    channel_schema: dict[int, int] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    #: per topic: (log times, chunk offsets) in file order
    times: dict[str, list[int]] = field(default_factory=dict)
    offsets: dict[str, list[int]] = field(default_factory=dict)
    #: metadata record name -> byte offset of the record
    metadata_offsets: dict[str, int] = field(default_factory=dict)
    #: True when the file ends with a summary that was used (closed cleanly, summary intact)
    indexed: bool = False
    #: where a scan stopped because the file ends inside a record (cut short), else None
    truncated_at: int | None = None
    #: where a scan stopped at a damaged record, and what was wrong there, else None
    damaged_at: int | None = None
    damage: str = ""
    #: why the file's summary was not used although the file has one (or ends as if it had)
    summary_problem: str | None = None
    #: a scan that reached the end of the data section: (CRC stored there, CRC of the bytes read)
    data_crc: tuple[int, int] | None = None
    #: messages a scan found twice (same channel and time); the first one is kept
    duplicates: int = 0
    #: chunks a scan passed over (``skip_damaged_chunks``): (byte offset, what was wrong)
    damaged_chunks: list[tuple[int, str]] = field(default_factory=list)
    #: size of the file in bytes
    size: int = 0
    #: message records a scan found outside chunks (an unchunked MCAP file; not indexed)
    loose_messages: int = 0

    def add(self, channel_id: int, log_time: int, offset: int) -> None:
        info = self.channels.get(channel_id)
        if info is None:
            return
        self.times.setdefault(info.topic, []).append(log_time)
        self.offsets.setdefault(info.topic, []).append(offset)

    def arrays(self, topic: str) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        times = np.asarray(self.times.get(topic, []), dtype=np.int64)
        offsets = np.asarray(self.offsets.get(topic, []), dtype=np.int64)
        return times, offsets

    def channel(self, topic: str) -> ChannelInfo | None:
        return next((c for c in self.channels.values() if c.topic == topic), None)


def _stream(data: bytes | memoryview) -> Any:
    from mcap.data_stream import ReadDataStream

    return ReadDataStream(io.BytesIO(data))


def file_size(f: IO[bytes]) -> int:
    try:
        return os.fstat(f.fileno()).st_size
    except (AttributeError, OSError, io.UnsupportedOperation):
        return f.seek(0, io.SEEK_END)


def read_at(f: IO[bytes], offset: int, length: int, size: int, *, what: str) -> bytes:
    """``length`` bytes at ``offset``, or a :class:`DecodeError` saying what was expected there."""
    if offset < 0 or length < 0 or offset + length > size:
        raise DecodeError(
            f"{what}: expected {length} bytes at byte offset {offset}, "
            f"but the file is {size} bytes long"
        )
    try:
        f.seek(offset)
        data = f.read(length)
    except (OSError, OverflowError, ValueError) as exc:
        raise DecodeError(f"{what}: cannot read byte offset {offset}: {exc}") from exc
    if len(data) != length:
        raise DecodeError(f"{what}: the file ends before byte offset {offset + length}")
    return data


def _chunk_messages(content: bytes, offset: int, what: str) -> tuple[list[Any], list[Any]]:
    """(messages, other records) of a chunk record's content; its CRC is always checked."""
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk

    try:
        chunk = Chunk.read(_stream(content))
        if chunk.compression == "":
            # MCAP skips the check when the stored CRC is 0; pcdcodec always writes one.
            crc = zlib.crc32(chunk.data)
            if crc != chunk.uncompressed_crc:
                raise DecodeError(
                    f"CRC-32 {chunk.uncompressed_crc:#010x} stored, {crc:#010x} computed"
                )
        # (checked above for uncompressed chunks; MCAP checks the others after decompressing)
        records = list(breakup_chunk(chunk, validate_crc=chunk.compression != ""))
    except DecodeError as exc:
        raise DecodeError(f"{what}: chunk at byte offset {offset} is corrupt ({exc})") from exc
    except Exception as exc:
        raise DecodeError(
            f"{what}: chunk at byte offset {offset} is corrupt ({type(exc).__name__}: {exc})"
        ) from exc
    messages = [r for r in records if isinstance(r, Message)]
    return messages, [r for r in records if not isinstance(r, Message)]


def read_chunk_messages(
    f: IO[bytes], offset: int, *, what: str, size: int | None = None
) -> list[Any]:
    """The Message records of the chunk at ``offset``, its CRC checked."""
    size = file_size(f) if size is None else size
    head = read_at(f, offset, 9, size, what=what)
    if head[0] != _OP_CHUNK:
        raise DecodeError(
            f"{what}: expected a chunk record at byte offset {offset}, found record type "
            f"{head[0]:#04x}"
        )
    (length,) = struct.unpack_from("<Q", head, 1)
    if offset + 9 + length > size:
        raise DecodeError(f"{what}: chunk at byte offset {offset} is cut short")
    content = read_at(f, offset + 9, length, size, what=what)
    return _chunk_messages(content, offset, what)[0]


def _channel_info(channel: Any, schemas: dict[int, str]) -> ChannelInfo:
    return ChannelInfo(
        channel.id,
        channel.topic,
        channel.message_encoding,
        dict(channel.metadata),
        schemas.get(channel.schema_id, ""),
    )


class _SummaryError(Exception):
    """The summary is there but cannot be trusted; the message says why."""


def load(f: IO[bytes]) -> FileIndex:
    """The index of a recording: from its summary when that is intact, else from a scan."""
    problem: str | None = None
    try:
        index = from_summary(f)
    except _SummaryError as exc:
        index, problem = None, str(exc)
    if index is not None:
        # A summary that disagrees with the seal (written last, in the data section) is not
        # used either: the scan then finds what the file really holds.
        try:
            disagree = seal_problems(index, "the summary")
        except DecodeError as exc:
            disagree = [str(exc)]
        if not disagree:
            return index
        problem = "it disagrees with the file's seal (" + "; ".join(disagree) + ")"
    index = scan(f)
    if problem is None and index.data_crc is not None:
        problem = "the data section ends, but no intact summary and footer follow it"
    index.summary_problem = problem
    return index


def _records(data: bytes, base: int) -> Iterator[tuple[int, int, bytes]]:
    """(offset, opcode, content) of the records packed in ``data`` (which starts at ``base``)."""
    pos = 0
    while pos < len(data):
        if pos + 9 > len(data):
            raise _SummaryError(f"a record at byte offset {base + pos} is cut short")
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        if pos + 9 + length > len(data):
            raise _SummaryError(f"the record at byte offset {base + pos} runs past the summary")
        yield base + pos, opcode, data[pos + 9 : pos + 9 + length]
        pos += 9 + length


def from_summary(f: IO[bytes]) -> FileIndex | None:
    """The index from MCAP's summary, or ``None`` when the file has none (not closed).

    Raises ``_SummaryError`` when a summary is there but its CRC or its contents do not hold up.
    """
    size = file_size(f)
    if size < 8 + 9 + _TAIL_SIZE:
        return None
    tail = read_at(f, size - _TAIL_SIZE, _TAIL_SIZE, size, what="footer")
    if tail[-8:] != MAGIC:
        return None  # no footer: the writer did not finish
    opcode, length, start, _offsets, crc = _FOOTER.unpack_from(tail)
    if opcode != _OP_FOOTER or length != 20:
        raise _SummaryError(f"the footer at byte offset {size - _TAIL_SIZE} is damaged")
    if start == 0:
        return None
    end = size - _TAIL_SIZE
    if not 8 + 9 <= start <= end:
        raise _SummaryError(f"the footer says the summary starts at byte offset {start}")
    summary = read_at(f, start, end - start, size, what="summary")
    computed = zlib.crc32(tail[: _FOOTER.size - 4], zlib.crc32(summary))
    if crc == 0 or computed != crc:
        raise _SummaryError(
            f"the summary at byte offset {start} fails its CRC "
            f"({crc:#010x} stored, {computed:#010x} computed)"
        )
    try:
        return _parse_summary(f, summary, start, size)
    except _SummaryError:
        raise
    except DecodeError as exc:
        raise _SummaryError(str(exc)) from exc
    except Exception as exc:
        raise _SummaryError(f"the summary does not parse ({type(exc).__name__}: {exc})") from exc


def _parse_summary(f: IO[bytes], summary: bytes, start: int, size: int) -> FileIndex:
    from mcap.records import (
        Channel,
        ChunkIndex,
        Header,
        Metadata,
        MetadataIndex,
        Schema,
        Statistics,
    )

    head = read_at(f, 8, 9, size, what="header")
    if head[0] != _OP_HEADER:
        raise _SummaryError("no header record at byte offset 8")
    (hlen,) = struct.unpack_from("<Q", head, 1)
    header = Header.read(_stream(read_at(f, 17, hlen, size, what="header")))
    index = FileIndex(profile=header.profile, indexed=True, size=size)
    schemas: dict[int, str] = {}
    chunk_indexes: list[Any] = []
    metadata_indexes: list[Any] = []
    statistics: Any = None
    for offset, opcode, content in _records(summary, start):
        stream = _stream(content)
        if opcode == _OP_SCHEMA:
            schema = Schema.read(stream)
            schemas[schema.id] = schema.name
            index.schemas[schema.id] = (schema.name, schema.encoding, bytes(schema.data))
        elif opcode == _OP_CHANNEL:
            channel = Channel.read(stream)
            index.channels[channel.id] = _channel_info(channel, schemas)
            index.channel_schema[channel.id] = channel.schema_id
        elif opcode == _OP_CHUNK_INDEX:
            chunk_indexes.append(ChunkIndex.read(stream))
        elif opcode == _OP_METADATA_INDEX:
            metadata_indexes.append(MetadataIndex.read(stream))
        elif opcode == _OP_STATISTICS:
            statistics = Statistics.read(stream)
        elif opcode not in (_OP_ATTACHMENT_INDEX, _OP_SUMMARY_OFFSET):
            raise _SummaryError(f"unexpected record type {opcode:#04x} at byte offset {offset}")
    for mi in metadata_indexes:
        record = read_at(f, mi.offset, mi.length, size, what=f"metadata {mi.name!r}")
        if mi.length < 9 or record[0] != _OP_METADATA:
            raise _SummaryError(f"no metadata record at byte offset {mi.offset}")
        meta = Metadata.read(_stream(record[9:]))
        if meta.name != mi.name:
            raise _SummaryError(
                f"the metadata record at byte offset {mi.offset} is named {meta.name!r}, "
                f"the summary says {mi.name!r}"
            )
        index.metadata[meta.name] = dict(meta.metadata)
        index.metadata_offsets[meta.name] = mi.offset
    counts: dict[int, int] = {}
    previous_end = 8
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        if ci.chunk_start_offset < previous_end or ci.chunk_start_offset + ci.chunk_length > start:
            raise _SummaryError(
                f"a chunk index points at bytes {ci.chunk_start_offset}-"
                f"{ci.chunk_start_offset + ci.chunk_length}, outside the data section or "
                "overlapping another chunk"
            )
        previous_end = ci.chunk_start_offset + ci.chunk_length
        ids = list(ci.message_index_offsets)
        if len(ids) == 1 and ci.message_start_time == ci.message_end_time and _single(ci):
            index.add(ids[0], ci.message_start_time, ci.chunk_start_offset)
            counts[ids[0]] = counts.get(ids[0], 0) + 1
            continue
        # A chunk with several messages: read them from the chunk itself.
        for message in read_chunk_messages(f, ci.chunk_start_offset, what="index", size=size):
            index.add(message.channel_id, message.log_time, ci.chunk_start_offset)
            counts[message.channel_id] = counts.get(message.channel_id, 0) + 1
    if statistics is None and index.channels:
        # Without statistics nothing says whether every message is in an indexed chunk.
        raise _SummaryError("it has no statistics record to check its chunk indexes against")
    unknown = set(counts) - set(index.channels)
    if unknown:
        raise _SummaryError(f"chunks hold messages of channels {sorted(unknown)} it does not list")
    if statistics is not None:
        stated = {cid: n for cid, n in statistics.channel_message_counts.items() if n}
        if (
            stated != counts
            or statistics.message_count != sum(counts.values())
            or statistics.chunk_count != len(chunk_indexes)
            or statistics.channel_count != len(index.channels)
            or statistics.metadata_count != len(metadata_indexes)
        ):
            raise _SummaryError(
                f"its statistics ({statistics.message_count} messages, per channel {stated}) "
                f"disagree with its chunk indexes ({sum(counts.values())} messages, per "
                f"channel {counts})"
            )
    return index


def _single(ci: Any) -> bool:
    """Whether a chunk holds exactly one message, judged by the size of its message index."""
    # One message index record with one entry: opcode, length, channel id, count, 16 bytes.
    return bool(ci.message_index_length == 1 + 8 + 2 + 4 + 16)


def scan(f: IO[bytes], *, skip_damaged_chunks: bool = False) -> FileIndex:
    """Read every record from the start of the file, checking every CRC on the way.

    Stops at the end of the data section, at a record the file ends inside of
    (``truncated_at``) or at a damaged record (``damaged_at`` and ``damage``). With
    ``skip_damaged_chunks``, a chunk that fails its CRC is listed in ``damaged_chunks`` and
    passed over instead (its messages are missing from the index).
    """
    from mcap.records import Channel, DataEnd, Header, Metadata, Schema

    size = file_size(f)
    if read_at(f, 0, min(8, size), size, what="start") != MAGIC:
        raise DecodeError("not an MCAP file: it does not start with the MCAP magic bytes")
    index = FileIndex(size=size)
    schemas: dict[int, str] = {}
    seen: set[tuple[int, int]] = set()
    crc = zlib.crc32(MAGIC)
    pos = 8
    f.seek(pos)
    while True:
        head = f.read(9)
        if len(head) < 9:
            index.truncated_at = pos if head else None
            break
        opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
        if opcode not in _DATA_OPCODES:
            index.damaged_at, index.damage = pos, f"unknown record type {opcode:#04x}"
            break
        if pos + 9 + length > size:
            index.truncated_at = pos
            break
        content = f.read(length)
        try:
            if opcode == _OP_CHUNK:
                try:
                    messages, others = _chunk_messages(content, pos, "scan")
                except DecodeError as exc:
                    if not skip_damaged_chunks:
                        raise
                    index.damaged_chunks.append((pos, str(exc)))
                    messages, others = [], []
                # Channels and schemas may sit inside the chunk too.
                for record in others:
                    if isinstance(record, Schema):
                        schemas[record.id] = record.name
                        index.schemas[record.id] = (
                            record.name,
                            record.encoding,
                            bytes(record.data),
                        )
                    elif isinstance(record, Channel):
                        index.channels[record.id] = _channel_info(record, schemas)
                        index.channel_schema[record.id] = record.schema_id
                for message in messages:
                    key = (message.channel_id, message.log_time)
                    if key in seen:
                        index.duplicates += 1
                        continue
                    seen.add(key)
                    index.add(message.channel_id, message.log_time, pos)
            elif opcode == _OP_MESSAGE:
                index.loose_messages += 1  # no CRC of its own: such files are refused
            elif opcode == _OP_DATA_END:
                stored = DataEnd.read(_stream(content)).data_section_crc
                index.data_crc = (stored, crc)
                break
            elif opcode == _OP_HEADER:
                if pos != 8:
                    raise DecodeError("a second header record")
                index.profile = Header.read(_stream(content)).profile
            elif opcode == _OP_SCHEMA:
                schema = Schema.read(_stream(content))
                schemas[schema.id] = schema.name
                index.schemas[schema.id] = (schema.name, schema.encoding, bytes(schema.data))
            elif opcode == _OP_CHANNEL:
                channel = Channel.read(_stream(content))
                index.channels[channel.id] = _channel_info(channel, schemas)
                index.channel_schema[channel.id] = channel.schema_id
            elif opcode == _OP_METADATA:
                meta = Metadata.read(_stream(content))
                index.metadata[meta.name] = dict(meta.metadata)
                index.metadata_offsets[meta.name] = pos
        except Exception as exc:
            text = str(exc) if isinstance(exc, DecodeError) else f"{type(exc).__name__}: {exc}"
            index.damaged_at, index.damage = pos, f"a damaged record ({text})"
            break
        crc = zlib.crc32(content, zlib.crc32(head, crc))
        pos += 9 + length
    return index


# -- the file's own settings --------------------------------------------------------------------


def digest(name: str, data: dict[str, str]) -> str:
    """The digest of a metadata record: SHA-256 of its name and sorted pairs, as JSON."""
    pairs = sorted([k, v] for k, v in data.items() if k != DIGEST_KEY)
    text = json.dumps([name, pairs], separators=(",", ":"))
    return "sha256:" + hashlib.sha256(text.encode("ascii")).hexdigest()


def seal(name: str, data: dict[str, str]) -> dict[str, str]:
    """``data`` with its digest added, as a writer stores every metadata record."""
    return {**data, DIGEST_KEY: digest(name, data)}


def check_metadata(index: FileIndex, what: str) -> None:
    """Check the digest of every metadata record of a recording that was written with them.

    Files whose ``pcdcodec`` record has no digest were written before digests existed and are
    read as they are. Raises :class:`DecodeError` naming the record and its byte offset.
    """
    main = index.metadata.get(METADATA_NAME)
    if main is None or DIGEST_KEY not in main:
        return
    for name, data in index.metadata.items():
        offset = index.metadata_offsets.get(name)
        if DIGEST_KEY not in data:
            if name == METADATA_NAME:
                continue
            listed = name in _listed(main, what)
            if listed:
                raise DecodeError(
                    f"{what}: metadata record {name!r} at byte offset {offset} has no digest"
                )
            continue  # a record some other tool added: pcdcodec does not read it
        if data[DIGEST_KEY] != digest(name, data):
            raise DecodeError(
                f"{what}: metadata record {name!r} at byte offset {offset} does not match its "
                "digest: the recording's settings were changed or damaged"
            )
    missing = [name for name in _listed(main, what) if name not in index.metadata]
    if missing:
        raise DecodeError(f"{what}: metadata record(s) {missing} are missing")


def _listed(main: dict[str, str], what: str) -> list[str]:
    try:
        names = json.loads(main.get(RECORDS_KEY, "[]"))
    except ValueError:
        names = None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise DecodeError(f"{what}: {RECORDS_KEY!r} is not a list of record names")
    return names


# -- color digests and the seal ----------------------------------------------------------------

#: What a color packet adds to its group's digest: pts, dts (as stored), keyframe flag, length.
_PACKET_FIELDS = struct.Struct("<QQBQ")
#: A ``/camera/frame_digest`` message: the number of color packets in the frame's group and
#: their SHA-256, the SHA-256 of the depth message's data, and the SHA-256 of the pose and pose
#: matrix messages' data (32 zero bytes for a frame without a pose).
DIGEST_RECORD = struct.Struct("<I32s32s32s")
NO_POSE = bytes(32)


def data_digest(*parts: bytes | memoryview) -> bytes:
    """SHA-256 of the message data ``parts`` one after another."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    return h.digest()


class Sealer:
    """Follows the messages of a recording in file order and makes its integrity records.

    A writer calls :meth:`note` for every message it writes and :meth:`packet` for every color
    packet; :meth:`group` closes the group of packets of one frame (for its digest message) and
    :meth:`seal` makes the seal record. A reader uses the same methods to recompute them.
    """

    def __init__(self) -> None:
        self._structure = hashlib.sha256()
        self.counts: dict[str, int] = {}
        self.first: int | None = None
        self.last: int | None = None
        self._group = hashlib.sha256()
        self._group_count = 0

    def note(self, topic: str, log_time: int) -> None:
        """A message on ``topic`` at ``log_time`` (ns), the next one in the file."""
        if topic not in SEALED_TOPICS:
            return
        self._structure.update(f"{topic} {log_time}\n".encode())
        self.counts[topic] = self.counts.get(topic, 0) + 1
        if topic == TOPIC_DEPTH:
            self.first = log_time if self.first is None else self.first
            self.last = log_time

    def packet(self, pts: int, dts: int, keyframe: bool, data: bytes | memoryview) -> None:
        """A color packet: its message's log time, publish time and data, as stored."""
        self._group.update(_PACKET_FIELDS.pack(pts, dts, int(keyframe), len(data)))
        self._group.update(data)
        self._group_count += 1

    def group(self) -> tuple[int, bytes]:
        """The number and SHA-256 of the packets since the last call; starts a new group."""
        out = self._group_count, self._group.digest()
        self._group, self._group_count = hashlib.sha256(), 0
        return out

    def frame_record(self, depth: bytes | memoryview, pose: bytes = NO_POSE) -> bytes:
        """The data of a frame's digest message: :meth:`group`, the depth message's data and
        the digest of its pose messages' data (:func:`data_digest`)."""
        count, color = self.group()
        return DIGEST_RECORD.pack(count, color, data_digest(depth), pose)

    def seal(self) -> dict[str, str]:
        """The seal record (before its own digest is added by :func:`seal`)."""
        count, digest_ = self.group()
        return {
            **self.summary(),
            "tail_packets": str(count),
            "tail_digest": "sha256:" + digest_.hex(),
        }

    def summary(self) -> dict[str, str]:
        """The part of the seal that an index alone can be checked against."""
        return {
            "frames": str(self.counts.get(TOPIC_DEPTH, 0)),
            "messages": json.dumps(dict(sorted(self.counts.items())), separators=(",", ":")),
            "first_timestamp": "" if self.first is None else str(self.first),
            "last_timestamp": "" if self.last is None else str(self.last),
            "structure": "sha256:" + self._structure.hexdigest(),
        }


def structure_of(index: FileIndex) -> Sealer:
    """A :class:`Sealer` that has noted the messages of ``index`` in file order."""
    entries = [
        (offset, k, topic, t)
        for topic in SEALED_TOPICS
        for k, (t, offset) in enumerate(
            zip(index.times.get(topic, []), index.offsets.get(topic, []), strict=True)
        )
    ]
    # One message per chunk in files pcdcodec writes; within a chunk, the index keeps order.
    entries.sort(key=lambda e: (e[0], e[1]))
    sealer = Sealer()
    for _, _, topic, t in entries:
        sealer.note(topic, t)
    return sealer


def integrity_version(index: FileIndex, what: str) -> int:
    """The ``integrity`` of the file's ``pcdcodec`` record, 0 for files written without it."""
    text = index.metadata.get(METADATA_NAME, {}).get(INTEGRITY_KEY)
    if text is None:
        return 0
    try:
        version = int(text)
        if version < 1:
            raise ValueError
    except ValueError:
        raise DecodeError(
            f"{what}: {INTEGRITY_KEY!r} is {text!r}, expected a positive int"
        ) from None
    return version


def seal_problems(index: FileIndex, what: str) -> list[str]:
    """How the messages of ``index`` differ from the file's seal (empty when they agree).

    Raises :class:`DecodeError` when a file written with integrity records lacks a seal
    although it was closed (it has a usable summary, or its data section ends), or its seal
    has no digest. A file without a seal that was not closed (its writer died) has none.
    """
    if not integrity_version(index, what):
        return []
    seal_ = index.metadata.get(SEAL_NAME)
    if seal_ is None:
        if index.indexed or index.data_crc is not None:
            raise DecodeError(
                f"{what}: the file was closed, but its seal record {SEAL_NAME!r} is missing"
            )
        return []
    if DIGEST_KEY not in seal_:
        raise DecodeError(f"{what}: the seal record {SEAL_NAME!r} has no digest")
    found = structure_of(index).summary()
    labels = {
        "frames": "frames",
        "messages": "messages per channel",
        "first_timestamp": "first frame time (ns)",
        "last_timestamp": "last frame time (ns)",
        "structure": "",
    }
    return [
        f"{label}: sealed {seal_.get(key)!r}, found {found[key]!r}"
        if key != "structure"
        else "the messages are not those sealed, or not in the sealed order"
        for key, label in labels.items()
        if seal_.get(key) != found[key]
    ]
