"""A ROS bag read message by message as MCAP sees it, and an MCAP writer with zstd chunks at a
chosen level: what :mod:`~pcdcodec.bench.bag_peers` rewrites bags with.

:func:`open_bag` gives every message of a ROS 1 bag, a ROS 2 bag (sqlite3 or mcap storage, a
folder of several files or one file) or any MCAP file, in the bag's own order, one at a time,
each with its :class:`Channel` (topic, schema, message encoding and metadata as MCAP keeps
them). MCAP files are read with the ``mcap`` reader, so publish times and sequence numbers come
along; the others through rosbags, whose bags keep no publish time (the log time stands in).
:class:`McapOut` writes such messages again, adding each schema and channel on first sight,
and :func:`zstd_level` sets the zstd level of its chunks.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import IO, Any

from ..errors import CodecUnavailableError, DecodeError, InputError
from ..ros import bagfile

__all__ = ["Bag", "Channel", "McapOut", "Record", "open_bag", "ros1_schema", "zstd_level"]


@dataclass(frozen=True)
class Channel:
    """A topic as MCAP keeps it: name, schema (name, encoding, text) and message encoding."""

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    metadata: tuple[tuple[str, str], ...]


#: (channel, log time, publish time, sequence, serialized message)
Record = tuple[Channel, int, int, int, bytes]


@dataclass
class Bag:
    profile: str
    records: Iterator[Record]
    extras: Callable[[Any], None]  # copies an MCAP input's metadata and attachments


def _mcap_files(path: Path) -> list[Path] | None:
    """The MCAP files of a bag, in order, or ``None`` for a bag read through rosbags."""
    if path.is_dir():
        import yaml

        try:
            meta = yaml.safe_load((path / "metadata.yaml").read_text())
            info = meta["rosbag2_bagfile_information"]
            if info.get("storage_identifier") != "mcap":
                return None
            return [path / name for name in info["relative_file_paths"]]
        except (OSError, KeyError, TypeError, yaml.YAMLError) as exc:
            raise DecodeError(f"cannot read bag {str(path)!r}: metadata.yaml: {exc}") from exc
    with path.open("rb") as f:
        head = f.read(64)
    return [path] if head.startswith(bagfile.MCAP_MAGIC) else None


def _mcap_records(path: Path, files: list[Path], stack: contextlib.ExitStack) -> Bag:
    from mcap.reader import NonSeekingReader, make_reader

    try:
        with files[0].open("rb") as f:
            profile = make_reader(f).get_header().profile
    except Exception as exc:
        raise bagfile.bag_error(exc, path) from exc

    def records() -> Iterator[Record]:
        channels: dict[tuple[int, int], Channel] = {}
        for n, file in enumerate(files):
            try:
                f = stack.enter_context(file.open("rb"))
                # In the file's own order, one chunk at a time: the seeking reader would read
                # every chunk before the first message unless asked for log-time order.
                for schema, channel, message in NonSeekingReader(f).iter_messages(
                    log_time_order=False
                ):
                    key = (n, channel.id)
                    if key not in channels:
                        channels[key] = Channel(
                            channel.topic,
                            schema.name if schema else "",
                            schema.encoding if schema else "",
                            bytes(schema.data) if schema else b"",
                            channel.message_encoding,
                            tuple(sorted(channel.metadata.items())),
                        )
                    yield (
                        channels[key],
                        message.log_time,
                        message.publish_time,
                        message.sequence,
                        bytes(message.data),
                    )
            except DecodeError:
                raise
            except Exception as exc:
                raise bagfile.bag_error(exc, path) from exc

    def extras(writer: Any) -> None:
        for file in files:
            try:
                with file.open("rb") as f:
                    reader = make_reader(f)
                    for meta in reader.iter_metadata():
                        writer.add_metadata(meta.name, dict(meta.metadata))
                    for att in reader.iter_attachments():
                        writer.add_attachment(
                            att.create_time, att.log_time, att.name, att.media_type, att.data
                        )
            except Exception as exc:
                raise bagfile.bag_error(exc, path) from exc

    return Bag(profile, records(), extras)


def ros1_schema(msgtype: str) -> str:
    """``sensor_msgs/msg/Image`` as ROS 1 names it: ``sensor_msgs/Image``."""
    return msgtype.replace("/msg/", "/", 1)


def _rosbags_channel(conn: Any, reader: Any) -> Channel:
    from rosbags.interfaces import ConnectionExtRosbag1, MessageDefinitionFormat

    ext = conn.ext
    if isinstance(ext, ConnectionExtRosbag1):
        meta = {"md5sum": conn.digest}
        if ext.callerid is not None:
            meta["callerid"] = ext.callerid
        if ext.latching is not None:
            meta["latching"] = str(ext.latching)
        return Channel(
            conn.topic,
            ros1_schema(conn.msgtype),
            "ros1msg",
            conn.msgdef.data.encode(),
            "ros1",
            tuple(sorted(meta.items())),
        )
    from rosbags.rosbag2.metadata import dump_qos_v8

    text = conn.msgdef.data
    fmt = conn.msgdef.format
    if not text:  # a bag of an older ROS 2 keeps no definitions: the typestore's (Humble's)
        text = reader.typestore.generate_msgdef(conn.msgtype, ros_version=2)[0]
        fmt = MessageDefinitionFormat.MSG
    meta2 = {"offered_qos_profiles": dump_qos_v8(ext.offered_qos_profiles)}
    return Channel(
        conn.topic,
        conn.msgtype,
        "ros2idl" if fmt == MessageDefinitionFormat.IDL else "ros2msg",
        text.encode(),
        ext.serialization_format,
        tuple(sorted(meta2.items())),
    )


def _rosbags_records(path: Path, stack: contextlib.ExitStack) -> Bag:
    reader, tmp = bagfile.open_reader(path)
    stack.callback(reader.close)
    if tmp is not None:
        stack.callback(tmp.cleanup)
    channels = {(c.id, id(c.owner)): _rosbags_channel(c, reader) for c in reader.connections}

    def records() -> Iterator[Record]:
        try:
            for conn, t, raw in reader.messages():
                yield channels[(conn.id, id(conn.owner))], t, t, 0, bytes(raw)
        except Exception as exc:
            raise bagfile.bag_error(exc, path) from exc

    return Bag("ros2" if reader.is2 else "ros1", records(), lambda writer: None)


def open_bag(path: Path, stack: contextlib.ExitStack) -> Bag:
    """Every message of the bag at ``path``, in the bag's order, one at a time."""
    if not path.exists():
        raise InputError(f"bag {str(path)!r} does not exist")
    files = _mcap_files(path)
    if files is not None:
        return _mcap_records(path, files, stack)
    return _rosbags_records(path, stack)


@contextlib.contextmanager
def zstd_level(level: int) -> Iterator[None]:
    """The ``mcap`` writer's chunks compressed at zstd ``level`` (it offers no level of its
    own: it calls ``zstandard.compress`` at zstd's default 3). It swaps the ``mcap.writer``
    module's compressor while the block runs, so other MCAP writers of the process that
    compress with zstd at that time get the level too (pcdcodec's recordings use none)."""

    import zstandard

    module: Any = importlib.import_module("mcap.writer")

    if not -7 <= level <= 22:
        raise InputError(f"zstd level must be from -7 to 22, got {level}")
    if getattr(module, "zstandard", None) is None:
        raise CodecUnavailableError("this mcap package compresses chunks without zstandard")
    saved = module.zstandard
    compressor = zstandard.ZstdCompressor(level=level)
    module.zstandard = SimpleNamespace(compress=compressor.compress)
    try:
        yield
    finally:
        module.zstandard = saved


class McapOut:
    """An MCAP writer with zstd chunks that adds each schema and channel on first sight."""

    def __init__(self, stream: IO[bytes], profile: str, chunk_size: int) -> None:
        from mcap.writer import CompressionType, Writer

        self.writer: Any = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self.writer.start(profile=profile, library="pcdcodec bench")
        self.schemas: dict[tuple[str, str, bytes], int] = {}
        self.channels: dict[Channel, int] = {}

    def channel(self, ch: Channel) -> int:
        cid = self.channels.get(ch)
        if cid is None:
            key = (ch.schema_name, ch.schema_encoding, ch.schema_data)
            sid = self.schemas.get(key)
            if sid is None:
                sid = 0 if not ch.schema_name else self.writer.register_schema(*key)
                self.schemas[key] = sid
            cid = self.writer.register_channel(
                ch.topic, ch.message_encoding, sid, dict(ch.metadata)
            )
            self.channels[ch] = cid
        return cid

    def write(self, ch: Channel, log: int, publish: int, seq: int, data: bytes) -> None:
        self.writer.add_message(self.channel(ch), log, data, publish, seq)
