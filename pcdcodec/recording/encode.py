"""One call from any input to a recording: :func:`encode`."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import InputError
from ._header import writer_camera

__all__ = ["EncodeSummary", "encode"]


@dataclass
class EncodeSummary:
    """What :func:`encode` did: frames written, sizes, what the source dropped, and what of
    the input the recording does not hold (:attr:`left_out`)."""

    path: Path
    frames: int
    bytes: int
    bytes_color: int
    bytes_depth: int
    seconds: float
    source: dict[str, Any] = field(default_factory=dict)

    @property
    def fps(self) -> float:
        """Frames encoded per second of wall time."""
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def dropped(self) -> dict[str, int]:
        """Images the source dropped for lack of a partner, by stream (empty when it pairs
        nothing)."""
        value = self.source.get("dropped")
        return dict(value) if isinstance(value, dict) else {}

    @property
    def left_out(self) -> list[dict[str, Any]]:
        """The input's topics, tracks or files the recording does not hold (IMU, infrared,
        other cameras, device options, ...): ``name``, ``type`` and ``messages`` (``None``
        where the input's index does not say), as :attr:`pcdcodec.Source.left_out` lists."""
        value = self.source.get("left_out")
        return [dict(item) for item in value] if isinstance(value, list) else []

    @property
    def kept(self) -> list[dict[str, Any]]:
        """The input's other topics the recording keeps as they came: ``name``, ``type``,
        ``messages`` and ``bytes`` (as the input held them)."""
        value = self.source.get("kept")
        return [dict(item) for item in value] if isinstance(value, list) else []

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": str(self.path),
            "frames": self.frames,
            "bytes": self.bytes,
            "bytes_color": self.bytes_color,
            "bytes_depth": self.bytes_depth,
            "seconds": self.seconds,
            "fps": self.fps,
            "dropped": self.dropped,
            "left_out": self.left_out,
            "kept": self.kept,
            "source": self.source,
        }


def encode(
    src: Any,
    out: str | os.PathLike[str],
    *,
    color: Any = "h264",
    depth: Any = DEFAULT_DEPTH_CODEC,
    intrinsics: Any = None,
    depth_scale: float | None = None,
    fps: float | None = None,
    metadata: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
    passthrough: bool | str = False,
    override: bool = False,
    kept_images: str = "lossless",
    **source_options: Any,
) -> EncodeSummary:
    """Record any input into a ``.pcdc`` file: a :class:`~pcdcodec.Source`, or a path that
    :func:`pcdcodec.open_source` reads (RGB-D folder, ROS 1 or ROS 2 bag, ...).

    ``passthrough`` (``True`` or a topic name) records a bag's encoded video (Foxglove
    ``CompressedVideo`` or ffmpeg_image_transport packets, h264/h265) as it is, without
    decoding or re-encoding it; ``color`` is then ignored (see
    :meth:`~pcdcodec.sources.rosbag.RosbagSource.encoded_frames`).

    ``kept_images`` is how the kept image and organized cloud topics are stored:
    ``"lossless"`` (compressed, given back byte for byte; ``docs/bags.md``) or ``"raw"``.

    ``source_options`` go to :func:`~pcdcodec.open_source` (for bags: ``depth_topic``,
    ``color_topic``, ``info_topic``, ``cloud_topic``, ``max_frames``, ...).

    ``intrinsics`` (a :class:`~pcdcodec.CameraIntrinsics`, a dict or an intrinsics file) and
    ``depth_scale`` fill in what the input lacks: the input's own camera and depth scale
    (recorded, in its folder's files, or by its dataset's convention) win, and where a given
    value contradicts them the summary's ``source["camera_notes"]`` names both. With
    ``override=True`` they replace the input's own instead, and the notes say what was
    replaced (:class:`~pcdcodec.sources.CameraDefaults`). A source without color is recorded
    depth only. The source's metadata (topics, distortion) is kept in the recording. ``fps`` is the
    nominal frame rate; without it, the rate the source records (a recording's), else 30.
    A ``.pcdc`` recording is an input too: its frames are written again with the codecs
    given, depth exactly as stored, color decoded and encoded again.

    Raises :class:`~pcdcodec.InputError` when the source has no camera and none is given, and
    whatever the source and the writer raise; an interrupted encode leaves a readable file
    (see :class:`~pcdcodec.RecordingWriter`), a failed replacement leaves the old file.
    """
    from ..sources.base import CameraDefaults, Source, open_source, settle_camera
    from .writer import RecordingWriter

    given = None
    if intrinsics is not None or depth_scale is not None:
        # A camera given as a value is checked once, here; a file is read by the reader,
        # which knows the depth images' size for a bare 3 x 3 matrix.
        if intrinsics is not None and not isinstance(intrinsics, (str, os.PathLike)):
            intrinsics = writer_camera(intrinsics)
        given = CameraDefaults(
            intrinsics,
            depth_scale,
            origin="intrinsics=",
            depth_scale_origin="depth_scale=",
            override=override,
        )
    elif override:
        raise InputError("override=True needs intrinsics= or depth_scale= to replace the input's")
    if isinstance(src, Source):
        if source_options:
            raise InputError(
                f"source options {sorted(source_options)} apply to paths only; this source is "
                "already open"
            )
        source, owned = src, False
    else:
        source, owned = open_source(src, defaults=given, **source_options), True
    try:
        if given is not None and not owned:
            settle_camera(source, given)
        if source.intrinsics is None:
            raise InputError(
                f"no intrinsics for {str(source.path)!r}: pass intrinsics= (a CameraIntrinsics; "
                "on the command line --camera NAME, --intrinsics FILE or --fx --fy --cx --cy), "
                "or give the input a camera (camera.json, a CameraInfo topic)"
            )
        meta = {**source.metadata, **(metadata or {})}
        rate = fps if fps is not None else (source.fps if source.fps is not None else 30.0)
        target = Path(out)
        if target.exists() and not overwrite:
            raise InputError(f"{str(target)!r} already exists; pass overwrite=True to replace it")
        if target.is_dir():
            raise InputError(f"{str(target)!r} is a folder, not a file")
        if not target.parent.is_dir():
            raise InputError(
                f"the folder of the output {str(target)!r} does not exist; create "
                f"{str(target.parent)!r} first"
            )
        use_depth_codec = getattr(source, "use_depth_codec", None)
        if use_depth_codec is not None:  # images kept beside (an Azure Kinect's IR), lossless
            use_depth_codec(depth)
        # Written beside the final name and moved there once complete: a failed conversion
        # leaves nothing under the final name (and an older file there intact).
        from .._atomic import atomic_output  # not loaded by `import pcdcodec`

        with atomic_output(target) as partial:
            start = time.perf_counter()
            if passthrough:
                count, writer = _passthrough(
                    source, partial, passthrough, depth=depth, fps=rate, metadata=meta,
                    progress=progress, kept_images=kept_images,
                )  # fmt: skip
            else:
                with RecordingWriter(
                    partial,
                    intrinsics=source.intrinsics,
                    depth_scale=source.depth_scale,
                    color=color if source.has_color else None,
                    depth=depth,
                    fps=rate,
                    metadata=meta,
                    color_intrinsics=source.color_intrinsics,
                    depth_to_color=source.depth_to_color,
                    frame_id=source.frame_id or "camera",
                    kept_topics=source.kept_topics(),
                    kept_images=kept_images,
                ) as writer:
                    # Opened from the source: its camera is the recording's, checked once.
                    count = writer._write_source(source, progress)
            if count == 0:
                from ._inputs import no_frames_error  # (loaded when needed: import stays light)

                raise no_frames_error(source)
        seconds = time.perf_counter() - start
        info = source.describe()
        written = writer.kept_written
        for item in info.get("kept", []):
            item["messages"], item["bytes"] = written.get(item["name"], (0, 0))
        return EncodeSummary(
            target, count, target.stat().st_size, writer.bytes_color, writer.bytes_depth,
            seconds, info,
        )  # fmt: skip
    finally:
        if owned:
            source.close()


def _passthrough(
    source: Any,
    path: Path,
    topic: bool | str,
    *,
    depth: Any,
    fps: float,
    metadata: dict[str, Any],
    progress: Callable[[int], None] | None,
    kept_images: str = "lossless",
) -> tuple[int, Any]:
    from ..sources.rosbag import RosbagSource
    from .writer import RecordingWriter

    if not isinstance(source, RosbagSource):
        raise InputError(
            f"pass-through takes encoded video from ROS bags; {str(source.path)!r} is a "
            f"{type(source).__name__}"
        )
    writer: RecordingWriter | None = None
    count = 0
    try:
        for fmt, packets, image, ts in source.encoded_frames(
            topic if isinstance(topic, str) else None
        ):
            if writer is None:
                writer = RecordingWriter(
                    path,
                    intrinsics=source.intrinsics,
                    depth_scale=source.depth_scale,
                    color=fmt,
                    depth=depth,
                    fps=fps,
                    metadata={**metadata, "ros_video_topic": source.color_topic or ""},
                    kept_topics=source.kept_topics(),
                    kept_images=kept_images,
                )
            writer.write_encoded(packets, image, ts)
            count += 1
            if progress is not None:
                progress(count)
        if writer is not None:
            # The other topics, after the frames (their order among themselves is kept).
            for message in source.kept_messages():
                writer.write_message(message)
    finally:
        if writer is not None:
            writer.close()
    if writer is None:
        from ._inputs import no_frames_error

        raise no_frames_error(source)
    return count, writer
