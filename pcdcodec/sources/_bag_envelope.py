"""A ROS bag's camera messages kept exactly (``docs/bags.md``, ``docs/format.md``).

Each depth and color message made into a frame is kept as an *envelope*
(:mod:`pcdcodec.ros.envelope`): the message without its pixels, on a channel of the camera
topic's own name, schema and connection facts, which the recording gives back message for
message (:meth:`pcdcodec.Recording.camera_messages`). A camera message no frame holds (dropped
for lack of a partner, skipped for a stamp that did not increase, another publisher's on the
topic) or one its frame cannot give back as it was (row padding, alpha, ...) is kept raw, on a
camera channel of its own encoding. So every message of the camera topics comes back; with
``max_frames``, those of the frames read (a prefix of the bag).

Envelopes are made while :meth:`~pcdcodec.Source.items` reads the frames, and merged into the
kept messages in log-time order: a camera message read but not yet paired or dropped holds
back the messages logged after it, so at most the synchronizer's queue is waited for. Messages
waiting beyond :data:`HELD_BYTES` (a long stretch of images without partners between two
frames) wait in a temporary file, so memory stays bounded however long the bag.
"""

from __future__ import annotations

import heapq
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO, Any

from ..ros.envelope import make_envelope
from ..ros.kept import (
    CAMERA_KEY,
    ENVELOPE_ENCODING,
    ORIGINAL_ENCODING_KEY,
    KeptMessage,
    KeptTopic,
    by_time,
    kept_topic_of_connection,
)
from ._bag_kept import BagKeptTopics, _qos_yaml

__all__ = ["HELD_BYTES", "BagEnvelopes"]

#: The most bytes of camera messages held in memory while they wait for their turn.
HELD_BYTES = 64 << 20


@dataclass
class _Read:
    """A camera message read, not yet given a place in the kept stream."""

    seq: int
    log_time: int
    conn: Any
    raw: bytes
    msg: Any


@dataclass
class _Run:
    """The envelopes of one pass over the frames: the messages read and not yet resolved, and
    those resolved, waiting (by log time, then read order) until nothing read is before them."""

    topics: dict[int, tuple[KeptTopic, KeptTopic]]  # connection id: (envelope, raw)
    cdr: bool
    read: dict[int, _Read] = field(default_factory=dict)  # id(msg): read
    # (log time, read order, message, or (topic, offset, length) in the spill file)
    ready: list[tuple[int, int, Any]] = field(default_factory=list)
    held: int = 0  # bytes of the messages in ``ready`` held in memory
    spill: IO[bytes] | None = None
    seq: int = 0
    last_log: int = -1
    done: bool = False

    def note(self, conn: Any, log_time: int, raw: bytes, msg: Any) -> None:
        if conn.id in self.topics:
            self.read[id(msg)] = _Read(self.seq, int(log_time), conn, bytes(raw), msg)
            self.seq += 1
            self.last_log = max(self.last_log, int(log_time))

    def take(self, msg: Any) -> _Read | None:
        return self.read.pop(id(msg), None)

    def put(self, r: _Read, data: bytes | None) -> None:
        """Keep ``r`` as an envelope (``data``), or raw where ``data`` is None."""
        envelope, raw = self.topics[r.conn.id]
        m = KeptMessage(envelope, r.log_time, data) if data else KeptMessage(raw, r.log_time, r.raw)
        item: Any = m
        if self.held + len(m.data) > HELD_BYTES:
            if self.spill is None:
                self.spill = tempfile.TemporaryFile()  # noqa: SIM115 (closed by close())
            at = self.spill.seek(0, 2)
            self.spill.write(m.data)
            item = (m.topic, at, len(m.data))
        else:
            self.held += len(m.data)
        heapq.heappush(self.ready, (r.log_time, r.seq, item))

    def pop(self) -> KeptMessage:
        log_time, _, item = heapq.heappop(self.ready)
        if isinstance(item, KeptMessage):
            self.held -= len(item.data)
            return item
        topic, at, size = item
        assert self.spill is not None
        self.spill.seek(at)
        return KeptMessage(topic, log_time, self.spill.read(size))

    def close(self) -> None:
        if self.spill is not None:
            self.spill.close()
            self.spill = None

    def bound(self) -> float:
        """No message still to come is logged before this."""
        lows: list[float] = [r.log_time for r in self.read.values()]
        if self.ready:
            lows.append(self.ready[0][0])
        if not self.done:
            lows.append(self.last_log)
        return min(lows, default=float("inf"))

    def releasable(self) -> bool:
        if not self.ready:
            return False
        first = min(((r.log_time, r.seq) for r in self.read.values()), default=None)
        return first is None or self.ready[0][:2] < first

    def finish(self) -> None:
        """The frames ended: a message read and left unresolved (after ``max_frames``) is not
        kept; everything else is released."""
        self.done = True
        self.read.clear()


class BagEnvelopes(BagKeptTopics):
    """The camera-message half of :class:`~pcdcodec.sources.rosbag.RosbagSource`."""

    mode: str
    _depth_conn: Any
    _color_conn: Any
    _env: _Run | None = None

    def _camera_topics(self) -> dict[int, tuple[KeptTopic, KeptTopic]]:
        """Per camera connection read into frames: its envelope and raw channels."""
        found: dict[int, tuple[KeptTopic, KeptTopic]] | None = getattr(self, "_camera_conns", None)
        if found is not None:
            return found
        found = {}
        if self.mode == "images":
            roles = [(self._depth_conn, "depth"), (self._color_conn, "color")]
            ros2 = bool(self._reader.is2)
            for conn, role in roles:
                if conn is None or not self.topic_filter(conn.topic):
                    continue
                t = kept_topic_of_connection(conn, ros2, _qos_yaml(conn) if ros2 else "")
                raw = KeptTopic(
                    t.topic, t.msgtype, t.schema_encoding, t.definition, t.message_encoding,
                    {**t.metadata, CAMERA_KEY: role},
                )  # fmt: skip
                meta = {**raw.metadata, ORIGINAL_ENCODING_KEY: t.message_encoding}
                envelope = KeptTopic(
                    t.topic, t.msgtype, t.schema_encoding, t.definition, ENVELOPE_ENCODING, meta
                )
                found[conn.id] = (envelope, raw)
        self._camera_conns = found
        return found

    def _kept_connections(self) -> dict[int, KeptTopic]:
        """The kept connections, and the camera topics' other connections (a ROS 1 topic's
        other publishers), whose messages no frame holds: kept raw."""
        kept = dict(super()._kept_connections())
        cams = self._camera_topics()
        roles = {topics[1].topic: topics[1] for topics in cams.values()}
        for c in self._reader.connections:
            if c.topic in roles and c.id not in cams and c.id not in kept:
                t = kept_topic_of_connection(c, bool(self._reader.is2), _qos_yaml(c))
                kept[c.id] = KeptTopic(
                    t.topic, t.msgtype, t.schema_encoding, t.definition, t.message_encoding,
                    {**t.metadata, CAMERA_KEY: roles[c.topic].camera},
                )  # fmt: skip
        return kept

    def kept_topics(self) -> list[KeptTopic]:
        """The kept topics, and the camera topics' channels (their :attr:`KeptTopic.camera`
        says the role): envelopes, and messages kept raw."""
        out = super().kept_topics()
        for pair in self._camera_topics().values():
            out += [t for t in pair if t not in out]
        return out

    # -- hooks of the frame path ------------------------------------------------------------

    def _env_read(self, conn: Any, log_time: int, raw: bytes, msg: Any) -> None:
        if self._env is not None:
            self._env.note(conn, log_time, raw, msg)

    def _env_left(self, _is_depth: bool, _ts: int, msg: Any) -> None:
        """A camera message no frame holds (dropped, out of order): kept raw."""
        if self._env is not None and (r := self._env.take(msg)) is not None:
            self._env.put(r, None)

    def _env_frame(self, ts: int, *images: tuple[Any, Any, str]) -> None:
        """The messages ``(message, image, role)`` made into the frame at ``ts``: envelopes,
        or raw where the frame cannot give them back as they were."""
        run = self._env
        if run is None:
            return
        for msg, image, role in images:
            r = run.take(msg)
            if r is not None:
                run.put(r, make_envelope(r.raw, msg, role, image, ts, cdr=run.cdr))

    # -- frames and kept messages in time order ----------------------------------------------

    def items(self) -> Iterator[Any]:
        topics = self._camera_topics()
        if not topics:  # Source.items: no camera messages kept
            return by_time(iter(self), self.kept_messages())  # type: ignore[call-overload]
        return self._items(_Run(topics, bool(self._reader.is2)))

    def _items(self, run: _Run) -> Iterator[Any]:
        """The frames, and before each the kept messages and envelopes logged before its
        time whose place is known (nothing read and unresolved before them); the rest at
        the end. One frame and one kept message are held at a time."""
        self._env = run
        kept = self.kept_messages()
        k = next(kept, None)

        def release(limit: float) -> Iterator[KeptMessage]:
            nonlocal k
            while True:
                if k is not None and k.log_time < limit and k.log_time <= run.bound():
                    yield k
                    k = next(kept, None)
                elif run.releasable() and run.ready[0][0] < limit:
                    yield run.pop()
                else:
                    return

        try:
            for frame in iter(self):  # type: ignore[call-overload]
                yield from release(frame.timestamp_ns)
                yield frame
            run.finish()
            yield from release(float("inf"))
        finally:
            self._env = None
            run.close()
