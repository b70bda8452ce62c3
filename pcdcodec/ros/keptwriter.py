"""Kept topics written into a ROS bag: each :class:`~pcdcodec.ros.kept.KeptTopic` becomes a
connection of its own and each :class:`~pcdcodec.ros.kept.KeptMessage` is written with its log
time (``docs/bags.md``, "Giving the bag back").

Into a bag of the topic's own kind (ROS 1 messages into a ROS 1 bag, CDR into a ROS 2 bag) a
topic goes as it came: its type, message definition, serialization, its ROS 1 connection
header (caller id, latching, md5sum) or ROS 2 offered QoS profiles and type hash, and every
message's bytes unchanged.

Into a bag of the other kind the topic is converted by rosbags' own rules (those of
``rosbags-convert``): the types are read from the topic's definition, the ROS 1 ``Header``
loses its ``seq`` (ROS 2) or gains ``seq = 0`` (ROS 1), ``tf/tfMessage`` becomes
``tf2_msgs/TFMessage``, a latched ROS 1 topic is offered as transient local in ROS 2 and back,
and each message is converted byte by byte. A topic that cannot be converted (no definition
and a type ROS does not ship, a serialization that is not ROS 1 or CDR) is refused, naming it.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable, Iterable
from typing import Any

from ..errors import InputError
from .bagwriter import BagWriter
from .kept import KeptMessage, KeptTopic

__all__ = ["KeptConnections", "bag_encoding"]

#: The message encoding of each bag kind.
_ENCODING = {False: "ros1", True: "cdr"}


def bag_encoding(ros2: bool) -> str:
    """The serialization the messages of a ROS 1 (``"ros1"``) or ROS 2 (``"cdr"``) bag use."""
    return _ENCODING[ros2]


class KeptConnections:
    """The kept topics of one bag being written: their connections, and how each topic's
    messages are written (as they are, or converted to the bag's kind)."""

    def __init__(self, bag: BagWriter, *, what: str) -> None:
        self.bag = bag
        self.ros2 = bag.messages.ros2
        self.what = what
        self.conns: dict[KeptTopic, Any] = {}
        self.convert: dict[KeptTopic, Callable[[bytes], Any]] = {}
        #: Messages written per topic name.
        self.counts: dict[str, int] = {}
        #: What converting the topics said (types copied or migrated).
        self.notes: list[str] = []

    def add(self, topics: Iterable[KeptTopic]) -> None:
        """Add a connection for each of ``topics`` not added yet."""
        new = [t for t in topics if t not in self.conns]
        for t in new:
            if not t.msgtype:
                raise InputError(
                    f"{self.what}: topic {t.topic!r} has no message type: a bag cannot say "
                    "what its messages are"
                )
            if t.message_encoding not in _ENCODING.values():
                raise InputError(
                    f"{self.what}: topic {t.topic!r} ({t.msgtype}) is serialized as "
                    f"{t.message_encoding!r}; a ROS bag holds ROS 1 or CDR messages only"
                )
        same = [t for t in new if t.message_encoding == bag_encoding(self.ros2)]
        other = [t for t in new if t.message_encoding != bag_encoding(self.ros2)]
        for t in same:
            self.conns[t] = self._as_it_came(t)
        if other:
            self._converted(other)

    def write(self, message: KeptMessage) -> None:
        """Write ``message`` at its log time, adding its topic's connection when new."""
        topic = message.topic
        if topic not in self.conns:
            self.add([topic])
        conv = self.convert.get(topic)
        data = message.data if conv is None else bytes(conv(message.data))
        self.bag.writer.write(self.conns[topic], message.log_time, data)
        self.counts[topic.topic] = self.counts.get(topic.topic, 0) + 1

    def _as_it_came(self, t: KeptTopic) -> Any:
        meta = t.metadata
        writer = self.bag.writer
        if not self.ros2:
            md5sum = (
                meta.get("md5sum") or _types(self.what, [t], False).generate_msgdef(t.msgtype)[1]
            )
            latching = meta.get("latching")
            return writer.add_connection(
                t.topic,
                t.msgtype,
                msgdef=t.definition,
                md5sum=md5sum,
                callerid=meta.get("callerid"),
                latching=None if latching is None else int(latching),
            )
        from rosbags.rosbag2.metadata import parse_qos

        qos = parse_qos(meta.get("offered_qos_profiles", ""))
        fmt = meta.get("serialization_format", "cdr")
        if not t.definition:  # the bag had none: ROS 2's own, where ROS ships the type
            store = _types(self.what, [t], True)
            return writer.add_connection(
                t.topic,
                t.msgtype,
                typestore=store,
                serialization_format=fmt,
                offered_qos_profiles=qos,
            )
        rihs01 = meta.get("type_hash") or _types(self.what, [t], True).hash_rihs01(t.msgtype)
        return writer.add_connection(
            t.topic,
            t.msgtype,
            msgdef=t.definition,
            rihs01=rihs01,
            serialization_format=fmt,
            offered_qos_profiles=qos,
        )

    def _converted(self, topics: list[KeptTopic]) -> None:
        """Connections and converters of topics of the other kind, by rosbags' rules."""
        from rosbags.convert.converter import create_connections_converters
        from rosbags.interfaces import (
            Connection,
            ConnectionExtRosbag1,
            ConnectionExtRosbag2,
            MessageDefinition,
            MessageDefinitionFormat,
        )
        from rosbags.rosbag2.metadata import parse_qos

        src2 = not self.ros2
        store = _types(self.what, topics, src2)
        owner = object()
        conns = []
        for k, t in enumerate(topics):
            meta = t.metadata
            ext: Any
            if src2:
                qos = parse_qos(meta.get("offered_qos_profiles", ""))
                ext = ConnectionExtRosbag2(meta.get("serialization_format", "cdr"), qos)
                digest = meta.get("type_hash", "")
            else:
                latching = meta.get("latching")
                ext = ConnectionExtRosbag1(
                    meta.get("callerid"), None if latching is None else int(latching)
                )
                digest = meta.get("md5sum", "")
            fmt = (
                MessageDefinitionFormat.IDL
                if t.schema_encoding == "ros2idl"
                else MessageDefinitionFormat.MSG
            )
            msgdef = MessageDefinition(fmt, t.definition)
            conns.append(Connection(k, t.topic, t.msgtype, msgdef, digest, 0, ext, owner))
        said = io.StringIO()
        try:
            with contextlib.redirect_stdout(said):
                reader: Any = _Reader(src2, store)
                connmap, convmap = create_connections_converters(
                    conns, None, reader, self.bag.writer
                )
        except Exception as exc:
            names = ", ".join(sorted({t.topic for t in topics}))
            raise InputError(
                f"{self.what}: cannot convert {names} to a ROS {2 if self.ros2 else 1} bag: {exc}"
            ) from exc
        self.notes += [line for line in said.getvalue().splitlines() if line.strip()]
        for c, t in zip(conns, topics, strict=True):
            self.conns[t] = connmap[(c.id, owner)]
            self.convert[t] = convmap[t.msgtype]


class _Reader:
    """What rosbags' converter asks of the bag it reads: its kind and its types."""

    def __init__(self, is2: bool, typestore: Any) -> None:
        self.is2 = is2
        self.typestore = typestore


def _types(what: str, topics: list[KeptTopic], ros2: bool) -> Any:
    """A typestore of the types of ``topics`` (ROS 2 ones when ``ros2``), read from their
    definitions; a topic without one takes ROS's own type (Noetic, Humble) where ROS ships
    it, and is refused where it does not."""
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    default = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    types: dict[str, Any] = {}
    for t in topics:
        try:
            if t.schema_encoding == "ros2idl":
                sep = "=" * 80 + "\n"  # several IDL files, each after its name
                if not t.definition.startswith(sep):
                    types.update(get_types_from_idl(t.definition))
                for part in t.definition.split(sep)[1:]:
                    types.update(get_types_from_idl(part.split("\n", 1)[1]))
            elif t.definition:
                types.update(get_types_from_msg(t.definition, t.msgtype))
            elif t.msgtype in default.fielddefs:
                types.update(_closure(default, t.msgtype))
            else:
                raise InputError(
                    f"{what}: topic {t.topic!r} has no message definition and {t.msgtype} is "
                    "not a type ROS ships: its messages cannot be described in the bag"
                )
        except InputError:
            raise
        except Exception as exc:
            raise InputError(
                f"{what}: the message definition of topic {t.topic!r} ({t.msgtype}) cannot "
                f"be read: {exc}"
            ) from exc
    store = get_typestore(Stores.EMPTY)
    try:
        store.register(types)
    except Exception as exc:
        raise InputError(f"{what}: the kept topics' message definitions disagree: {exc}") from exc
    return store


def _closure(store: Any, msgtype: str) -> dict[str, Any]:
    """``msgtype``'s field definitions in ``store`` and those of every type it holds."""
    from rosbags.interfaces import Nodetype

    out: dict[str, Any] = {}
    todo = [msgtype]
    while todo:
        name = todo.pop()
        if name in out:
            continue
        out[name] = store.fielddefs[name]
        for _, desc in out[name][1]:
            sub = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
            if sub[0] == Nodetype.NAME:
                todo.append(sub[1])
    return out
