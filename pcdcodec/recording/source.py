"""A recording as an input: its frames as a :class:`~pcdcodec.Source`, so that
:func:`pcdcodec.encode` writes them again with other codecs (``pcdcodec encode run.pcdc -o
train.pcdc --color av1:gop=1``).

:class:`RecordingSource` reads one camera of a ``.pcdc`` file through
:class:`~pcdcodec.Recording`, with every check the reader makes: depth exactly as stored
(uint16 or float32 with NaN, bit for bit), color decoded to RGB (encoded again, a lossy color
codec loses once more), timestamps, poses, the camera (intrinsics, depth scale, rate, frame
name, the color camera apart from depth) and the user metadata. :func:`recording_cameras`
opens every camera of a rig's file (format version 3) with its name and rig pose, so a rig
is written again as a rig. The reader registers itself as the source kind ``"recording"``
(:mod:`pcdcodec.recording`); this module loads when a recording is first opened as an input.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import DecodeError, InputError
from ..geometry.camera import as_intrinsics
from ..sources.base import InputStream, Source

if TYPE_CHECKING:
    from ..frame import Frame
    from ..ros.kept import KeptMessage, KeptTopic
    from ..sources.rig import CameraInput
    from .reader import Recording
    from .rig_reader import RigRecording

__all__ = ["RecordingSource", "recording_cameras"]


def _open(path: Path, threads: int | None) -> Recording | RigRecording:
    """The recording at ``path``: a :class:`~pcdcodec.Recording`, or a
    :class:`~pcdcodec.RigRecording` for a rig's file (as :func:`pcdcodec.open` reads)."""
    from .reader import Recording, SeveralCamerasError
    from .rig_reader import RigRecording

    try:
        return Recording(path, threads=threads)
    except SeveralCamerasError as rig:
        return RigRecording(path, index=rig.index, threads=threads)


class RecordingSource(Source):
    """The frames of one camera of a ``.pcdc`` recording, as stored.

    ``camera`` names the camera of a rig's file (it may be left out when the file has one);
    ``max_frames`` keeps the first frames (the kept topics' messages are all given, as a
    bag's); ``keep_topics``, ``include_topics`` and ``exclude_topics`` choose the recording's
    kept topics written again, as for a bag (:class:`~pcdcodec.sources.RosbagSource`);
    ``intrinsics`` and ``depth_scale`` replace what the recording says (the depth values stay
    as stored); ``threads`` is the reader's (see
    :class:`~pcdcodec.Recording`). Raises what opening the recording raises (a damaged file:
    :class:`~pcdcodec.DecodeError` naming it), :class:`~pcdcodec.DecodeError` for a file
    without its index (cut short, or its writer did not finish: ``pcdcodec recover`` first),
    and :class:`~pcdcodec.InputError` for a rig's file without ``camera`` or a camera it does
    not hold.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        camera: str | None = None,
        max_frames: int | None = None,
        intrinsics: Any = None,
        depth_scale: float | None = None,
        threads: int | None = None,
        keep_topics: bool = True,
        include_topics: Any = None,
        exclude_topics: Any = None,
        _rig: RigRecording | None = None,
    ) -> None:
        from ..ros.kept import TopicFilter
        from .rig_reader import RigRecording

        self.path = Path(path)
        self.topic_filter = TopicFilter.of(include_topics, exclude_topics, keep_topics)
        if max_frames is not None and (
            isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 1
        ):
            raise InputError(f"max_frames must be an int of at least 1, got {max_frames!r}")
        self.max_frames = max_frames
        opened: Recording | RigRecording = _rig if _rig is not None else _open(self.path, threads)
        #: Whether this source opened the file's reader (else only its camera's is its own).
        self._owns = _rig is None
        self._file = opened
        try:
            if not opened.index.indexed:
                # Written again, the frames before the cut would pass for the whole recording.
                # (Said first: a rig's file cut short is not cured by naming a camera.)
                cut = opened.index.truncated_at
                where = f" (it ends inside a record at byte offset {cut})" if cut else ""
                raise DecodeError(
                    f"{str(self.path)!r} has no index{where}: it was cut short, or its writer "
                    "did not finish; `pcdcodec recover` copies the frames it can read into a "
                    "complete recording, which can then be encoded again"
                )
            if isinstance(opened, RigRecording) and camera is None and len(opened.cameras) > 1:
                raise InputError(
                    f"{str(self.path)!r} holds {len(opened.cameras)} cameras "
                    f"({', '.join(opened.camera_names)}): pass camera=NAME to read one, or "
                    "re-encode them all as a rig (pcdcodec.encode_rig, or `pcdcodec encode`)"
                )
            rec: Recording = opened.frames(camera)
            lost = rec.color_missing
            if lost:
                # A recording with color takes a color image with every frame.
                shown = ", ".join(str(i) for i in lost[:8]) + (", ..." if len(lost) > 8 else "")
                raise DecodeError(
                    f"{str(self.path)!r} holds {len(lost)} frame(s) that `pcdcodec recover` "
                    f"kept without their color, lost to damage (frames {shown}): they cannot "
                    "be written again into a recording with color; read them with "
                    "pcdcodec.open() (their color is None)"
                )
        except BaseException:
            if self._owns:
                opened.close()
            raise
        self._rec = rec
        #: The camera of a rig's file this reads (``None``: a one-camera file).
        self.camera = rec.camera
        own = rec.intrinsics
        self.intrinsics = (
            own
            if intrinsics is None
            else as_intrinsics(intrinsics, "intrinsics", own.width, own.height)
        )
        self.depth_scale = rec.depth_scale if depth_scale is None else float(depth_scale)
        self.color_intrinsics = rec.color_intrinsics
        self.depth_to_color = rec.depth_to_color
        self.has_color = rec.color_codec is not None
        self.fps = rec.fps
        self.frame_id = rec.frame_id
        self.metadata = dict(rec.metadata)
        if self.camera is not None:
            # A rig's metadata is the file's: this camera's own keys carry its name in front.
            prefix = f"{self.camera}."
            self.metadata = {
                k[len(prefix) :]: v for k, v in rec.metadata.items() if k.startswith(prefix)
            }
        self.intrinsics_origin = "input" if intrinsics is None else "given"
        self.depth_scale_origin = "input" if depth_scale is None else "given"

    @property
    def recording(self) -> Recording:
        """The reader of the camera's frames."""
        return self._rec

    @property
    def codecs(self) -> dict[str, dict[str, Any] | None]:
        """The codecs the recording was written with."""
        return self._rec.codecs

    def __len__(self) -> int:
        n = len(self._rec)
        return n if self.max_frames is None else min(n, self.max_frames)

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Frame]:
        """Frames ``start`` to ``stop`` (exclusive), decoded from the keyframe before
        ``start``; each color packet is decoded once."""
        n = len(self)
        stop = n if stop is None else min(stop, n)
        start = max(start, 0)
        if start >= stop:
            return iter(())
        return itertools.islice(self._rec._in_order(start), stop - start)

    def kept_topics(self) -> list[KeptTopic]:
        """The recording's kept topics (those the patterns choose), as it describes them, and
        the channels of its camera topics (their envelopes), copied as stored so the new file
        gives the camera messages back as this one does."""
        from ._kept import kept_topics_of

        topics = [*self._rec.kept_topics, *kept_topics_of(self._rec.index, camera=True)]
        return [t for t in topics if self.topic_filter(t.topic)]

    def kept_messages(self) -> Iterator[KeptMessage]:
        """Their messages, bytes as the input held them (camera channels' as stored), in log
        time order: each chunk's CRC checked, and the whole against the recording's seal
        (:meth:`~pcdcodec.Recording.kept_messages`)."""
        import heapq

        chosen = self.kept_topics()
        names = {t.topic for t in chosen if not t.camera}
        cameras = {t.topic for t in chosen if t.camera}
        kept = self._rec.kept_messages(names) if names else iter(())
        camera = (m for m in self._rec._read_kept(camera=True) if m.topic.topic in cameras)
        return heapq.merge(kept, camera, key=lambda m: m.log_time)

    def input_streams(self) -> list[InputStream]:
        """Of a rig's file, its cameras (``camera NAME``, with their frame counts); of a
        one-camera recording, its kept topics (with their messages)."""
        from .rig_reader import RigRecording

        if not isinstance(self._file, RigRecording):
            counts = self._rec.kept_counts()
            types = {t.topic: t.msgtype for t in self._rec.kept_topics}
            return [InputStream(n, types[n], counts.get(n, 0)) for n in sorted(types)]
        rig = self._file
        names = sorted(rig.camera_names)
        return [InputStream(f"camera {n}", "camera", len(rig.frames(n))) for n in names]

    def recorded_streams(self) -> set[str]:
        """This camera, of a rig's file."""
        return {f"camera {self.camera}"} if self.camera is not None else set()

    def describe(self) -> dict[str, Any]:
        """As :meth:`Source.describe`, with the codecs the recording was written with, its
        rate, the camera of a rig's file, and a note on what happens to the color."""
        out = super().describe()
        out["codecs"] = self.codecs
        out["fps"] = self.fps
        color = self.codecs.get("color")
        if color is not None:
            out["notes"] = [
                f"color decoded from the recording's {color.get('id')} and encoded again "
                "(a lossy color codec loses once more); depth as stored, bit for bit"
            ]
        if self.camera is not None:
            out["camera"] = self.camera
        return out

    def close(self) -> None:
        """Close the recording (of a rig's file opened for all its cameras, this camera's
        reader)."""
        if self._owns:
            self._file.close()
        else:
            self._rec.close()


def recording_cameras(
    path: str | os.PathLike[str], **options: Any
) -> tuple[list[CameraInput], str] | None:
    """A :class:`~pcdcodec.sources.rig.CameraInput` per camera of the rig's file at ``path``,
    named and placed as recorded, with their frame names and the file's metadata (the keys
    that name no camera as the rig's own), and the rig frame; ``None`` for a one-camera
    recording. ``options`` go to each camera's :class:`RecordingSource` (``max_frames``, ...).
    """
    from ..sources.rig import CameraInput
    from .rig_reader import RigRecording

    if "camera" in options:
        raise InputError("camera= picks one camera; a rig's file read as a rig gives them all")
    threads = options.pop("threads", None)
    opened = _open(Path(path), threads)
    if not isinstance(opened, RigRecording):
        opened.close()
        return None
    try:
        names = opened.camera_names
        own = {
            k: v
            for k, v in opened.metadata.items()
            if not any(k.startswith(f"{name}.") for name in names)
        }
        cams = []
        for name in names:
            source = RecordingSource(path, camera=name, _rig=opened, **options)
            cams.append(
                CameraInput(
                    name,
                    source,
                    rig_pose=opened.rig_poses[name].copy(),
                    pose_from=f"{str(Path(path))!r} (recorded)",
                    frame_id=opened.cameras[name].frame_id,
                    rig_metadata=own,
                )
            )
    except BaseException:
        opened.close()
        raise
    # Each camera's source closes its camera's reader; closing them all closes the file.
    return cams, opened.rig_frame_id
