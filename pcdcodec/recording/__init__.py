"""Recordings: one ``.pcdc`` file (MCAP) holding a color stream, a depth stream and the camera.

See ``docs/format.md`` for the layout and :func:`open` for use. A recording is also an input
(the source kind ``"recording"``, :mod:`.source`), so ``encode`` writes it again with other
codecs.
"""

from __future__ import annotations

import importlib
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, overload

from ..errors import InputError
from ..frame import Frame
from ..sources.base import read_magic, register_source
from ._index import FORMAT_VERSION, MAGIC, PROFILE
from .encode import EncodeSummary, encode
from .recover import recover

if TYPE_CHECKING:
    from .encode_rig import RigSummary, encode_rig
    from .reader import Recording
    from .rig import CameraSpec, RigWriter
    from .rig_reader import FrameSet, RigRecording
    from .verify import VerifyReport
    from .writer import RecordingWriter

#: Names whose modules load on first use, so that ``import pcdcodec`` stays light (the
#: reader and the writer bring their codecs' machinery).
_LAZY = {
    "CameraSpec": "pcdcodec.recording.rig",
    "RigSummary": "pcdcodec.recording.encode_rig",
    "encode_rig": "pcdcodec.recording.encode_rig",
    "FrameSet": "pcdcodec.recording.rig_reader",
    "RigRecording": "pcdcodec.recording.rig_reader",
    "RigWriter": "pcdcodec.recording.rig",
    "Recording": "pcdcodec.recording.reader",
    "RecordingWriter": "pcdcodec.recording.writer",
    "VerifyReport": "pcdcodec.recording.verify",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    if name in ("reader", "writer", "verify"):  # attributes once `import pcdcodec` loaded them
        return importlib.import_module(f"pcdcodec.recording.{name}")
    if name in ("paper", "rosbag_export"):  # moved to pcdcodec.convert; the import warns
        return importlib.import_module(f"pcdcodec.recording.{name}")
    if name == "export_bag":  # the bag export is a conversion; it used to be named here
        warnings.warn(
            "pcdcodec.recording.export_bag has moved to pcdcodec.convert.rosbag.export_bag (also "
            "pcdcodec.export_bag); pcdcodec.recording.export_bag goes in a later release",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.import_module("pcdcodec.convert.rosbag").export_bag
    raise AttributeError(f"module 'pcdcodec.recording' has no attribute {name!r}")


__all__ = [
    "FORMAT_VERSION",
    "CameraSpec",
    "EncodeSummary",
    "Frame",
    "FrameSet",
    "Recording",
    "RecordingWriter",
    "RigRecording",
    "RigSummary",
    "RigWriter",
    "VerifyReport",
    "encode",
    "encode_rig",
    "open",
    "recover",
]


@overload
def open(
    path: str | os.PathLike[str], mode: Literal["r"] = "r", *, threads: int | None = None
) -> Recording: ...
@overload
def open(
    path: str | os.PathLike[str],
    mode: Literal["w"],
    *,
    intrinsics: Any,
    depth_scale: float | None = ...,
    color: Any = ...,
    depth: Any = ...,
    fps: float = ...,
    metadata: dict[str, Any] | None = ...,
    overwrite: bool = ...,
    in_flight: int = ...,
    frame_id: str = ...,
) -> RecordingWriter: ...
@overload
def open(
    path: str | os.PathLike[str],
    mode: Literal["w"],
    *,
    cameras: list[CameraSpec],
    metadata: dict[str, Any] | None = ...,
    overwrite: bool = ...,
    in_flight: int = ...,
    rig_frame_id: str = ...,
) -> RigWriter: ...


def open(path: str | os.PathLike[str], mode: str = "r", **options: Any) -> Any:
    """Open a ``.pcdc`` recording for reading (``"r"``) or writing (``"w"``).

    Writing::

        with pcdcodec.open("run.pcdc", "w", intrinsics=cam, depth_scale=1000.0,
                           color="h264", depth="depthac") as rec:
            rec.write(rgb, depth, timestamp_ns)

    Options for ``"w"``: ``intrinsics`` (required), ``depth_scale`` (depth units per metre;
    1000, millimetres, by default, which float32 depth does not take: give 1.0 for metres),
    ``color`` and ``depth`` (codec names, configs or codecs; ``color=None`` records depth only),
    ``fps`` (nominal frame rate), ``metadata`` (a dict of your own), ``overwrite``,
    ``in_flight`` (frames encoded ahead, bounding memory).

    Reading::

        with pcdcodec.open("run.pcdc") as rec:
            for frame in rec:
                cloud = frame.to_point_cloud()

    Option for ``"r"``: ``threads``, the cores reading may use (``None``, the default: one
    frame at a time, each codec with its own default). With 2 or more, iterating and ``play()``
    decode the next ``6 × threads`` frames on worker threads while the caller uses the current
    one: the same frames in the same order, checked as ever (see :class:`Recording`).
    """
    from .reader import Recording, SeveralCamerasError
    from .writer import RecordingWriter

    if mode == "r":
        unknown = sorted(set(options) - {"threads"})
        if unknown:
            raise InputError(f"reading takes only the option threads, got {unknown}")
        try:
            return Recording(path, **options)
        except SeveralCamerasError as rig:
            from .rig_reader import RigRecording

            return RigRecording(path, index=rig.index, **options)
    if mode == "w":
        if "cameras" in options:
            from .rig import RigWriter

            return RigWriter(path, **options)
        return RecordingWriter(path, **options)
    raise InputError(f"mode must be 'r' or 'w', got {mode!r}")


def _is_recording(path: Path) -> bool:
    """Whether ``path`` is a file that starts as a pcdcodec recording: MCAP whose header names
    pcdcodec's profile (its first 64 bytes are read; a ROS 2 ``.mcap`` bag names ``ros2``)."""
    from ..ros.bagfile import mcap_profile

    if not path.is_file():
        return False
    head = read_magic(path, 64)
    return head.startswith(MAGIC) and mcap_profile(head) == PROFILE


def _open_source(path: Path, **options: Any) -> Any:
    from .source import RecordingSource

    return RecordingSource(path, **options)


def _open_cameras(path: Path, **options: Any) -> Any:
    from .source import recording_cameras

    return recording_cameras(path, **options)


register_source(
    "recording",
    _is_recording,
    _open_source,
    "a .pcdc recording, written again with other codecs (depth as stored, color decoded)",
    cameras=_open_cameras,
)
