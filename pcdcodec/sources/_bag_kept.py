"""The topics of a ROS bag that a recording keeps as they came (``docs/bags.md``).

Every topic whose messages are not made into frames (the depth, color or cloud topic read) is
kept: its connections become :class:`~pcdcodec.ros.kept.KeptTopic` channels, its messages
:class:`~pcdcodec.ros.kept.KeptMessage` items, read raw (never deserialized) in the bag's
order, unless the source was opened with ``keep_topics=False`` or patterns leave them out.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from ..errors import PcdcodecError
from ..ros import bagfile
from ..ros.kept import KeptMessage, KeptTopic, TopicFilter, kept_topic_of_connection

__all__ = ["BagKeptTopics"]


def _qos_yaml(conn: Any) -> str:
    qos = getattr(getattr(conn, "ext", None), "offered_qos_profiles", None)
    if not qos:
        return ""
    if isinstance(qos, str):
        return qos
    from rosbags.rosbag2.metadata import dump_qos_v8

    return str(dump_qos_v8(list(qos)))


class BagKeptTopics:
    """The kept-topic half of the bag readers (:class:`~pcdcodec.sources.rosbag.RosbagSource`,
    :class:`~pcdcodec.sources.realsense.RealSenseBagSource`)."""

    path: Any
    _reader: Any
    topic_filter: TopicFilter

    def _frame_topics(self) -> set[str]:
        """The topics whose messages become frames."""
        return {
            t
            for t in (
                getattr(self, "depth_topic", None),
                getattr(self, "color_topic", None),
                getattr(self, "cloud_topic", None),
            )
            if t
        }

    def _bag_connections(self) -> tuple[list[Any], bool]:
        """The bag's rosbags connections (their ids those of :func:`bagfile.open_reader`'s
        reader), and whether it is a ROS 2 bag: the open reader's, unless a reader says."""
        return list(self._reader.connections), bool(self._reader.is2)

    def _kept_connections(self) -> dict[int, KeptTopic]:
        found = getattr(self, "_kept_conns", None)
        if found is not None:
            return found  # type: ignore[no-any-return]
        frames = self._frame_topics()
        connections, ros2 = self._bag_connections()
        found = {
            c.id: kept_topic_of_connection(c, ros2, _qos_yaml(c) if ros2 else "")
            for c in connections
            if c.topic not in frames and self.topic_filter(c.topic)
        }
        self._kept_conns = found
        return found

    def kept_topics(self) -> list[KeptTopic]:
        """The bag's topics kept as they came, one per distinct connection description."""
        out: list[KeptTopic] = []
        for t in self._kept_connections().values():
            if t not in out:
                out.append(t)
        return out

    def kept_messages(
        self, start: int | None = None, stop: int | None = None
    ) -> Iterator[KeptMessage]:
        """The kept topics' messages in the bag's order, their bytes as stored; those logged
        from ``start`` and before ``stop`` (ns) where given (the bag's index skips the rest)."""
        conns = self._kept_connections()
        if not conns or (start is not None and stop is not None and stop <= start):
            return
        # A reader of its own: the frames are read from the bag at the same time.
        reader, tmp = bagfile.open_reader(self.path)
        try:
            wanted = [c for c in reader.connections if c.id in conns]
            for c, t, raw in reader.messages(connections=wanted, start=start, stop=stop):
                yield KeptMessage(conns[c.id], int(t), bytes(raw))
        except PcdcodecError:
            raise
        except Exception as exc:
            raise bagfile.bag_error(exc, self.path) from exc
        finally:
            reader.close()
            if tmp is not None:
                tmp.cleanup()
