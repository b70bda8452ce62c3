"""Recordings of several RGB-D cameras in one file (format version 3): writing them.

A rig's file keeps each camera as a one-camera file would, under the camera's own namespace
(``/<name>/depth``, ``/<name>/color``, ...) and its own metadata and seal records, plus where
the camera sits on the rig (``docs/format.md``, "Format version 3"). :class:`RigWriter` runs one
:class:`~pcdcodec.RecordingWriter` per camera on the shared file, so each camera is encoded,
checked and written exactly as in a one-camera recording, at its own rate and timestamps.
Reading is :mod:`pcdcodec.recording.rig_reader`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..color import DEFAULT_COLOR_CODEC
from ..color.fork import check_not_inherited, inherited, keep_in_child
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import InputError, InputTypeError
from ..geometry.transform import as_rigid
from . import _header as header
from . import _index as fmt
from ._container import SharedFile
from .writer import RecordingWriter, end_close, open_output

__all__ = ["CameraSpec", "RigWriter"]


@dataclass(frozen=True)
class CameraSpec:
    """One camera of a rig, as :class:`RigWriter` records it.

    ``name`` names the camera in the file and in the API (a letter, then letters, digits or
    ``_``; it is also the ROS namespace its topics get on export). ``intrinsics``,
    ``depth_scale``, ``fps``, ``color``, ``depth``, ``color_intrinsics`` and ``depth_to_color``
    are as for :func:`pcdcodec.open` with mode ``"w"``. ``rig_pose`` is the rigid 4 × 4
    transform (metres) taking a point of the camera's depth frame into the rig frame (default:
    the identity). ``frame_id`` is its frame name in poses and exported bags (default: ``name``).
    """

    name: str
    intrinsics: Any
    depth_scale: float | None = None
    fps: float = 30.0
    color: Any = DEFAULT_COLOR_CODEC
    depth: Any = DEFAULT_DEPTH_CODEC
    color_intrinsics: Any = None
    depth_to_color: Any = None
    rig_pose: Any = None
    frame_id: str | None = None


def _check_specs(cameras: Any, rig_frame_id: str) -> list[CameraSpec]:
    if isinstance(cameras, CameraSpec) or not isinstance(cameras, Sequence):
        raise InputTypeError(f"cameras must be a list of CameraSpec, got {type(cameras).__name__}")
    specs = list(cameras)
    if not specs:
        raise InputError("cameras is empty: a rig records at least one camera")
    for k, spec in enumerate(specs):
        if not isinstance(spec, CameraSpec):
            raise InputTypeError(f"cameras[{k}] is a {type(spec).__name__}, expected a CameraSpec")
        if not isinstance(spec.name, str) or not fmt.CAMERA_NAME.fullmatch(spec.name):
            raise InputError(
                f"camera name {spec.name!r} is not a name: a letter, then up to 63 letters, "
                "digits or '_'"
            )
        if spec.frame_id is not None and not isinstance(spec.frame_id, str):
            raise InputTypeError(
                f"camera {spec.name!r}: frame_id must be a str, got {spec.frame_id!r}"
            )
    names = [s.name for s in specs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"camera names must differ; given more than once: {twice}")
    frames = [s.frame_id or s.name for s in specs]
    if len(set(frames)) != len(frames) or rig_frame_id in frames:
        raise InputError(
            f"frame ids {frames} and the rig's {rig_frame_id!r} must all differ: poses and "
            "exported bags tell the cameras apart by them"
        )
    return specs


class RigWriter:
    """Writes several RGB-D cameras into one ``.pcdc`` file (format version 3).

    Use :func:`pcdcodec.open` with mode ``"w"`` and ``cameras=[CameraSpec(...), ...]``, or this
    class. :meth:`write` takes a frame of any camera, in any order across cameras, each camera
    at its own rate; timestamps increase per camera. Each camera is encoded on its own threads
    and written as soon as it is encoded, exactly as a one-camera recording is, so what a crash
    loses, what memory is held (``in_flight`` frames per camera) and every check on what is
    handed in are as for :class:`~pcdcodec.RecordingWriter`. :meth:`camera` gives a camera's
    own writer, for ``write_source``, ``write_rgbd``, ``write_encoded`` and the rest.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        cameras: Sequence[CameraSpec],
        *,
        metadata: dict[str, Any] | None = None,
        overwrite: bool = False,
        in_flight: int = 4,
        rig_frame_id: str = "rig",
        world_frame_id: str = "world",
    ) -> None:
        if not isinstance(rig_frame_id, str) or not rig_frame_id:
            raise InputError(f"rig_frame_id must be a non-empty str, got {rig_frame_id!r}")
        specs = _check_specs(cameras, rig_frame_id)
        poses = {
            s.name: np.eye(4) if s.rig_pose is None else as_rigid(s.rig_pose, f"{s.name}.rig_pose")
            for s in specs
        }
        user = header.user_metadata(metadata)
        self.path = Path(path)
        self.rig_frame_id = rig_frame_id
        self._target = self.path
        self._writing, file = open_output(self.path, overwrite)
        self._shared = SharedFile(file, self._writing)
        self._closed = False
        keep_in_child(self)  # a forked process never frees or finishes it (color/fork.py)
        self._cameras: dict[str, RecordingWriter] = {}
        try:
            for s in specs:
                # Each camera's codecs are made ready (and its threads started) as it opens.
                self._cameras[s.name] = RecordingWriter(
                    self.path,
                    intrinsics=s.intrinsics,
                    depth_scale=s.depth_scale,
                    color=s.color,
                    depth=s.depth,
                    fps=s.fps,
                    in_flight=in_flight,
                    frame_id=s.frame_id or s.name,
                    color_intrinsics=s.color_intrinsics,
                    depth_to_color=s.depth_to_color,
                    world_frame_id=world_frame_id,
                    _shared=self._shared,
                    _camera=s.name,
                )
            self.rig_poses: dict[str, npt.NDArray[np.float64]] = poses
            self._start(user)
        except BaseException:
            # A writer that never started leaves nothing behind, so a retry finds no file,
            # and no camera's threads run on.
            for cam in self._cameras.values():
                cam.abort()
            file.close()
            self._writing.unlink(missing_ok=True)
            raise

    def _start(self, user: dict[str, str]) -> None:
        records: dict[str, dict[str, str]] = {}
        for name, cam in self._cameras.items():
            records[fmt.camera_record(name)] = {
                **cam._settings.record(),
                "name": name,
                fmt.RIG_POSE_KEY: json.dumps(self.rig_poses[name].tolist()),
            }
        if user:
            records[fmt.USER_METADATA_NAME] = user
        main = {
            "format_version": str(fmt.RIG_VERSION),
            "library": header.LIBRARY,
            fmt.CAMERAS_KEY: json.dumps(list(self._cameras)),
            fmt.RIG_FRAME_KEY: self.rig_frame_id,
            fmt.INTEGRITY_KEY: str(fmt.INTEGRITY_VERSION),
            fmt.RECORDS_KEY: json.dumps(list(records)),
        }
        mcap = header.start_mcap(self._shared.file)
        mcap.add_metadata(fmt.METADATA_NAME, fmt.seal(fmt.METADATA_NAME, main))
        for name, data in records.items():
            mcap.add_metadata(name, fmt.seal(name, data))
        self._shared.file.flush()
        self._shared.mcap = mcap
        for cam in self._cameras.values():
            cam._container.mcap = mcap

    # -- the cameras -----------------------------------------------------------------------

    @property
    def cameras(self) -> list[str]:
        """The camera names, in the order given."""
        return list(self._cameras)

    def camera(self, name: str) -> RecordingWriter:
        """The writer of camera ``name``: everything :class:`~pcdcodec.RecordingWriter` takes
        (``write_source``, ``write_rgbd``, ``write_encoded``, ...) goes into this file.
        Close the rig, not the camera's writer."""
        try:
            return self._cameras[name]
        except (KeyError, TypeError):
            raise InputError(
                f"no camera {name!r} in this rig; its cameras are {self.cameras}"
            ) from None

    def write(
        self,
        camera: str,
        color: Any,
        depth: Any,
        timestamp: int | None = None,
        *,
        pose: Any = None,
        color_timestamp: int | None = None,
        depth_timestamp: int | None = None,
    ) -> None:
        """Add a frame of ``camera``: as :meth:`pcdcodec.RecordingWriter.write`, for that
        camera (its color size, its depth, its own increasing timestamps)."""
        check_not_inherited(self, f"the writer of {str(self.path)!r}")
        self._check_open()
        self.camera(camera).write(
            color,
            depth,
            timestamp,
            pose=pose,
            color_timestamp=color_timestamp,
            depth_timestamp=depth_timestamp,
        )

    @property
    def frames_complete(self) -> dict[str, int]:
        """Per camera, the frames whose messages are all written."""
        return {n: c.frames_complete for n, c in self._cameras.items()}

    @property
    def frames_written(self) -> dict[str, int]:
        """Per camera, the frames whose depth and digest are written."""
        return {n: c.frames_written for n, c in self._cameras.items()}

    @property
    def bytes_color(self) -> int:
        """Bytes of color packets written, all cameras."""
        return sum(c.bytes_color for c in self._cameras.values())

    @property
    def bytes_depth(self) -> int:
        """Bytes of encoded depth written, all cameras."""
        return sum(c.bytes_depth for c in self._cameras.values())

    def flush(self) -> None:
        """Wait until every frame handed in, of every camera, is written and flushed."""
        self._check_open()
        for cam in self._cameras.values():
            cam.flush()

    # -- closing ---------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise InputError(f"recording {str(self.path)!r} is closed")

    def close(self) -> None:
        """Write what every camera still holds, each camera's seal, the index and the summary,
        and close the file. Every step is tried even when an earlier one fails, as for
        :meth:`pcdcodec.RecordingWriter.close`; the first error is raised at the end."""
        if self._closed or inherited(self):  # in a forked process: the parent's file
            self._closed = True
            return
        self._closed = True
        errors: list[BaseException] = []

        def attempt(step: Callable[[], Any]) -> None:
            try:
                step()
            except BaseException as exc:  # every step is tried; the first error is raised
                errors.append(exc)

        for cam in self._cameras.values():
            attempt(cam.close)
        shared = self._shared
        if not shared.failures:
            first = next(iter(self._cameras.values()))._container
            attempt(lambda: first.to_file(shared.mcap.finish))
        attempt(shared.file.close)
        end_close(
            errors, shared.failures[0] if shared.failures else None, self._writing, self._target
        )

    def abort(self) -> None:
        """Stop without finishing: what was written stays readable, as after a crash."""
        if inherited(self):  # in a forked process: the parent's file and threads
            self._closed = True
            return
        self._closed = True
        for cam in self._cameras.values():
            cam.abort()
        self._shared.file.close()

    def __enter__(self) -> RigWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RigWriter({str(self.path)!r}, cameras={self.cameras})"
