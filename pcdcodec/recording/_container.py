"""The container side of a writer: the MCAP file a recording's encoded frames go into.

:class:`Container` takes what the codecs made (color packets, depth bytes) and writes the
messages, the frame digests and, on closing, the seal (``docs/format.md``). It never sees an
image and checks nothing the writer checked: it runs on the writer's one writing thread.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from ..color.base import Packet
from ..errors import InputError, PcdcodecError
from ..ros.foxglove import (
    CAMERA_CALIBRATION,
    CAMERA_CALIBRATION_SCHEMA,
    COMPRESSED_VIDEO,
    COMPRESSED_VIDEO_SCHEMA,
    FRAME_TRANSFORM,
    FRAME_TRANSFORM_SCHEMA,
    CompressedVideo,
)
from ..ros.kept import KeptMessage
from . import _header as header
from . import _index as fmt
from ._kept import KeptChannels


class SharedFile:
    """The file the cameras of a rig write into together (format version 3): its MCAP writer,
    the lock each camera holds while writing, and the first failure, which stops them all."""

    def __init__(self, file: IO[bytes], writing: Path) -> None:
        self.file = file
        self.writing = writing
        self.mcap: Any = None
        self.lock = threading.Lock()
        self.failures: list[BaseException] = []


class Container:
    """Writes a recording's records and messages into an open file, in order.

    A message that fails part way leaves MCAP's writer holding part of a record: from then on
    (:attr:`broken`) nothing more is written, and the file is left unfinished (every frame
    before stays readable) rather than sealed and damaged.
    """

    def __init__(
        self,
        file: IO[bytes],
        writing: Path,
        settings: header.Settings,
        *,
        video_format: str | None,
        world_frame_id: str,
        camera: str | None = None,
        shared: SharedFile | None = None,
        kept: KeptChannels | None = None,
    ) -> None:
        self.file = file
        self.writing = writing
        self.settings = settings
        #: The Foxglove video format of the color codec (its packets then go in
        #: CompressedVideo messages), or ``None`` (raw packets).
        self.video_format = video_format
        #: The frame the poses are given in (their ``FrameTransform`` parent).
        self.world_frame_id = world_frame_id
        #: The camera's name in a file of several (its topics are ``/<camera>/...`` and its
        #: seal its own), or ``None`` for a one-camera file.
        self.camera = camera
        #: The file this camera shares with others, or ``None`` when it has the file alone.
        self.shared = shared
        #: Held while writing: the cameras of one file share its MCAP writer.
        self.lock = shared.lock if shared is not None else threading.Lock()
        self._failures: list[BaseException] = shared.failures if shared is not None else []
        self.mcap: Any = None
        self.channels: dict[str, int] = {}
        self.sequence = 0
        self.sealer = fmt.Sealer()
        # Frames count as complete once their depth and their color packet are both written.
        self.depth_written: deque[int] = deque()
        self.color_written: set[int] = set()
        # The color packets of the open digest group: readable once its digest is written.
        self.group_pts: list[int] = []
        self.frames_complete = 0
        self.frames_written = 0
        self.bytes_color = 0
        self.bytes_depth = 0
        self.poses_written = 0
        #: The kept topics' channels (format version 4), or ``None``.
        self.kept = kept

    @property
    def broken(self) -> BaseException | None:
        """The error that stopped writing to the file (by any camera of it), or ``None``."""
        return self._failures[0] if self._failures else None

    def topic(self, topic: str) -> str:
        """Where this camera writes what a one-camera file writes on ``topic``."""
        return topic if self.camera is None else fmt.camera_topic(topic, self.camera)

    def start(self, user: dict[str, str]) -> None:
        """Write the file's header and metadata records."""
        self.mcap = header.start_mcap(self.file)
        for name, data in header.records(self.settings, user).items():
            self.mcap.add_metadata(name, data)
        if self.kept is not None:
            self.kept.register(self.mcap)
        self.file.flush()

    def start_streams(
        self, height: int, width: int, timestamp: int, extradata: bytes | None
    ) -> None:
        """Register the channels and write the cameras, at the first frame's ``timestamp``."""
        s = self.settings
        mcap = self.mcap
        ch, cw = s.color_shape
        if s.color_codec is not None:
            video_format = self.video_format
            meta = header.color_channel(cw, ch, s.color_codec, extradata, video_format)
            if video_format:
                sid = mcap.register_schema(COMPRESSED_VIDEO, "ros2msg", COMPRESSED_VIDEO_SCHEMA)
                self.channels["color"] = mcap.register_channel(
                    self.topic(fmt.TOPIC_COLOR), "cdr", sid, meta
                )
            else:
                self.channels["color"] = mcap.register_channel(
                    self.topic(fmt.TOPIC_COLOR), fmt.ENCODING_COLOR, 0, meta
                )
            self.channels["key"] = mcap.register_channel(
                self.topic(fmt.TOPIC_KEYFRAMES), fmt.ENCODING_KEYFRAME, 0, {}
            )
        self.channels["depth"] = mcap.register_channel(
            self.topic(fmt.TOPIC_DEPTH),
            fmt.ENCODING_DEPTH,
            0,
            header.depth_channel(width, height, s.depth_codec, s.depth_scale),
        )
        self.channels["digest"] = mcap.register_channel(
            self.topic(fmt.TOPIC_FRAME_DIGEST), fmt.ENCODING_FRAME_DIGEST, 0, {}
        )
        sid = mcap.register_schema(CAMERA_CALIBRATION, "ros2msg", CAMERA_CALIBRATION_SCHEMA)
        cal = self.channels["cal"] = mcap.register_channel(
            self.topic(fmt.TOPIC_CALIBRATION), "cdr", sid, {}
        )
        mcap.add_message(
            cal, timestamp, header.calibration(s.intrinsics, s.frame_id, timestamp), timestamp
        )
        self.sealer.note(fmt.TOPIC_CALIBRATION, timestamp)
        if s.color_intrinsics is not None and s.depth_to_color is not None:
            color_frame = f"{s.frame_id}_color"
            ccal = mcap.register_channel(self.topic(fmt.TOPIC_COLOR_CALIBRATION), "cdr", sid, {})
            message = header.calibration(s.color_intrinsics, color_frame, timestamp)
            mcap.add_message(ccal, timestamp, message, timestamp)
            self.sealer.note(fmt.TOPIC_COLOR_CALIBRATION, timestamp)
            ext = mcap.register_channel(
                self.topic(fmt.TOPIC_EXTRINSICS), "cdr", self._transform_schema(), {}
            )
            pose = header.extrinsics(s.depth_to_color)
            message = header.transform(pose, timestamp, s.frame_id, color_frame)
            mcap.add_message(ext, timestamp, message, timestamp)
            self.sealer.note(fmt.TOPIC_EXTRINSICS, timestamp)

    def _transform_schema(self) -> int:
        if "transform_schema" not in self.channels:
            self.channels["transform_schema"] = self.mcap.register_schema(
                FRAME_TRANSFORM, "ros2msg", FRAME_TRANSFORM_SCHEMA
            )
        return self.channels["transform_schema"]

    def to_file(self, step: Callable[[], None]) -> None:
        """Run ``step``, which writes to the file; an error in it stops all writing."""
        if self.broken is not None:
            raise PcdcodecError(
                f"{str(self.writing)!r} is not written further: writing it failed before "
                f"({self.broken!r})"
            ) from self.broken
        try:
            with self.lock:
                step()
        except BaseException as exc:
            self._failures.append(exc)
            raise

    # -- frames ----------------------------------------------------------------------------

    def write_packets(self, packets: list[Packet]) -> None:
        """Write color packets, in decode order."""
        messages = self._color_messages(packets)
        self.to_file(lambda: self._write_color(messages))

    def _color_messages(self, packets: list[Packet]) -> list[tuple[Packet, int, bytes]]:
        """Each packet with the publish time and data of its message, made before any is
        written (a packet that fails leaves no message of its group half written)."""
        video_format = self.video_format
        frame_id = self.settings.frame_id
        out = []
        for packet in packets:
            data = (
                CompressedVideo(packet.pts, frame_id, packet.data, video_format).encode()
                if video_format
                else bytes(packet.data)
            )
            # B-frames give the first packets decoding times before the first frame; MCAP times
            # are unsigned, so those are stored as 0 (decoders only need the order).
            out.append((packet, max(packet.dts, 0), data))
        return out

    def _write_color(self, messages: list[tuple[Packet, int, bytes]]) -> None:
        mcap = self.mcap
        for packet, dts, data in messages:
            if packet.keyframe:
                mcap.add_message(self.channels["key"], packet.pts, b"", dts, self.sequence)
                self.sealer.note(fmt.TOPIC_KEYFRAMES, packet.pts)
            mcap.add_message(self.channels["color"], packet.pts, data, dts, self.sequence)
            self.sealer.note(fmt.TOPIC_COLOR, packet.pts)
            self.sealer.packet(packet.pts, dts, packet.keyframe, data)
            self.sequence += 1
            self.bytes_color += len(packet.data)
            self.group_pts.append(packet.pts)

    def write_frame(
        self,
        timestamp: int,
        data: bytes,
        pose: npt.NDArray[np.float64] | None,
        stamps: tuple[int, int] | None = None,
    ) -> None:
        """Write the rest of a frame after its color packets: depth, pose, the images' own
        times (``stamps``: color's and depth's, where either is not the frame's) and digest."""
        self.to_file(lambda: self._write_frame(timestamp, data, pose, stamps))

    def _write_frame(
        self,
        timestamp: int,
        data: bytes,
        pose: npt.NDArray[np.float64] | None,
        stamps: tuple[int, int] | None,
    ) -> None:
        s = self.settings
        self.mcap.add_message(
            self.channels["depth"], timestamp, data, timestamp, self.frames_written
        )
        self.sealer.note(fmt.TOPIC_DEPTH, timestamp)
        self.bytes_depth += len(data)
        pose_digest = fmt.NO_POSE
        if pose is not None:
            if "pose" not in self.channels:
                self.channels["pose"] = self.mcap.register_channel(
                    self.topic(fmt.TOPIC_POSE), "cdr", self._transform_schema(), {}
                )
                self.channels["pose_matrix"] = self.mcap.register_channel(
                    self.topic(fmt.TOPIC_POSE_MATRIX), fmt.ENCODING_POSE_MATRIX, 0, {}
                )
            msg = header.transform(pose, timestamp, self.world_frame_id, s.frame_id)
            self.mcap.add_message(self.channels["pose"], timestamp, msg, timestamp)
            exact = header.pose_matrix(pose)
            self.mcap.add_message(self.channels["pose_matrix"], timestamp, exact, timestamp)
            self.sealer.note(fmt.TOPIC_POSE, timestamp)
            self.sealer.note(fmt.TOPIC_POSE_MATRIX, timestamp)
            pose_digest = fmt.data_digest(msg, exact)
            self.poses_written += 1
        if stamps is not None:
            if "stamps" not in self.channels:
                self.channels["stamps"] = self.mcap.register_channel(
                    self.topic(fmt.TOPIC_STAMPS), fmt.ENCODING_STAMPS, 0, {}
                )
            own = fmt.STAMPS_RECORD.pack(*stamps)
            self.mcap.add_message(self.channels["stamps"], timestamp, own, timestamp)
            self.sealer.note(fmt.TOPIC_STAMPS, timestamp, own)
        # Last of the frame: the digests of the color packets written since the previous
        # frame's (its group), of its depth and of its pose; the frame is readable from here.
        record = self.sealer.frame_record(data, pose_digest)
        self.mcap.add_message(
            self.channels["digest"], timestamp, record, timestamp, self.frames_written
        )
        self.sealer.note(fmt.TOPIC_FRAME_DIGEST, timestamp)
        self.color_written.update(self.group_pts)
        self.group_pts.clear()
        self.frames_written += 1
        self.depth_written.append(timestamp)
        self._count_complete()
        self.file.flush()

    def _count_complete(self) -> None:
        while self.depth_written and (
            self.settings.color_codec is None or self.depth_written[0] in self.color_written
        ):
            self.color_written.discard(self.depth_written.popleft())
            self.frames_complete += 1

    # -- kept topics -----------------------------------------------------------------------

    def add_kept(self, message: KeptMessage) -> None:
        """Take a message of a kept topic; a chunk's worth is written as one zstd chunk."""
        kept = self.kept
        if kept is None:
            raise InputError(
                f"this recording keeps no other topics; open it with kept_topics to keep "
                f"{message.topic.topic!r}"
            )
        if kept.add(message):
            self.to_file(lambda: kept.write(self.mcap))

    # -- closing ---------------------------------------------------------------------------

    def seal(self) -> None:
        """Write the kept messages still waiting, then the seal: what the file holds, and the
        digest of the packets after the last frame's digest (the encoder's flush)."""
        name = fmt.SEAL_NAME if self.camera is None else fmt.camera_seal(self.camera)
        record = self.sealer.seal()
        if self.kept is not None:
            self.kept.drain()
            self.kept.write(self.mcap)
            record.update(self.kept.digest.seal())
        self.mcap.add_metadata(name, fmt.seal(name, record))
        self.color_written.update(self.group_pts)
        self.group_pts.clear()
        self._count_complete()
