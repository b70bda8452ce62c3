"""Rewriting a recording message by message with the ``mcap`` library: files whose CRCs,
offsets and summary are all consistent, whatever their messages now hold, and files as pcdcodec
wrote them before frame digests and seals. For tests, fuzzers and benchmarks of the container's
checks (``benchmarks/integrity_cost.py``); nothing else in pcdcodec imports it.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO


@dataclass(frozen=True)
class Message:
    topic: str
    log_time: int
    publish_time: int
    sequence: int
    data: bytes


@dataclass
class Contents:
    """What a recording's data section holds, in file order."""

    profile: str
    library: str
    metadata: list[tuple[str, dict[str, str]]]
    #: channel topic -> (encoding, metadata, schema (name, encoding, data) or None)
    channels: dict[str, tuple[str, dict[str, str], tuple[str, str, bytes] | None]]
    messages: list[Message]


def read(path: Path | IO[bytes]) -> Contents:
    """Every record of the data section of ``path`` (chunks opened), in file order."""
    from mcap.records import Channel, DataEnd, Header, Metadata, Schema
    from mcap.records import Message as McapMessage
    from mcap.stream_reader import StreamReader

    schemas: dict[int, tuple[str, str, bytes]] = {}
    channels: dict[int, Channel] = {}
    out = Contents("", "", [], {}, [])
    with path.open("rb") if isinstance(path, Path) else nullcontext(path) as f:
        for record in StreamReader(f, emit_chunks=False).records:
            if isinstance(record, Header):
                out.profile, out.library = record.profile, record.library
            elif isinstance(record, Metadata):
                out.metadata.append((record.name, dict(record.metadata)))
            elif isinstance(record, Schema):
                schemas[record.id] = (record.name, record.encoding, bytes(record.data))
            elif isinstance(record, Channel):
                channels[record.id] = record
                out.channels[record.topic] = (
                    record.message_encoding,
                    dict(record.metadata),
                    schemas.get(record.schema_id),
                )
            elif isinstance(record, McapMessage):
                ch = channels[record.channel_id]
                out.messages.append(
                    Message(
                        ch.topic,
                        record.log_time,
                        record.publish_time,
                        record.sequence,
                        bytes(record.data),
                    )
                )
            elif isinstance(record, DataEnd):
                break
    return out


def write(contents: Contents, path: Path | IO[bytes], *, chunked: bool = True) -> None:
    """Write ``contents`` as a complete MCAP file: CRCs, data end and summary all consistent.

    ``chunked`` writes each message in a chunk of its own, as pcdcodec does; otherwise the
    messages stand in the data section without chunks (a valid MCAP file too).
    """
    from mcap.writer import CompressionType, Writer

    with path.open("wb") if isinstance(path, Path) else nullcontext(path) as f:
        writer = Writer(
            f,
            chunk_size=0,
            compression=CompressionType.NONE,
            use_chunking=chunked,
            enable_data_crcs=True,
        )
        writer.start(profile=contents.profile, library=contents.library)
        for name, data in contents.metadata:
            writer.add_metadata(name, data)
        schema_ids: dict[tuple[str, str, bytes], int] = {}
        channel_ids: dict[str, int] = {}
        for topic, (encoding, meta, schema) in contents.channels.items():
            sid = 0
            if schema is not None:
                if schema not in schema_ids:
                    schema_ids[schema] = writer.register_schema(*schema)
                sid = schema_ids[schema]
            channel_ids[topic] = writer.register_channel(topic, encoding, sid, meta)
        for m in contents.messages:
            writer.add_message(channel_ids[m.topic], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()  # type: ignore[no-untyped-call]


def without_integrity(contents: Contents) -> Contents:
    """``contents`` as pcdcodec wrote them before color digests and seals."""
    from . import _index as fmt

    metadata = []
    for name, data in contents.metadata:
        if name == fmt.SEAL_NAME:
            continue
        if name == fmt.METADATA_NAME:
            data = {k: v for k, v in data.items() if k != fmt.INTEGRITY_KEY}
            data = fmt.seal(name, data)
        metadata.append((name, data))
    contents.metadata = metadata
    contents.channels.pop(fmt.TOPIC_FRAME_DIGEST, None)
    contents.messages = [m for m in contents.messages if m.topic != fmt.TOPIC_FRAME_DIGEST]
    return contents


def rewrite(
    src: Path,
    dst: Path,
    edit: Callable[[list[Message]], list[Message]] = lambda messages: messages,
    *,
    chunked: bool = True,
    strip_integrity: bool = False,
) -> None:
    """Copy ``src`` to ``dst`` with its messages passed through ``edit`` (in file order);
    ``strip_integrity`` makes it a file as written before color digests and seals."""
    contents = read(src)
    if strip_integrity:
        contents = without_integrity(contents)
    contents.messages = edit(list(contents.messages))
    write(contents, dst, chunked=chunked)


def positions(messages: list[Message], topic: str) -> list[int]:
    """Indices into ``messages`` of the messages on ``topic``."""
    return [k for k, m in enumerate(messages) if m.topic == topic]


def with_data(message: Message, data: bytes) -> Message:
    return replace(message, data=data)
