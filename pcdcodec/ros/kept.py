"""Messages a recording keeps as they came: the topics of an input that pcdcodec does not
compress (IMU, odometry, ``/tf``, camera info, diagnostics, ...), each with its type, message
definition, serialization, connection facts and bytes (``docs/bags.md``).

A source yields :class:`KeptMessage` items beside its frames (:meth:`pcdcodec.Source.items`);
the writer stores each :class:`KeptTopic` as an MCAP channel of its own, in the topic's own
encoding with its schema, and the reader and the bag export give them back byte for byte.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import InputError

__all__ = [
    "CAMERA_KEY",
    "ENVELOPE_ENCODING",
    "IMAGE_ENCODING",
    "KEPT_KEY",
    "KeptMessage",
    "KeptTopic",
    "TopicFilter",
    "by_time",
    "kept_listing",
    "kept_topic_of_connection",
]

#: The channel metadata key that marks a kept topic's channel in a recording.
KEPT_KEY = "pcdcodec.kept"
#: The message encoding of a kept topic of pcdcodec's own making whose messages are images in
#: the encoded depth frame container (``docs/format.md``), kept losslessly: an Azure Kinect's IR.
IMAGE_ENCODING = "pcdcodec.depth"
#: The channel metadata key that marks the channels of a camera topic (one made into frames):
#: its value is the role, ``depth`` or ``color``. Their messages are envelopes
#: (:data:`ENVELOPE_ENCODING`), or messages kept raw where no frame gives them back.
CAMERA_KEY = "pcdcodec.camera"
#: The message encoding of a camera topic's envelopes (:mod:`pcdcodec.ros.envelope`).
ENVELOPE_ENCODING = "pcdcodec.envelope"
#: An envelope channel's metadata key with the original message encoding (``ros1``, ``cdr``).
ORIGINAL_ENCODING_KEY = "pcdcodec.encoding"
#: Channel metadata keys with the connection facts of ROS 1 (the connection header's fields
#: besides the topic, type and definition) and of ROS 2 (what ``ros2 bag`` keeps per topic).
ROS1_KEYS = ("callerid", "latching", "md5sum")
ROS2_KEYS = ("offered_qos_profiles", "serialization_format", "type_hash")


@dataclass(frozen=True)
class KeptTopic:
    """A topic kept as it came.

    ``msgtype`` is the type as rosbags spells it (``sensor_msgs/msg/Imu``, for ROS 1 too),
    ``schema_encoding`` the definition's language (``ros1msg``, ``ros2msg``, ``ros2idl``, or
    ``""`` where the input has no definition), ``definition`` its text, ``message_encoding``
    the serialization (``ros1``, ``cdr``), and ``metadata`` the connection facts the input
    holds (:data:`ROS1_KEYS`, :data:`ROS2_KEYS`; text values).
    """

    topic: str
    msgtype: str
    schema_encoding: str
    definition: str
    message_encoding: str
    metadata: Mapping[str, str] = field(default_factory=dict, hash=False)

    @property
    def camera(self) -> str:
        """The role of a camera topic's channel (``depth``, ``color``), else ``""``."""
        return str(self.metadata.get(CAMERA_KEY, ""))

    @property
    def original_encoding(self) -> str:
        """The messages' own encoding: an envelope channel's original one."""
        if self.message_encoding == ENVELOPE_ENCODING:
            return str(self.metadata.get(ORIGINAL_ENCODING_KEY, ""))
        return self.message_encoding

    def original(self) -> KeptTopic:
        """The topic as the input had it: a camera channel without pcdcodec's own keys, in
        its original encoding."""
        own = (CAMERA_KEY, ORIGINAL_ENCODING_KEY)
        meta = {k: v for k, v in self.metadata.items() if k not in own}
        return KeptTopic(
            self.topic, self.msgtype, self.schema_encoding, self.definition,
            self.original_encoding, meta,
        )  # fmt: skip

    @property
    def schema_name(self) -> str:
        """The type as the input's ROS spells it: ``sensor_msgs/Imu`` in ROS 1."""
        if self.original_encoding == "ros1" and "/msg/" in self.msgtype:
            return self.msgtype.replace("/msg/", "/", 1)
        return self.msgtype

    def channel_metadata(self) -> dict[str, str]:
        """The MCAP channel's metadata: the connection facts, and the kept marker."""
        return {**dict(self.metadata), KEPT_KEY: "1"}

    @classmethod
    def from_channel(
        cls,
        topic: str,
        message_encoding: str,
        metadata: Mapping[str, str],
        schema: tuple[str, str, bytes] | None,
    ) -> KeptTopic:
        """The kept topic an MCAP channel (its ``metadata``, its schema's ``(name, encoding,
        data)``) stores."""
        name, encoding, data = schema if schema is not None else ("", "", b"")
        msgtype = name
        original = message_encoding
        if message_encoding == ENVELOPE_ENCODING:
            original = metadata.get(ORIGINAL_ENCODING_KEY, "")
        if original == "ros1" and name.count("/") == 1:
            msgtype = name.replace("/", "/msg/", 1)
        meta = {k: v for k, v in metadata.items() if k != KEPT_KEY}
        return cls(topic, msgtype, encoding, data.decode(errors="replace"), message_encoding, meta)

    def to_dict(self) -> dict[str, Any]:
        return {
            "topic": self.topic,
            "type": self.msgtype,
            "encoding": self.message_encoding,
            "schema_encoding": self.schema_encoding,
            "metadata": dict(self.metadata),
        }


@dataclass(frozen=True)
class KeptMessage:
    """One message of a kept topic (``topic``, whose channel it goes on: a ROS 1 bag's
    publishers of one topic may differ in caller id), its serialized bytes as the input held
    them, its log time (ns, the time the bag logged it) and publish time (the log time where
    the input has none)."""

    topic: KeptTopic
    log_time: int
    data: bytes
    publish_time: int | None = None

    @property
    def published(self) -> int:
        return self.log_time if self.publish_time is None else self.publish_time


@dataclass(frozen=True)
class TopicFilter:
    """Which topics are kept: those matching any ``include`` pattern (every topic when none is
    given) and no ``exclude`` pattern. Patterns are shell-style (``/camera/*``, ``/tf*``),
    matched against the whole topic name."""

    include: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    #: False: no topic is kept (the recording holds the camera only).
    keep: bool = True

    @classmethod
    def of(
        cls,
        include: Iterable[str] | str | None = None,
        exclude: Iterable[str] | str | None = None,
        keep: bool = True,
    ) -> TopicFilter:
        def patterns(value: Iterable[str] | str | None, name: str) -> tuple[str, ...]:
            if value is None:
                return ()
            items = (value,) if isinstance(value, str) else tuple(value)
            for p in items:
                if not isinstance(p, str) or not p:
                    raise InputError(f"{name} patterns must be non-empty strings, got {p!r}")
            return items

        return cls(patterns(include, "include_topics"), patterns(exclude, "exclude_topics"), keep)

    def __call__(self, topic: str) -> bool:
        if not self.keep:
            return False
        if self.include and not any(fnmatch.fnmatchcase(topic, p) for p in self.include):
            return False
        return not any(fnmatch.fnmatchcase(topic, p) for p in self.exclude)

    def describe(self) -> str:
        if not self.keep:
            return "no other topic kept"
        parts = []
        if self.include:
            parts.append("including " + ", ".join(self.include))
        if self.exclude:
            parts.append("excluding " + ", ".join(self.exclude))
        return "; ".join(parts) or "every other topic kept"


def _definition(conn: Any, ros2: bool) -> tuple[str, str]:
    """(schema encoding, text) of a rosbags connection's message definition."""
    msgdef = getattr(conn, "msgdef", None)
    data = getattr(msgdef, "data", "") or ""
    kind = getattr(getattr(msgdef, "format", None), "name", "")
    if not data:
        return "", ""
    if kind == "IDL":
        return "ros2idl", data
    return ("ros2msg" if ros2 else "ros1msg"), data


def kept_topic_of_connection(conn: Any, ros2: bool, qos_yaml: str = "") -> KeptTopic:
    """The :class:`KeptTopic` of a rosbags connection, with the connection facts it holds
    (ROS 1: caller id, latching, md5sum; ROS 2: offered QoS profiles, serialization format,
    type hash). ``qos_yaml`` is the offered QoS profiles as ``ros2 bag`` writes them."""
    encoding, definition = _definition(conn, ros2)
    meta: dict[str, str] = {}
    ext: Any = getattr(conn, "ext", None)
    if ros2:
        fmt = str(getattr(ext, "serialization_format", "cdr") or "cdr")
        meta["serialization_format"] = fmt
        if qos_yaml:
            meta["offered_qos_profiles"] = qos_yaml
        if getattr(conn, "digest", ""):
            meta["type_hash"] = str(conn.digest)
        message_encoding = fmt
    else:
        if getattr(ext, "callerid", None) is not None:
            meta["callerid"] = str(ext.callerid)
        if getattr(ext, "latching", None) is not None:
            meta["latching"] = str(int(ext.latching))
        if getattr(conn, "digest", ""):
            meta["md5sum"] = str(conn.digest)
        message_encoding = "ros1"
    return KeptTopic(conn.topic, conn.msgtype, encoding, definition, message_encoding, meta)


def by_time(frames: Iterator[Any], messages: Iterator[KeptMessage]) -> Iterator[Any]:
    """Frames (by ``timestamp_ns``) and kept messages (by log time) merged in time order, a
    frame first on a tie; one of each is held at a time."""
    frame = next(frames, None)
    message = next(messages, None)
    while frame is not None or message is not None:
        if message is None or (frame is not None and frame.timestamp_ns <= message.log_time):
            yield frame
            frame = next(frames, None)
        else:
            yield message
            message = next(messages, None)


def kept_listing(topics: Iterable[KeptTopic], streams: Iterable[Any]) -> list[dict[str, Any]]:
    """``{"name", "type", "messages"}`` per kept topic name, the count from the input's
    ``streams`` (:class:`~pcdcodec.sources.InputStream`) where its index says; the type is the
    message encoding for a topic without a message type (an Azure Kinect's IR, IMU)."""
    counts = {s.name: s.count for s in streams}
    out: dict[str, dict[str, Any]] = {}
    for t in topics:
        if t.camera:
            continue  # a camera topic's messages: made into frames, given back from them
        kind = t.msgtype or t.message_encoding
        out.setdefault(t.topic, {"name": t.topic, "type": kind, "messages": counts.get(t.topic)})
    return list(out.values())
