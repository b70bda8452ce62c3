"""The kept topics of a recording (format version 4, ``docs/format.md``): the channels that
hold an input's other topics as they came, how they are written (in zstd chunks of their own,
as MCAP's own compression does) and sealed, and how they are read back and checked.
"""

from __future__ import annotations

import hashlib
import json
import struct
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from typing import IO, Any

from ..errors import DecodeError, InputError
from ..ros.kept import IMAGE_ENCODING, KEPT_KEY, KeptMessage, KeptTopic
from . import _index as fmt
from ._camera import CameraAccess
from ._kept_pack import (
    PACKED_ENCODINGS,
    DepthAt,
    Packer,
    kept_topic_of_channel,
    packed_frames,
    unpack,
)

__all__ = [
    "CHUNK_BYTES",
    "KEPT_VERSION",
    "KeptChannels",
    "check_kept",
    "kept_problems",
    "kept_topics_of",
    "read_kept",
]

#: The format version of files with kept topics: earlier readers refuse them rather than
#: read the camera and drop the rest unseen.
KEPT_VERSION = 4
#: Kept messages are gathered into zstd chunks of about this many bytes (MCAP's default).
CHUNK_BYTES = 1 << 20
#: Kept images and clouds packed at once on the packing thread, at most (each holds its
#: message, a cloud about 10 MB): the reading thread waits for the oldest beyond that.
PACKING = 4
#: Threads packing them (the reading thread and the frame coders take the rest of the CPU).
PACKERS = 1
#: The seal's keys for kept messages: per topic counts (JSON) and the digest of them all.
SEAL_KEPT_KEYS = ("kept", "kept_digest")
_FIELDS = struct.Struct("<QQQQ")  # topic length, log time, publish time, data length

#: pcdcodec's own topic names, which a kept topic may not take.
OWN_TOPICS = frozenset(
    (*fmt.SEALED_TOPICS, fmt.TOPIC_STAMPS, fmt.TOPIC_FRAME_DIGEST, fmt.TOPIC_KEYFRAMES)
)


class KeptDigest:
    """The seal's count and digest of the kept messages, in file order."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self._digest = hashlib.sha256()

    def note(self, topic: str, log_time: int, publish_time: int, data: bytes) -> None:
        name = topic.encode()
        self._digest.update(_FIELDS.pack(len(name), log_time, publish_time, len(data)))
        self._digest.update(name)
        self._digest.update(data)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def seal(self) -> dict[str, str]:
        if not self.counts:
            return {}
        return {
            "kept": json.dumps(dict(sorted(self.counts.items())), separators=(",", ":")),
            "kept_digest": "sha256:" + self._digest.hexdigest(),
        }


class KeptChannels:
    """A writer's kept channels: registered when the file starts, messages gathered and
    written a chunk at a time."""

    def __init__(self, topics: Sequence[KeptTopic], packer: Packer | None = None) -> None:
        #: Packs kept images and clouds (``_kept_pack``), or ``None``: all kept as they came.
        self.packer = packer
        self.packed_ids: dict[KeptTopic, int] = {}
        self.topics: list[KeptTopic] = []
        for t in topics:
            if not isinstance(t, KeptTopic):
                raise InputError(f"kept_topics takes KeptTopic items, got {type(t).__name__}")
            if t.topic in OWN_TOPICS:
                raise InputError(
                    f"topic {t.topic!r} has the name of a channel pcdcodec writes itself; leave "
                    "it out (exclude_topics) or rename it in the input"
                )
            if t not in self.topics:
                self.topics.append(t)
        self.ids: dict[KeptTopic, int] = {}
        #: Messages taken, in order, each with its channel or the packing under way.
        self.taken: deque[tuple[int, KeptMessage, Future[bytes | None] | None]] = deque()
        self.packing = 0  # how many of them are being packed
        self._pool: ThreadPoolExecutor | None = None
        #: Messages ready to write, in the order taken.
        self.pending: list[tuple[int, KeptMessage]] = []
        self.pending_bytes = 0
        self.digest = KeptDigest()
        #: Messages and bytes written, per topic.
        self.written: dict[str, list[int]] = {}

    def register(self, mcap: Any) -> None:
        schemas: dict[tuple[str, str, str], int] = {}
        for t in self.topics:
            key = (t.schema_name, t.schema_encoding, t.definition)
            if key not in schemas:
                schemas[key] = (
                    mcap.register_schema(t.schema_name, t.schema_encoding, t.definition.encode())
                    if t.schema_encoding
                    else 0
                )
            self.ids[t] = mcap.register_channel(
                t.topic, t.message_encoding, schemas[key], t.channel_metadata()
            )
            packed = None if self.packer is None else self.packer.packs(t)
            if packed is not None:
                meta = Packer.channel_metadata(t)
                self.packed_ids[t] = mcap.register_channel(t.topic, packed, schemas[key], meta)

    def saw_frame(self, timestamp: int, depth: Any) -> None:
        """A frame the recording holds: kept images and clouds may refer to its depth."""
        if self.packer is not None:
            self.packer.saw_frame(timestamp, depth)

    def add(self, message: KeptMessage) -> bool:
        """Take ``message``; ``True`` when a chunk's worth is waiting."""
        cid = self.ids.get(message.topic)
        if cid is None:
            raise InputError(
                f"topic {message.topic.topic!r} ({message.topic.msgtype}) is not one of the "
                "kept topics this recording was opened with (kept_topics)"
            )
        if not isinstance(message.data, (bytes, bytearray, memoryview)):
            raise InputError(
                f"a kept message of {message.topic.topic!r} holds a "
                f"{type(message.data).__name__}, expected bytes"
            )
        if message.log_time < 0 or message.published < 0:
            raise InputError(
                f"a kept message of {message.topic.topic!r} has a negative time "
                f"({message.log_time} ns)"
            )
        job = None
        if self.packer is not None and message.topic in self.packed_ids:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(PACKERS, thread_name_prefix="pcdcodec-kept")
            # packed on a thread of its own (the coders release the GIL), with the frames held
            # now: the thread reading the input goes on
            job = self._pool.submit(self.packer.pack, message, self.packer.recent())
            self.packing += 1
        self.taken.append((cid, message, job))
        self._settle(PACKING)
        return self.pending_bytes >= CHUNK_BYTES

    def _settle(self, most: int) -> None:
        """Move the messages taken to the ones ready, in order, until at most ``most`` are
        being packed (waiting for the oldest), and no finished one is left behind."""
        while self.taken:
            cid, message, job = self.taken[0]
            if job is not None:
                if self.packing <= most and not job.done():
                    return
                packed = job.result()
                self.packing -= 1
                if packed is not None:
                    cid, message = self.packed_ids[message.topic], replace(message, data=packed)
            self.taken.popleft()
            self.pending.append((cid, message))
            self.pending_bytes += len(message.data) + 40

    def drain(self) -> None:
        """Wait for every message being packed (before the last chunk is written)."""
        self._settle(0)
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def write(self, mcap: Any) -> None:
        """Write the messages ready as one zstd chunk (each in the order taken)."""
        if not self.pending:
            return
        pending, self.pending, self.pending_bytes = self.pending, [], 0
        with _CompressedChunks(mcap):
            for cid, m in pending:
                data = bytes(m.data)
                mcap.add_message(cid, m.log_time, data, m.published, 0)
                self.digest.note(m.topic.topic, m.log_time, m.published, data)
                count = self.written.setdefault(m.topic.topic, [0, 0])
                count[0] += 1
                count[1] += len(data)


class _CompressedChunks:
    """Within the block, the MCAP writer gathers messages into one zstd chunk, written when
    the block ends; outside, every message is a chunk of its own, uncompressed (the writer's
    settings for frames, :func:`pcdcodec.recording._header.start_mcap`)."""

    _SIZE = "_Writer__chunk_size"
    _COMPRESSION = "_Writer__compression"

    def __init__(self, mcap: Any) -> None:
        self.mcap = mcap
        self.usable = hasattr(mcap, self._SIZE) and hasattr(mcap, self._COMPRESSION)

    def __enter__(self) -> None:
        if self.usable:
            from mcap.writer import CompressionType

            self.saved = getattr(self.mcap, self._SIZE), getattr(self.mcap, self._COMPRESSION)
            setattr(self.mcap, self._SIZE, 1 << 62)
            setattr(self.mcap, self._COMPRESSION, CompressionType.ZSTD)

    def __exit__(self, *exc: object) -> None:
        if self.usable:
            try:
                self.mcap.flush()  # the chunk, compressed
            finally:
                setattr(self.mcap, self._SIZE, self.saved[0])
                setattr(self.mcap, self._COMPRESSION, self.saved[1])


# -- reading ------------------------------------------------------------------------------------


def kept_channel_ids(index: fmt.FileIndex) -> dict[int, KeptTopic]:
    """The kept channels of a file, by channel id."""
    return {
        cid: kept_topic_of_channel(
            ch.topic, ch.encoding, ch.metadata, index.schemas.get(index.channel_schema.get(cid, 0))
        )
        for cid, ch in index.channels.items()
        if ch.metadata.get(KEPT_KEY) == "1"
    }


def stored_channel_ids(index: fmt.FileIndex) -> dict[int, KeptTopic]:
    """The kept channels of a file, by channel id, each described as stored (a packed or
    envelope channel with its own message encoding and metadata): what a copy of the file's
    chunks (recover, join) registers again, so the bytes it copies keep their meaning."""
    return {
        cid: KeptTopic.from_channel(
            ch.topic, ch.encoding, ch.metadata, index.schemas.get(index.channel_schema.get(cid, 0))
        )
        for cid, ch in index.channels.items()
        if ch.metadata.get(KEPT_KEY) == "1"
    }


def stored_topics_of(index: fmt.FileIndex) -> list[KeptTopic]:
    """Every kept channel of a file as stored (:func:`stored_channel_ids`), each once."""
    out: list[KeptTopic] = []
    for t in stored_channel_ids(index).values():
        if t not in out:
            out.append(t)
    return out


def kept_topics_of(index: fmt.FileIndex, camera: bool = False) -> list[KeptTopic]:
    """The kept topics of a file, in channel order: those kept as they came, or with
    ``camera`` the channels of the camera topics (envelopes, and messages kept raw)."""
    out: list[KeptTopic] = []
    for t in kept_channel_ids(index).values():
        if bool(t.camera) == camera and t not in out:
            out.append(t)
    return out


def kept_counts(index: fmt.FileIndex) -> dict[str, int]:
    """Messages per kept topic, from the index."""
    names = {ch.topic for ch in index.channels.values() if ch.metadata.get(KEPT_KEY) == "1"}
    return {t: len(index.times.get(t, [])) for t in sorted(names) if index.times.get(t)}


def kept_problems(index: fmt.FileIndex, seal: dict[str, str] | None) -> list[str]:
    """How the kept messages the index lists differ from the seal's counts (none for a file
    without a seal: its writer died, and its chunks' CRCs vouch for what it holds)."""
    if seal is None:
        return []
    found = kept_counts(index)
    sealed_text = seal.get("kept")
    if sealed_text is None:
        return [f"kept messages: sealed none, found {found}"] if found else []
    try:
        sealed = json.loads(sealed_text)
    except ValueError:
        return [f"kept messages: the seal's count {sealed_text!r} is not JSON"]
    if sealed != found:
        return [f"kept messages per topic: sealed {sealed}, found {found}"]
    return []


def read_kept(
    f: IO[bytes],
    index: fmt.FileIndex,
    what: str,
    *,
    topics: Iterable[str] | None = None,
    check: bool = True,
    select: Callable[[KeptTopic], bool] | None = None,
    depth_at: DepthAt | None = None,
    camera: tuple[float, float, float, float, float] | None = None,
) -> Iterator[KeptMessage]:
    """The kept messages of the file (those of ``topics`` and of channels ``select`` takes,
    when given), in file order, each chunk's CRC checked before its messages are given. With
    ``check`` the whole (every kept channel's) is compared with the seal's digest at the end:
    a :class:`~pcdcodec.DecodeError` then says the messages given were not those sealed.
    Packed images and clouds are given as they came; those that refer to a depth frame need
    ``depth_at(timestamp)``, and clouds the recording's ``camera``, ``(fx, fy, cx, cy,
    depth_scale)`` (:mod:`._kept_pack`)."""
    channels = kept_channel_ids(index)
    packed = {c for c in channels if index.channels[c].encoding in PACKED_ENCODINGS}
    if not channels:
        return
    wanted = None if topics is None else set(topics)
    offsets = sorted(
        {
            off
            for ch in {c.topic for c in index.channels.values() if c.id in channels}
            for off in index.offsets.get(ch, [])
        }
    )
    digest = KeptDigest()
    for off in offsets:
        for m in fmt.read_chunk_messages(f, off, what=what):
            topic = channels.get(m.channel_id)
            if topic is None:
                continue
            data = bytes(m.data)
            digest.note(topic.topic, m.log_time, m.publish_time, data)
            if (wanted is None or topic.topic in wanted) and (select is None or select(topic)):
                if m.channel_id in packed:
                    data = unpack(data, depth_at, what, camera)
                yield KeptMessage(topic, int(m.log_time), data, int(m.publish_time))
    seal = index.metadata.get(fmt.SEAL_NAME)
    if (
        check
        and seal is not None
        and digest.seal() != {k: seal[k] for k in SEAL_KEPT_KEYS if k in seal}
    ):
        raise DecodeError(
            f"{what}: the kept messages are not those sealed (changed, added, removed or "
            "reordered); run `pcdcodec recover` to copy those that check out"
        )


def kept_offsets(index: fmt.FileIndex) -> dict[int, list[str]]:
    """The chunks that hold kept messages: byte offset -> the kept topics found there."""
    names = {ch.topic for ch in index.channels.values() if ch.metadata.get(KEPT_KEY) == "1"}
    out: dict[int, list[str]] = {}
    for topic in sorted(names):
        for off in index.offsets.get(topic, []):
            if topic not in out.setdefault(off, []):
                out[off].append(topic)
    return dict(sorted(out.items()))


def check_kept(f: IO[bytes], index: fmt.FileIndex, what: str) -> tuple[list[str], dict[str, int]]:
    """Every kept message of the file read, each chunk's CRC checked (a damaged chunk is
    passed over, and said with the topics it holds), and what was read compared with the
    seal: each topic's count, then the digest of them all. Returns the problems and the
    messages read per topic."""
    channels = kept_channel_ids(index)
    problems: list[str] = []
    digest = KeptDigest()
    for off, topics in kept_offsets(index).items():
        try:
            messages = fmt.read_chunk_messages(f, off, what=what)
        except DecodeError as exc:
            problems.append(f"kept topics {', '.join(topics)}: unreadable ({exc})")
            continue
        for m in messages:
            kept = channels.get(m.channel_id)
            if kept is not None:
                digest.note(kept.topic, m.log_time, m.publish_time, bytes(m.data))
    seal = index.metadata.get(fmt.SEAL_NAME)
    if seal is None:
        return problems, digest.counts
    try:
        sealed = json.loads(seal.get("kept", "{}"))
        if not isinstance(sealed, dict):
            raise ValueError
    except ValueError:
        return [*problems, f"kept messages: the seal's count {seal.get('kept')!r} is not JSON"], {}
    for topic in sorted(set(sealed) | set(digest.counts)):
        if sealed.get(topic, 0) != digest.counts.get(topic, 0):
            problems.append(
                f"kept topic {topic}: {sealed.get(topic, 0)} messages sealed, "
                f"{digest.counts.get(topic, 0)} read"
            )
    if not problems and digest.seal().get("kept_digest") != seal.get("kept_digest"):
        problems.append(
            "the kept messages are not those sealed (changed or reordered; their chunks' CRCs "
            f"hold) on topics {', '.join(sorted(digest.counts))}"
        )
    return problems, digest.counts


class KeptAccess(CameraAccess):
    """What a :class:`~pcdcodec.Recording` gives of its kept topics (and, through
    :class:`~pcdcodec.recording._camera.CameraAccess`, of its camera topics' messages)."""

    path: Any
    index: fmt.FileIndex
    _file: IO[bytes]
    _lock: Any

    @property
    def kept_topics(self) -> list[KeptTopic]:
        """The other topics of the input that the recording keeps as they came (each with its
        type, message definition, serialization and connection facts); empty for recordings
        without (format versions 1-3). The camera topics are not among them
        (:attr:`camera_topics`)."""
        return kept_topics_of(self.index)

    @property
    def camera_topics(self) -> list[KeptTopic]:
        """The camera topics the frames were made of, as the input had them (type,
        definition, encoding, connection facts), whose messages :meth:`camera_messages`
        gives back; empty for recordings without."""
        out: list[KeptTopic] = []
        for t in kept_topics_of(self.index, camera=True):
            if t.original() not in out:
                out.append(t.original())
        return out

    def kept_counts(self) -> dict[str, int]:
        """Messages per kept topic (of :attr:`kept_topics`)."""
        names = {t.topic for t in self.kept_topics}
        return {t: n for t, n in kept_counts(self.index).items() if t in names}

    def _read_kept(self, camera: bool) -> Iterator[KeptMessage]:
        with open(self.path, "rb") as f:
            yield from read_kept(
                f, self.index, repr(str(self.path)), select=lambda t: bool(t.camera) == camera
            )

    def kept_messages(self, topics: Iterable[str] | None = None) -> Iterator[KeptMessage]:
        """The kept topics' messages (of ``topics`` only, when given), in the order they were
        written, each with its bytes as the input held them and its log and publish times.
        Each chunk's CRC is checked before its messages are given, and reading them all checks
        them against the seal at the end (:class:`~pcdcodec.DecodeError` if they differ).
        Reads its own handle of the file, so frames can be read meanwhile. The camera topics'
        messages are not among them (:meth:`camera_messages`). Packed images and clouds
        (``docs/bags.md``) come back byte for byte, rebuilt from what they hold and the depth
        frames they refer to."""
        depth_at, camera = packed_frames(self)
        with open(self.path, "rb") as f:
            yield from read_kept(
                f, self.index, repr(str(self.path)), topics=topics,
                select=lambda t: not t.camera, depth_at=depth_at, camera=camera,
            )  # fmt: skip

    def kept_images(self, topic: str) -> Iterator[tuple[int, Any]]:
        """The images of a kept topic of encoded depth frames (message encoding
        ``pcdcodec.depth``: an Azure Kinect's IR on ``/k4a/ir``), in order, each as ``(log
        time ns, image)``: bit-exact, of the dtype and size they were kept with (uint16 for
        IR). Each frame's CRC is checked as it decodes. Raises
        :class:`~pcdcodec.InputError` when ``topic`` is not such a kept topic of the recording,
        :class:`~pcdcodec.DecodeError` when a frame does not decode."""
        from ..depth import decode_depth

        encodings = {t.topic: t.message_encoding for t in self.kept_topics}
        if encodings.get(topic) != IMAGE_ENCODING:
            images = sorted(t for t, e in encodings.items() if e == IMAGE_ENCODING)
            raise InputError(
                f"{str(self.path)!r} keeps no images on {topic!r} (topics of "
                f"{IMAGE_ENCODING} frames: {', '.join(images) or 'none'})"
            )
        for m in self.kept_messages([topic]):
            try:
                image = decode_depth(m.data)
            except DecodeError as exc:
                raise DecodeError(
                    f"{str(self.path)!r}: the {topic} image at {m.log_time} ns: {exc}"
                ) from None
            yield m.log_time, image
