"""Finding messages in a ``.pcdc`` file: from MCAP's summary, or by scanning a damaged file.

A cleanly closed file ends with MCAP's summary, whose chunk indexes give every message's time,
channel and byte offset without reading the data. A file whose writer died has no summary;
then every complete record is read from the start, and the scan stops at the first record that
was cut short, so every message that was completely written is found.
"""

from __future__ import annotations

import io
import struct
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

ENCODING_DEPTH = "pcdcodec.depth"  # one encoded depth frame (docs/format.md), no schema
ENCODING_COLOR = "pcdcodec.color"  # one raw codec packet, for codecs without a standard schema
ENCODING_KEYFRAME = "pcdcodec.keyframe"  # an empty marker at each keyframe's pts

METADATA_NAME = "pcdcodec"
USER_METADATA_NAME = "user"

_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL = 0x01, 0x02, 0x03, 0x04
_OP_MESSAGE, _OP_CHUNK, _OP_METADATA, _OP_DATA_END = 0x05, 0x06, 0x0C, 0x0F


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
    #: True when the file ends with a summary (closed cleanly)
    indexed: bool = False
    #: where a scan stopped, when it stopped early (damaged tail), else None
    truncated_at: int | None = None

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


def _stream(data: bytes) -> Any:
    from mcap.data_stream import ReadDataStream

    return ReadDataStream(io.BytesIO(data))


def read_chunk_messages(f: IO[bytes], offset: int, *, what: str) -> list[Any]:
    """The Message records of the chunk at ``offset``, its CRC checked."""
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk

    f.seek(offset)
    head = f.read(9)
    if len(head) < 9 or head[0] != _OP_CHUNK:
        raise DecodeError(f"{what}: no chunk record at byte offset {offset}")
    (length,) = struct.unpack_from("<Q", head, 1)
    content = f.read(length)
    if len(content) < length:
        raise DecodeError(f"{what}: chunk at byte offset {offset} is cut short")
    try:
        chunk = Chunk.read(_stream(content))
        records = breakup_chunk(chunk, validate_crc=True)
    except Exception as exc:
        raise DecodeError(
            f"{what}: chunk at byte offset {offset} is corrupt ({type(exc).__name__}: {exc})"
        ) from exc
    return [r for r in records if isinstance(r, Message)]


def _channel_info(channel: Any, schemas: dict[int, str]) -> ChannelInfo:
    return ChannelInfo(
        channel.id,
        channel.topic,
        channel.message_encoding,
        dict(channel.metadata),
        schemas.get(channel.schema_id, ""),
    )


def from_summary(f: IO[bytes]) -> FileIndex | None:
    """The index from MCAP's summary, or ``None`` when the file has none (not closed)."""
    from mcap.reader import SeekingReader

    try:
        reader = SeekingReader(f)
        summary = reader.get_summary()
        header = reader.get_header()
    except Exception:
        return None
    if summary is None:
        return None
    index = FileIndex(profile=header.profile, indexed=True)
    schemas = {sid: s.name for sid, s in summary.schemas.items()}
    index.schemas = {sid: (s.name, s.encoding, bytes(s.data)) for sid, s in summary.schemas.items()}
    for cid, channel in summary.channels.items():
        index.channels[cid] = _channel_info(channel, schemas)
        index.channel_schema[cid] = channel.schema_id
    for meta in reader.iter_metadata():
        index.metadata[meta.name] = dict(meta.metadata)
    for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        ids = list(ci.message_index_offsets)
        if len(ids) == 1 and ci.message_start_time == ci.message_end_time and _single(ci):
            index.add(ids[0], ci.message_start_time, ci.chunk_start_offset)
            continue
        # A chunk with several messages: its message index records list them.
        for message in read_chunk_messages(f, ci.chunk_start_offset, what="index"):
            index.add(message.channel_id, message.log_time, ci.chunk_start_offset)
    return index


def _single(ci: Any) -> bool:
    """Whether a chunk holds exactly one message, judged by the size of its message index."""
    # One message index record with one entry: opcode, length, channel id, count, 16 bytes.
    return bool(ci.message_index_length == 1 + 8 + 2 + 4 + 16)


def scan(f: IO[bytes]) -> FileIndex:
    """Read every complete record from the start of the file (for files without a summary)."""
    from mcap.records import Channel, Header, Metadata, Schema

    f.seek(0, io.SEEK_END)
    size = f.tell()
    f.seek(0)
    if f.read(8) != MAGIC:
        raise DecodeError("not an MCAP file: it does not start with the MCAP magic bytes")
    index = FileIndex()
    schemas: dict[int, str] = {}
    pos = 8
    while True:
        head = f.read(9)
        if len(head) < 9:
            index.truncated_at = pos if head else None
            break
        opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
        if pos + 9 + length > size:
            index.truncated_at = pos
            break
        if opcode == _OP_CHUNK:
            try:
                messages = read_chunk_messages(f, pos, what="scan")
            except DecodeError:
                index.truncated_at = pos
                break
            # Channels and schemas may sit inside the chunk too.
            f.seek(pos + 9)
            content = f.read(length)
            for record in _chunk_records(content):
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                    index.schemas[record.id] = (record.name, record.encoding, bytes(record.data))
                elif isinstance(record, Channel):
                    index.channels[record.id] = _channel_info(record, schemas)
                    index.channel_schema[record.id] = record.schema_id
            for message in messages:
                index.add(message.channel_id, message.log_time, pos)
        elif opcode in (_OP_FOOTER, _OP_DATA_END):
            break
        else:
            content = f.read(length)
            if opcode == _OP_HEADER:
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
        pos += 9 + length
        f.seek(pos)
    return index


def _chunk_records(content: bytes) -> list[Any]:
    from mcap.records import Chunk
    from mcap.stream_reader import breakup_chunk

    return list(breakup_chunk(Chunk.read(_stream(content)), validate_crc=False))
