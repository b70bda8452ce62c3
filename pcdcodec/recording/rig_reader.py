"""Reading a recording of several cameras (format version 3): its cameras, each camera's frames,
and sets of frames matched by time with their clouds fused in the rig frame.

Each camera of the file is read by a :class:`~pcdcodec.Recording` that sees only that camera's
channels and records (:func:`~pcdcodec.recording._index.camera_view`), so every check a
one-camera recording gets (digests, seal, CRCs, frame digests) runs per camera.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError, InputError
from . import _header as header
from . import _index as fmt
from .framesets import FrameSet, FrameSets, RigCamera, framesets, match_times
from .reader import Recording
from .verify import VerifyReport, index_problems

__all__ = [
    "CameraRecording",
    "FrameSet",
    "FrameSets",
    "RigCamera",
    "RigRecording",
    "match_times",
]

_NS = 1_000_000_000


class CameraRecording(Recording):
    """One camera of a rig's file, read as a one-camera :class:`~pcdcodec.Recording` (its
    frames, ``rec[i]``, iteration, ``play()``, ``verify()``, ...). Made by
    :meth:`RigRecording.frames`."""

    def __init__(
        self,
        path: Path,
        view: fmt.FileIndex,
        camera: str,
        *,
        threads: int | None = None,
        other_chunks: frozenset[int] = frozenset(),
    ) -> None:
        self._view = view
        self.camera = camera
        self.other_chunks = other_chunks
        super().__init__(path, threads=threads)

    def _read_index(self, name: str) -> fmt.FileIndex:
        return self._view

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.camera!r} of {str(self.path)!r}: {len(self)} frames>"


class RigRecording:
    """A recording of several cameras opened for reading. Use :func:`pcdcodec.open`.

    :attr:`cameras` describes each camera (calibration, depth scale, where it sits on the rig);
    :meth:`frames` gives one camera's frames as a :class:`~pcdcodec.Recording` (``len``,
    ``rec[i]``, iteration, ``play()``, ...); :meth:`framesets` matches the cameras' frames by
    time, and each :class:`FrameSet` fuses its cameras' clouds in the rig frame.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        threads: int | None = None,
        index: fmt.FileIndex | None = None,
    ) -> None:
        self.path = Path(path)
        name = str(self.path)
        if index is None:
            index = _load(self.path)
        self.index = index
        names = fmt.rig_cameras(index, repr(name))
        if names is None:
            raise InputError(f"{name!r} is a one-camera recording: open it with pcdcodec.open()")
        main = index.metadata[fmt.METADATA_NAME]
        if main.get("format_version") != str(fmt.RIG_VERSION):
            raise DecodeError(
                f"{name!r} lists cameras but is format version {main.get('format_version')!r}; "
                f"this pcdcodec reads several cameras in format version {fmt.RIG_VERSION}"
            )
        self.format_version = fmt.RIG_VERSION
        #: the frame the cameras' rig poses take points into
        self.rig_frame_id = main.get(fmt.RIG_FRAME_KEY, "rig")
        self.metadata = header.read_user_metadata(index)
        self._recordings: dict[str, CameraRecording] = {}
        self.cameras: dict[str, RigCamera] = {}
        self.rig_poses: dict[str, npt.NDArray[np.float64]] = {}
        everything = {o for offsets in index.offsets.values() for o in offsets}
        try:
            for cam in names:
                record = index.metadata[fmt.camera_record(cam)]
                pose = fmt.camera_rig_pose(index, cam, repr(name))
                view = fmt.camera_view(index, cam)
                own = {o for offsets in view.offsets.values() for o in offsets}
                rec = CameraRecording(
                    self.path,
                    view,
                    cam,
                    threads=threads,
                    other_chunks=frozenset(everything - own),
                )
                self._recordings[cam] = rec
                self.rig_poses[cam] = pose
                self.cameras[cam] = RigCamera(
                    cam,
                    rec.intrinsics,
                    rec.depth_scale,
                    rec.fps,
                    pose,
                    record.get("frame_id", cam),
                    rec.color_intrinsics,
                    rec.depth_to_color,
                    rec.codecs.get("depth"),
                    rec.codecs.get("color"),
                )
        except BaseException:
            self.close()
            raise
        counts = ", ".join(f"{len(r)} of camera {c!r}" for c, r in self._recordings.items())
        try:
            fmt.warn_if_incomplete(index, name, lambda: f"frames ({counts})")
        except BaseException:  # a filter that turns the warning into an error
            self.close()
            raise

    @property
    def complete(self) -> bool:
        """False for a file that ends before its writer closed it (see
        :attr:`Recording.complete <pcdcodec.Recording.complete>`)."""
        return fmt.ends_early(self.index) is None

    @property
    def camera_names(self) -> list[str]:
        """The camera names, in the rig's order."""
        return list(self.cameras)

    def frames(self, camera: str | None = None) -> CameraRecording:
        """The frames of ``camera`` (may be left out when the rig has one camera)."""
        if camera is None:
            if len(self._recordings) == 1:
                return next(iter(self._recordings.values()))
            raise InputError(f"pass camera=: this recording has cameras {self.camera_names}")
        try:
            return self._recordings[camera]
        except (KeyError, TypeError):
            raise InputError(
                f"no camera {camera!r} in {str(self.path)!r}; its cameras are {self.camera_names}"
            ) from None

    def framesets(
        self, tolerance: float | None = None, *, reference: str | None = None
    ) -> FrameSets:
        """The frames of all cameras matched by time: one set per frame of ``reference`` (the
        first camera unless given), holding each other camera's frame nearest in time if it is
        within ``tolerance`` seconds (default: half the reference camera's frame interval,
        ``0.5 / fps``), else ``None`` (the set lists it in ``missing``). A frame joins at most
        one set."""
        return framesets(self, tolerance, reference)

    def verify(self) -> VerifyReport:
        """Verify every camera (``Recording.verify``); problems name their camera, and those of
        the whole file (cut short, an unusable summary) are said once."""
        errors = index_problems(self.index)
        frames = 0
        for cam, rec in self._recordings.items():
            report = rec.verify()
            frames += report.frames
            errors.extend(f"camera {cam!r}: {e}" for e in report.errors if e not in errors)
        return VerifyReport(frames, errors, self.index.indexed, self.index.truncated_at)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame of any camera."""
        times = [r.timestamps for r in self._recordings.values() if len(r)]
        if not times:
            return 0.0
        return float(max(int(t[-1]) for t in times) - min(int(t[0]) for t in times)) / _NS

    def __repr__(self) -> str:
        counts = ", ".join(f"{n}: {len(r)}" for n, r in self._recordings.items())
        return f"<RigRecording {str(self.path)!r}: {len(self.cameras)} cameras ({counts} frames)>"

    def close(self) -> None:
        """Close every camera's reader."""
        for rec in self._recordings.values():
            rec.close()

    def __enter__(self) -> RigRecording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _load(path: Path) -> fmt.FileIndex:
    """The checked index of a rig's file (every record's digest, every camera's seal)."""
    name = str(path)
    if not path.exists():
        raise InputError(f"recording {name!r} does not exist")
    with open(path, "rb") as f:
        return load_index(f, name)


def load_index(f: IO[bytes], name: str) -> fmt.FileIndex:
    """The index of the recording in ``f`` with the checks every camera relies on."""
    header.check_magic(f, name)
    try:
        index = fmt.load(f)
    except DecodeError as exc:
        raise DecodeError(f"{name!r}: {exc}") from exc
    except Exception as exc:  # whatever a damaged file makes the MCAP records raise
        raise DecodeError(f"{name!r} could not be read ({type(exc).__name__}: {exc})") from exc
    if index.damaged_at is not None:
        raise DecodeError(
            f"{name!r} is damaged at byte offset {index.damaged_at}: {index.damage}; "
            "`pcdcodec recover` copies the frames before the damage into a new file"
        )
    if not header.is_recording(index):
        raise header.not_a_recording(f, index, name)
    fmt.check_metadata(index, repr(name))
    return index
