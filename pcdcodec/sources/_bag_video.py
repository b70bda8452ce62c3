"""Encoded video in a bag passed through undecoded: its packets grouped with the depth images
they go with (:meth:`pcdcodec.sources.rosbag.RosbagSource.encoded_frames`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from functools import partial
from typing import Any

from ..color.base import Packet
from ..errors import InputError
from ..ros import messages as rm
from ..ros.topics import VIDEO_TYPES
from ..sync import Synchronizer


def paired_packets(
    messages: Iterable[tuple[Any, int, Any]],
    depth_topic: str,
    video_topic: str,
    *,
    stamp: Callable[[Any, int, str], int],
    decode: Callable[..., Any],
    stats: Any,
    max_difference: int,
    max_frames: int | None,
) -> Iterator[tuple[str, list[Packet], Any, int]]:
    """``(video_format, packets, depth, timestamp)`` per depth image paired with a video packet.

    ``messages`` are ``(connection, log time, message)`` of the depth and video topics in bag
    order; ``stamp`` gives a message's header stamp and ``decode(msg, ts=...)`` a depth image.
    Each video message is one packet, paired with a depth image by stamp as images are (the
    rule of :mod:`pcdcodec.sync`); the paired packet takes the depth's stamp, and packets
    without a depth partner are kept (later packets may need them to decode) and go with the
    next frame, at their own stamps. ``stats`` (frames, out of order, dropped) is kept up to
    date as frames are given.
    """
    sync: Synchronizer[Any, Any] = Synchronizer(max_difference=max_difference)
    waiting: list[tuple[int, bytes, bool]] = []  # video packets not yet written
    last = {"depth": -1, "video": -1}
    fmt_seen: str | None = None

    def groups(ready: list[Any]) -> Iterator[tuple[str, list[Packet], Any, int]]:
        for cts, _, dts, dmsg in ready:
            group = []
            while waiting and waiting[0][0] <= cts:
                ts, data, key = waiting.pop(0)
                pts = dts if ts == cts else ts
                group.append(Packet.create(data, pts, pts, key))
            depth = decode(dmsg, ts=dts)
            stats.frames += 1
            assert fmt_seen is not None
            yield fmt_seen, group, depth, dts

    def count_drops() -> None:
        stats.dropped_color = len(sync.dropped_color)
        stats.dropped_depth = len(sync.dropped_depth)

    for conn, t, msg in messages:
        role = "depth" if conn.topic == depth_topic else "video"
        ts = stamp(msg, t, conn.topic)
        if ts <= last[role]:
            stats.out_of_order += 1
            continue
        last[role] = ts
        if role == "video":
            fmt, data, key = rm.video_packet(msg, video_topic)
            if fmt_seen is not None and fmt != fmt_seen:
                raise InputError(f"video topic {video_topic!r} changes from {fmt_seen} to {fmt}")
            fmt_seen = fmt
            waiting.append((ts, data, key))
            ready = sync.add_color(ts, None)
        else:
            ready = sync.add_depth(ts, msg)
        count_drops()
        yield from groups(ready)
        if max_frames is not None and stats.frames >= max_frames:
            return
    yield from groups(sync.flush())
    count_drops()


class BagVideo:
    """The pass-through half of :class:`~pcdcodec.sources.rosbag.RosbagSource`: encoded video
    topics read as packets, undecoded."""

    _reader: Any
    path: Any
    mode: str
    max_difference: int
    max_frames: int | None
    color_topic: str | None
    _depth_conn: Any
    stats: Any
    _conn: Callable[..., Any]
    _messages: Callable[..., Any]
    _stamp: Callable[..., Any]
    _decode: Callable[..., Any]
    _new_stats: Callable[[], Any]

    def video_topics(self) -> list[str]:
        """Topics holding encoded video (Foxglove CompressedVideo, ffmpeg_image_transport)."""
        return [c.topic for c in self._reader.connections if c.msgtype in VIDEO_TYPES]

    def encoded_frames(self, video_topic: str | None = None) -> Iterator[tuple[str, Any, Any, int]]:
        """Frames whose color is the bag's encoded video, not decoded: ``(video_format,
        packets, depth, timestamp)`` for :meth:`pcdcodec.RecordingWriter.write_encoded`.

        Each video message is one packet, paired with a depth image by stamp as images are.
        The paired packet takes the depth's stamp; packets without a depth partner are kept
        (later packets may need them to decode) and go with the next frame, at their own
        stamps. Raises :class:`~pcdcodec.InputError` without a video topic or for a format
        other than h264/h265.
        """
        topics = self.video_topics()
        if video_topic is None:
            if not topics:
                raise InputError(
                    f"bag {str(self.path)!r} has no encoded video topic (foxglove_msgs/"
                    "CompressedVideo or ffmpeg_image_transport_msgs/FFMPEGPacket)"
                )
            video_topic = topics[0]
        vconn = self._conn(video_topic, "video")
        if vconn.msgtype not in VIDEO_TYPES:
            raise InputError(f"video topic {video_topic!r} is a {vconn.msgtype}")
        if self.mode != "images":
            raise InputError("pass-through pairs video with depth images, not with clouds")
        self.color_topic = video_topic
        self.stats = self._new_stats()
        yield from paired_packets(
            self._messages([self._depth_conn, vconn]),
            self._depth_conn.topic,
            video_topic,
            stamp=self._stamp,
            decode=partial(self._decode, conn=self._depth_conn, role="depth"),
            stats=self.stats,
            max_difference=self.max_difference,
            max_frames=self.max_frames,
        )
