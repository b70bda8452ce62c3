"""Giving the bag back: a recording made from a ROS bag written out as a bag that ROS tools play
as the original (``docs/bags.md``, "Giving the bag back").

:func:`~pcdcodec.convert.rosbag.export_bag` writes, beside the camera, every topic the recording
kept (:mod:`pcdcodec.ros.keptwriter`: each with its own connection, byte for byte into a bag of
its kind, converted by rosbags' rules into the other kind), merged by log time:

* where the recording gives its camera topics back as they came (``camera_messages()``: the
  depth and color topics with their original types, connection facts, bytes and log times),
  those are merged in with the kept topics, and the bag holds the original's topics only;
* otherwise the camera topics are built anew from the frames (as for any recording), under
  the names the recording says its input's camera topics had (``ros_depth_topic``,
  ``ros_color_topic``, ``ros_info_topic``, ``ros_cloud_topic``), a topic the recording kept
  (its CameraInfo, ``/tf``, ``/tf_static``) is not written a second time.

A bag comes back as the kind it came in (``to="rosbag"``): the recording notes the input's kind
(``bag_format``, ``bag_storage``, :func:`pcdcodec.ros.bagfile.bag_kind`).
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Iterator
from typing import Any

from ..errors import InputError
from ..ros.bagfile import FORMAT_KEY, STORAGE_KEY
from ..ros.bagwriter import BagWriter
from ..ros.kept import KeptMessage, KeptTopic
from ..ros.keptwriter import KeptConnections

__all__ = [
    "AS_IT_CAME",
    "FORMATS",
    "STORAGES",
    "BagBack",
    "bag_kind",
    "merge_by_time",
]

FORMATS = ("rosbag1", "rosbag2")
STORAGES = ("mcap", "sqlite3")
#: ``to``: the kind of bag the recording's input was (ROS 1 for a recording of no bag).
AS_IT_CAME = "rosbag"
#: image_transport's suffixes of a camera topic's compressed forms.
_TRANSPORTS = ("/compressedDepth", "/compressed")
#: The camera topics an export builds (attributes of its camera's export).
_NAMES = ("t_depth", "t_cdepth", "t_color", "t_dinfo", "t_cinfo", "t_cloud")


def bag_kind(to: str, storage: str | None, metadata: dict[str, str]) -> tuple[str, str]:
    """``(format, storage)`` of the bag to write: ``to`` ``"rosbag"`` is the kind the
    recording's input was (``rosbag1`` for a recording of anything else), a ``storage`` of
    ``None`` the input's storage (``mcap`` where it had none)."""
    if to == AS_IT_CAME:
        to = metadata.get(FORMAT_KEY, "rosbag1")
        to = to if to in FORMATS else "rosbag1"
    if storage is None:
        storage = metadata.get(STORAGE_KEY, "mcap")
        storage = storage if storage in STORAGES else "mcap"
    return to, storage


def merge_by_time(first: Iterator[Any], second: Iterator[Any], key: Callable[[Any], int]) -> Any:
    """Two streams, each in time order, merged by ``key`` (``first``'s item first on a tie);
    one item of each is held at a time."""
    return heapq.merge(first, second, key=key)


def base_topic(topic: str) -> str:
    """A camera topic without its image_transport suffix (``/compressed``, ...)."""
    for suffix in _TRANSPORTS:
        if topic.endswith(suffix):
            return topic[: -len(suffix)]
    return topic


def info_topic(image_topic: str) -> str:
    """The CameraInfo topic beside an image topic, as image_transport names it."""
    return base_topic(image_topic).rsplit("/", 1)[0] + "/camera_info"


class BagBack:
    """What the export of a recording with kept topics writes beside the frames: the kept
    messages, and the recording's camera messages where it gives them back as they came."""

    def __init__(self, rec: Any, what: str) -> None:
        self.rec = rec
        self.what = what
        self.metadata: dict[str, str] = dict(rec.metadata)
        self.topics: list[KeptTopic] = list(rec.kept_topics)
        self.kept_names = {t.topic for t in self.topics}
        meta = self.metadata
        #: The topic whose messages are the frames (counted as frames written).
        self.frame_topic = meta.get("ros_depth_topic") or meta.get("ros_cloud_topic")
        self.camera: Iterator[KeptMessage] | None = None
        given = getattr(rec, "camera_messages", None)
        if callable(given):
            messages = iter(given())
            first = next(messages, None)
            if first is not None:
                self.camera = itertools.chain([first], messages)
        self.conns: KeptConnections | None = None
        self._notes: list[str] = []

    @classmethod
    def of(cls, rec: Any, what: str) -> BagBack | None:
        """The kept side of exporting ``rec``; ``None`` when it keeps no topic."""
        if not getattr(rec, "kept_topics", None):
            return None
        return cls(rec, what)

    @property
    def as_recorded(self) -> bool:
        """Whether the camera topics come back as they came (not built anew)."""
        return self.camera is not None

    def defaults(
        self,
        images: bool | None,
        camera_info: bool | None,
        cloud: bool | None,
        compressed_depth: bool | None,
    ) -> tuple[bool, bool, bool, bool]:
        """``images``, ``camera_info``, ``cloud`` and ``compressed_depth`` where not given: the
        camera topics the input had (CameraInfo where it had a camera info topic, depth images
        as compressedDepth where its depth topic was). Where the camera topics come back as
        they came, options that build them anew are refused."""
        asked = [
            name
            for name, value in (
                ("images=False", images is False),
                ("cloud", cloud),
                ("compressed_depth", compressed_depth),
            )
            if value
        ]
        if self.as_recorded and asked:
            raise InputError(
                f"{self.what} gives its camera topics back as they came; {', '.join(asked)} "
                "would build them anew: pass kept=False (--no-kept) to export the camera alone, "
                "built from its frames"
            )
        meta = self.metadata
        depth = meta.get("ros_depth_topic", "")
        from_cloud = bool(meta.get("ros_cloud_topic")) and not depth
        return (
            (not from_cloud) if images is None else images,
            bool(meta.get("ros_info_topic")) if camera_info is None else camera_info,
            from_cloud if cloud is None else cloud,
            depth.endswith("/compressedDepth") if compressed_depth is None else compressed_depth,
        )

    def names(self, default: dict[str, Any], compressed_depth: bool, cloud: bool) -> dict[str, str]:
        """The topics of the camera built anew: those of ``default`` (``t_depth``,
        ``t_cdepth``, ``t_color``, ``t_dinfo``, ``t_cinfo``, ``t_cloud``), named as the
        input's were. Refuses an image or cloud topic that a kept topic's name takes."""
        meta = self.metadata
        names = {k: str(default[k]) for k in _NAMES}
        depth, color = meta.get("ros_depth_topic"), meta.get("ros_color_topic")
        if depth:
            names["t_depth"] = base_topic(depth)
            names["t_cdepth"] = base_topic(depth) + "/compressedDepth"
            names["t_dinfo"] = meta.get("ros_info_topic") or info_topic(depth)
            written = names["t_cdepth" if compressed_depth else "t_depth"]
            if written != depth:
                self._notes.append(f"depth topic {depth!r} is written as {written!r}")
        if color:
            names["t_color"] = base_topic(color)
            names["t_cinfo"] = info_topic(color)
            if names["t_color"] != color:
                self._notes.append(f"color topic {color!r} is written as {names['t_color']!r}")
        if meta.get("ros_cloud_topic"):
            names["t_cloud"] = meta["ros_cloud_topic"]
        written_keys = ["t_cdepth" if compressed_depth else "t_depth", "t_color"]
        for key in written_keys + (["t_cloud"] if cloud else []):
            if names[key] in self.kept_names:
                raise InputError(
                    f"{self.what}: the camera topic {names[key]!r} would be written over the "
                    "kept topic of that name; pass kept=False (--no-kept) to export the camera "
                    "alone"
                )
        return names

    def messages(self) -> Iterator[KeptMessage]:
        """The kept messages, and the camera's as they came where given, by log time."""
        kept = self.rec.kept_messages()
        if self.camera is None:
            return iter(kept)
        return iter(merge_by_time(kept, self.camera, key=_log_time))

    def open(self, bag: BagWriter) -> None:
        """Add the kept topics' connections to ``bag``, in the recording's order."""
        self.conns = KeptConnections(bag, what=self.what)
        self.conns.add(self.topics)

    def write(self, message: KeptMessage) -> bool:
        """Write ``message`` into the bag :meth:`open` opened; whether it is one of the frames
        (a camera message as it came, of the depth or cloud topic)."""
        assert self.conns is not None
        self.conns.write(message)
        name = message.topic.topic
        if self.camera is None or name in self.kept_names:
            return False
        return self.frame_topic is None or name == self.frame_topic

    def written_topics(self) -> list[str]:
        """The topics written as they came, in the order their connections were added."""
        conns = [] if self.conns is None else self.conns.conns
        return list(dict.fromkeys(t.topic for t in conns))

    def summary(self) -> dict[str, Any]:
        """``kept`` (messages written per kept topic), ``camera`` (``"as recorded"`` or
        ``"built anew"``) and ``notes`` (what converting the topics said)."""
        counts = {} if self.conns is None else self.conns.counts
        return {
            "kept": {t: n for t, n in counts.items() if t in self.kept_names},
            "camera": "as recorded" if self.as_recorded else "built anew",
            "notes": self._notes + ([] if self.conns is None else list(self.conns.notes)),
        }


def _log_time(message: KeptMessage) -> int:
    return message.log_time
