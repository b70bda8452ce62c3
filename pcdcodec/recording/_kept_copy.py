"""Kept topics copied from recordings into a new one, as ``recover`` and ``join`` write it:
the same channel descriptions (:class:`~pcdcodec.ros.kept.KeptTopic`), the messages' bytes and
times as stored, gathered into zstd chunks as the writer makes them, and the new file's seal
keys (``kept``, ``kept_digest``) made of what was copied (``docs/format.md``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from ..errors import DecodeError, InputError
from ..ros.kept import KeptMessage, KeptTopic
from . import _index as fmt
from ._kept import (
    SEAL_KEPT_KEYS,
    KeptChannels,
    KeptDigest,
    kept_channel_ids,
    stored_channel_ids,
    stored_topics_of,
)

__all__ = ["KeptCopy", "union_of", "without_kept"]


def union_of(indexes: Sequence[fmt.FileIndex], names: Sequence[str]) -> list[KeptTopic]:
    """The kept topics of several files (``names`` theirs, for messages): each description
    once, in the order first found. A topic kept with another type, definition or encoding in
    two files contradicts: :class:`~pcdcodec.InputError` naming both files. Connection facts
    (a ROS 1 publisher's caller id, QoS) may differ: each is a channel of its own, as in a bag.
    """
    out: list[KeptTopic] = []
    first: dict[tuple[str, str], tuple[KeptTopic, str]] = {}
    for index, name in zip(indexes, names, strict=True):
        for t in stored_topics_of(index):
            seen = first.setdefault((t.topic, t.message_encoding), (t, name))
            a = seen[0]
            if (a.msgtype, a.schema_encoding, a.definition, a.message_encoding) != (
                t.msgtype,
                t.schema_encoding,
                t.definition,
                t.message_encoding,
            ):
                what = (
                    f"type {a.msgtype} ({a.message_encoding}), {t.msgtype} ({t.message_encoding})"
                    if (a.msgtype, a.message_encoding) != (t.msgtype, t.message_encoding)
                    else "message definition"
                )
                raise InputError(
                    f"{name!r} cannot follow {seen[1]!r}: they keep topic {t.topic!r} with "
                    f"another {what}; every part must keep a topic alike"
                )
            if t not in out:
                out.append(t)
    return out


class KeptCopy:
    """The kept topics of the file being written, and the messages copied into them.

    ``topics`` are registered with :meth:`register`; :meth:`take` copies a message of a source
    file's kept channel (``channels``: that file's channel ids -> topics, from :meth:`source`)
    and writes a chunk when one is full; :meth:`finish` writes the rest and gives the seal keys.
    """

    def __init__(self, topics: Sequence[KeptTopic]) -> None:
        self.out = KeptChannels(topics) if topics else None
        self.channels: dict[int, KeptTopic] = {}
        #: Of the source being copied: its messages read, per topic, and their digest.
        self.read = KeptDigest()

    @classmethod
    def of(cls, index: fmt.FileIndex | None) -> KeptCopy:
        """The kept topics of the file of ``index`` (none for ``None``), to be copied."""
        return cls(stored_topics_of(index) if index is not None else [])

    def source(self, index: fmt.FileIndex) -> fmt.FileIndex:
        """Start copying the file of ``index``; returns ``index`` without its kept channels
        (the others are copied as they are)."""
        self.channels = stored_channel_ids(index)
        self.read = KeptDigest()
        return without_kept(index)

    def register(self, writer: Any) -> None:
        if self.out is not None:
            self.out.register(writer)

    def take(self, writer: Any, message: Any) -> bool:
        """Copy ``message`` (an MCAP message of the source) when it is a kept topic's; whether
        it was."""
        topic = self.channels.get(message.channel_id)
        if topic is None or self.out is None:
            return False
        data = bytes(message.data)
        self.read.note(topic.topic, message.log_time, message.publish_time, data)
        kept = KeptMessage(topic, int(message.log_time), data, int(message.publish_time))
        if self.out.add(kept):
            self.out.write(writer)
        return True

    def check_sealed(self, seal: dict[str, str] | None, what: str) -> None:
        """Compare the source's kept messages copied with its ``seal`` (a closed file's):
        :class:`~pcdcodec.DecodeError` naming ``what`` when they differ."""
        if seal is None:
            return
        sealed = {k: seal[k] for k in SEAL_KEPT_KEYS if k in seal}
        if self.read.seal() != sealed:
            raise DecodeError(
                f"{what}: its kept messages are not those sealed (per topic, sealed "
                f"{sealed.get('kept', '{}')}, found {json.dumps(self.read.counts)}); "
                "`pcdcodec verify` it"
            )

    def finish(self, writer: Any) -> dict[str, str]:
        """Write the messages still waiting; the new seal's kept keys."""
        if self.out is None:
            return {}
        self.out.write(writer)
        return self.out.digest.seal()

    def losses(self, seal: dict[str, str] | None) -> list[str]:
        """What of the source's kept messages was not copied, by topic, and why (said against
        its seal: a file without one, whose writer died, keeps what its written chunks hold)."""
        if not self.channels or seal is None:
            return []
        try:
            sealed = json.loads(seal.get("kept", "{}"))
            if not isinstance(sealed, dict):
                raise ValueError
        except ValueError:
            return [f"the seal's count of kept messages {seal.get('kept')!r} is not JSON"]
        found = self.read.counts
        out = [
            f"kept topic {topic}: {int(n) - found.get(topic, 0)} of {n} message(s) left out "
            "(in damaged chunks)"
            for topic, n in sorted(sealed.items())
            if isinstance(n, int) and found.get(topic, 0) < n
        ]
        if not out and self.read.seal().get("kept_digest") != seal.get("kept_digest"):
            out.append(
                "the kept messages do not match the seal's digest although their chunks' CRCs "
                "hold (changed or reordered): copied as found"
            )
        return out


def without_kept(index: fmt.FileIndex) -> fmt.FileIndex:
    """``index`` without its kept channels (and their schemas)."""
    import dataclasses

    kept = kept_channel_ids(index)
    channels = {c: ch for c, ch in index.channels.items() if c not in kept}
    schema_of = {c: s for c, s in index.channel_schema.items() if c in channels}
    used = set(schema_of.values())
    return dataclasses.replace(
        index,
        channels=channels,
        channel_schema=schema_of,
        schemas={s: v for s, v in index.schemas.items() if s in used},
    )
