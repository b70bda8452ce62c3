"""Finding messages in an MCAP file: from its summary, or by scanning a damaged file.

A cleanly closed file ends with MCAP's summary, whose chunk indexes give every message's time,
channel and byte offset without reading the data. The summary is used only when its CRC (in
MCAP's footer) matches and what it says holds together (statistics, offsets, metadata records);
otherwise, and for a file whose writer died before writing one, every record is read from the
start. A scan stops at the first record that is cut short (an unfinished file) or damaged (a bad
CRC, an unknown record type, a record that does not parse), so every message that was completely
written before it is found, and says which of the two it was.

Nothing here knows what a recording holds; :mod:`pcdcodec.recording._index` names that.
"""

from __future__ import annotations

import io
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
    #: messages a scan found twice (same channel and time), by topic; the first one is kept
    duplicates: dict[str, int] = field(default_factory=dict)
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
        # The record's length must be that of its fields: a damaged length would move the
        # next record.
        fields = _CHUNK_HEAD.size + len(chunk.compression.encode()) + 8 + len(chunk.data)
        if fields != len(content):
            raise DecodeError(
                f"the record is {len(content)} bytes long, its fields take {fields} bytes"
            )
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


class SummaryError(Exception):
    """The summary is there but cannot be trusted; the message says why."""


def _records(data: bytes, base: int) -> Iterator[tuple[int, int, bytes]]:
    """(offset, opcode, content) of the records packed in ``data`` (which starts at ``base``)."""
    pos = 0
    while pos < len(data):
        if pos + 9 > len(data):
            raise SummaryError(f"a record at byte offset {base + pos} is cut short")
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        if pos + 9 + length > len(data):
            raise SummaryError(f"the record at byte offset {base + pos} runs past the summary")
        yield base + pos, opcode, data[pos + 9 : pos + 9 + length]
        pos += 9 + length


def from_summary(f: IO[bytes]) -> FileIndex | None:
    """The index from MCAP's summary, or ``None`` when the file has none (not closed).

    Raises ``SummaryError`` when a summary is there but its CRC or its contents do not hold up.
    """
    size = file_size(f)
    if size < 8 + 9 + _TAIL_SIZE:
        return None
    tail = read_at(f, size - _TAIL_SIZE, _TAIL_SIZE, size, what="footer")
    if tail[-8:] != MAGIC:
        return None  # no footer: the writer did not finish
    opcode, length, start, _offsets, crc = _FOOTER.unpack_from(tail)
    if opcode != _OP_FOOTER or length != 20:
        raise SummaryError(f"the footer at byte offset {size - _TAIL_SIZE} is damaged")
    if start == 0:
        return None
    end = size - _TAIL_SIZE
    if not 8 + 9 <= start <= end:
        raise SummaryError(f"the footer says the summary starts at byte offset {start}")
    summary = read_at(f, start, end - start, size, what="summary")
    computed = zlib.crc32(tail[: _FOOTER.size - 4], zlib.crc32(summary))
    if crc == 0 or computed != crc:
        raise SummaryError(
            f"the summary at byte offset {start} fails its CRC "
            f"({crc:#010x} stored, {computed:#010x} computed)"
        )
    try:
        return _parse_summary(f, summary, start, size)
    except SummaryError:
        raise
    except DecodeError as exc:
        raise SummaryError(str(exc)) from exc
    except Exception as exc:
        raise SummaryError(f"the summary does not parse ({type(exc).__name__}: {exc})") from exc


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
        raise SummaryError("no header record at byte offset 8")
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
            raise SummaryError(f"unexpected record type {opcode:#04x} at byte offset {offset}")
    for mi in metadata_indexes:
        record = read_at(f, mi.offset, mi.length, size, what=f"metadata {mi.name!r}")
        if mi.length < 9 or record[0] != _OP_METADATA:
            raise SummaryError(f"no metadata record at byte offset {mi.offset}")
        meta = Metadata.read(_stream(record[9:]))
        if meta.name != mi.name:
            raise SummaryError(
                f"the metadata record at byte offset {mi.offset} is named {meta.name!r}, "
                f"the summary says {mi.name!r}"
            )
        index.metadata[meta.name] = dict(meta.metadata)
        index.metadata_offsets[meta.name] = mi.offset
    counts: dict[int, int] = {}
    previous_end = 8
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        if ci.chunk_start_offset < previous_end or ci.chunk_start_offset + ci.chunk_length > start:
            raise SummaryError(
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
        # A chunk with several messages (kept topics): read them from the chunk itself, or,
        # when it is damaged, from its message indexes (its messages are then found missing
        # where they are read, by the chunk's CRC, and not at opening).
        try:
            found = [
                (m.channel_id, m.log_time)
                for m in read_chunk_messages(f, ci.chunk_start_offset, what="index", size=size)
            ]
        except DecodeError:
            found = _message_indexes(f, ci, size)
        for channel_id, log_time in found:
            index.add(channel_id, log_time, ci.chunk_start_offset)
            counts[channel_id] = counts.get(channel_id, 0) + 1
    if statistics is None and index.channels:
        # Without statistics nothing says whether every message is in an indexed chunk.
        raise SummaryError("it has no statistics record to check its chunk indexes against")
    unknown = set(counts) - set(index.channels)
    if unknown:
        raise SummaryError(f"chunks hold messages of channels {sorted(unknown)} it does not list")
    if statistics is not None:
        stated = {cid: n for cid, n in statistics.channel_message_counts.items() if n}
        if (
            stated != counts
            or statistics.message_count != sum(counts.values())
            or statistics.chunk_count != len(chunk_indexes)
            or statistics.channel_count != len(index.channels)
            or statistics.metadata_count != len(metadata_indexes)
        ):
            raise SummaryError(
                f"its statistics ({statistics.message_count} messages, per channel {stated}) "
                f"disagree with its chunk indexes ({sum(counts.values())} messages, per "
                f"channel {counts})"
            )
    return index


def _message_indexes(f: IO[bytes], ci: Any, size: int) -> list[tuple[int, int]]:
    """(channel id, log time) of a chunk's messages in chunk order, from the message index
    records after it (which its chunk index points at)."""
    from mcap.records import MessageIndex

    if not ci.message_index_offsets:
        return []
    start = min(ci.message_index_offsets.values())
    data = read_at(f, start, ci.message_index_length, size, what="message index")
    entries = []
    for _, opcode, content in _records(data, start):
        if opcode != _OP_MESSAGE_INDEX:
            raise SummaryError(f"no message index record where chunk index {start} points")
        record = MessageIndex.read(_stream(content))
        entries += [(at, record.channel_id, t) for t, at in record.records]
    return [(cid, t) for _, cid, t in sorted(entries)]


def _kept_channel(index: FileIndex, channel_id: int) -> bool:
    info = index.channels.get(channel_id)
    # (the key of pcdcodec.ros.kept.KEPT_KEY, not imported: `import pcdcodec` stays light)
    return info is not None and info.metadata.get("pcdcodec.kept") == "1"


def _single(ci: Any) -> bool:
    """Whether a chunk holds exactly one message, judged by the size of its message index."""
    # One message index record with one entry: opcode, length, channel id, count, 16 bytes.
    return bool(ci.message_index_length == 1 + 8 + 2 + 4 + 16)


def scan(f: IO[bytes], *, skip_damaged_chunks: bool = False, resync: bool = False) -> FileIndex:
    """Read every record from the start of the file, checking every CRC on the way.

    Stops at the end of the data section, at a record the file ends inside of
    (``truncated_at``) or at a damaged record (``damaged_at`` and ``damage``). With
    ``skip_damaged_chunks``, a chunk that fails its CRC is listed in ``damaged_chunks`` and
    passed over instead (its messages are missing from the index). With ``resync`` (which
    implies it), a damaged record, or one whose length runs past the end of the file, is
    passed over too: reading goes on at the next chunk whose CRC holds, and the bytes passed
    over are listed in ``damaged_chunks``; only when no such chunk follows does the scan stop.
    """
    skip_damaged_chunks = skip_damaged_chunks or resync
    from mcap.records import Channel, DataEnd, Header, Metadata, Schema

    size = file_size(f)
    if read_at(f, 0, min(8, size), size, what="start") != MAGIC:
        raise DecodeError("not an MCAP file: it does not start with the MCAP magic bytes")
    index = FileIndex(size=size)
    schemas: dict[int, str] = {}
    seen: set[tuple[int, int]] = set()
    crc = zlib.crc32(MAGIC)
    # Where the last chunk whose CRC held ends: a record after it with a damaged length may
    # have made the scan step over good chunks, so a resync searches from here.
    anchor = 8
    pos = 8
    f.seek(pos)
    while True:
        head = f.read(9)
        if len(head) < 9:
            index.truncated_at = pos if head else None
            break
        opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
        problem = ""
        if opcode not in _DATA_OPCODES:
            problem = f"unknown record type {opcode:#04x}"
        elif pos + 9 + length > size:
            problem = "cut short"
        elif resync and opcode != _OP_CHUNK and length > _MAX_OTHER_RECORD:
            problem = f"a record of type {opcode:#04x} claims {length} bytes"
        if problem and resync:
            found = _next_chunk(f, max(anchor, 9), size)
            if found is not None:
                anchor = found + 1
                index.damaged_chunks.append(
                    (
                        pos,
                        f"a damaged record at byte offset {pos} ({problem}): reading goes on "
                        f"at the next whole chunk, at byte offset {found}",
                    )
                )
                pos = found
                f.seek(pos)
                continue
        if problem == "cut short":
            index.truncated_at = pos
            break
        if problem:
            index.damaged_at, index.damage = pos, problem
            break
        content = f.read(length)
        try:
            if opcode == _OP_CHUNK:
                try:
                    messages, others = _chunk_messages(content, pos, "scan")
                    anchor = pos + 9 + length
                except DecodeError as exc:
                    if not skip_damaged_chunks:
                        raise
                    if all(pos != at for at, _ in index.damaged_chunks):
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
                    if _kept_channel(index, message.channel_id):
                        pass  # a kept topic may log two messages at one time
                    elif key in seen:
                        info = index.channels.get(message.channel_id)
                        topic = info.topic if info is not None else f"channel {key[0]}"
                        index.duplicates[topic] = index.duplicates.get(topic, 0) + 1
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
            found = _next_chunk(f, max(anchor, 9), size) if resync else None
            if found is None:
                index.damaged_at, index.damage = pos, f"a damaged record ({text})"
                break
            anchor = found + 1
            index.damaged_chunks.append((pos, f"a damaged record ({text}); passed over"))
            pos = found
            f.seek(pos)
            continue
        crc = zlib.crc32(content, zlib.crc32(head, crc))
        pos += 9 + length
        f.seek(pos)
    return index


#: Records other than chunks that pcdcodec writes are small; a longer one is damage (resync).
_MAX_OTHER_RECORD = 16 << 20
#: A chunk record's fixed fields: start and end time, uncompressed size, CRC, and the length of
#: its compression name.
_CHUNK_HEAD = struct.Struct("<QQQII")
_SEARCH_BLOCK = 1 << 20


def _next_chunk(f: IO[bytes], start: int, size: int) -> int | None:
    """The byte offset of the first chunk record at or after ``start`` whose fields hold
    together and whose CRC matches, or ``None``."""
    pos = start
    while pos < size:
        f.seek(pos)
        block = f.read(_SEARCH_BLOCK + 64)
        k = block.find(b"\x06")
        while 0 <= k < min(len(block), _SEARCH_BLOCK):
            if _is_chunk(f, pos + k, block[k:], size):
                return pos + k
            k = block.find(b"\x06", k + 1)
        pos += _SEARCH_BLOCK
    return None


def _is_chunk(f: IO[bytes], at: int, head: bytes, size: int) -> bool:
    if len(head) < 9 + _CHUNK_HEAD.size:
        return False
    (length,) = struct.unpack_from("<Q", head, 1)
    start, end, _raw, _crc, name_len = _CHUNK_HEAD.unpack_from(head, 9)
    if at + 9 + length > size or start > end or name_len > 16:
        return False
    fixed = _CHUNK_HEAD.size + name_len + 8
    if len(head) < 9 + fixed or length < fixed:
        return False
    (records,) = struct.unpack_from("<Q", head, 9 + _CHUNK_HEAD.size + name_len)
    if records != length - fixed:
        return False
    f.seek(at + 9)
    try:
        _chunk_messages(f.read(length), at, "scan")
    except DecodeError:
        return False
    return True
