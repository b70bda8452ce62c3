"""Which recordings a dataset reads, what each holds, and the readers each process opens.

:func:`find_recordings` turns a path, a folder, a glob or a list of them into recording paths.
:class:`Readers` opens each recording once per process, on first use: a dataset handed to
DataLoader workers (forked or spawned) carries only paths and settings, and each worker opens
its own files (a file shared across a fork would share its read position too).

A forked worker never frees what it inherited: freeing a decoder (or a decoded picture) whose
FFmpeg threads stayed behind in the parent waits for those threads forever. So readers opened
before the fork stay referenced in the child, and the child freezes the garbage collector's
view of everything inherited (``gc.freeze``), so that no cycle left over in the parent, a
recording's or anyone's, is collected there.
"""

from __future__ import annotations

import gc
import glob
import os
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, InputTypeError
from ..recording import open as open_recording

__all__ = ["Camera", "Readers", "find_recordings"]

#: The file name ending of recordings found in a folder.
SUFFIX = ".pcdc"
_GLOB_CHARS = frozenset("*?[")

#: What a forked process inherited of its parent's readers, kept so that it is never freed.
_INHERITED: list[Any] = []

os.register_at_fork(after_in_child=gc.freeze)


def _one(spec: str | os.PathLike[str]) -> list[Path]:
    text = os.fspath(spec)
    if any(c in _GLOB_CHARS for c in text) and not Path(text).exists():
        found = sorted(Path(p) for p in glob.glob(text, recursive=True))
        files = [p for p in found if p.is_file()]
        if not files:
            raise InputError(f"the pattern {text!r} matches no recording")
        return files
    path = Path(text)
    if path.is_dir():
        files = sorted(p for p in path.rglob(f"*{SUFFIX}") if p.is_file())
        if not files:
            raise InputError(f"the folder {text!r} holds no {SUFFIX} recording")
        return files
    if not path.exists():
        raise InputError(f"recording {text!r} does not exist")
    return [path]


def find_recordings(recordings: Any) -> list[Path]:
    """The recordings ``recordings`` names: a path, a folder (every ``.pcdc`` file in it and
    its subfolders, sorted), a glob pattern (``**`` recurses), or a list or tuple of these.
    Each file is listed once, in the order given."""
    if isinstance(recordings, (str, os.PathLike)):
        specs: list[Any] = [recordings]
    elif isinstance(recordings, (list, tuple)):
        specs = list(recordings)
    else:
        raise InputTypeError(
            "recordings must be a path, a folder, a glob pattern or a list of them, got "
            f"{type(recordings).__name__}"
        )
    if not specs:
        raise InputError("recordings is an empty list")
    out: list[Path] = []
    seen: set[Path] = set()
    for spec in specs:
        if not isinstance(spec, (str, os.PathLike)):
            raise InputTypeError(
                f"each recording must be a path or a pattern, got {type(spec).__name__}"
            )
        for path in _one(spec):
            key = path.resolve()
            if key not in seen:
                seen.add(key)
                out.append(path)
    return out


@dataclass
class Camera:
    """One camera of an open recording, with what reading its frames needs at hand."""

    recording: Any  # a pcdcodec.Recording: that camera's frames
    timestamps: npt.NDArray[np.int64]
    rig_pose: npt.NDArray[np.float64]
    has_color: bool
    poses: list[npt.NDArray[np.float64] | None] | None = field(default=None, repr=False)

    def pose(self, i: int) -> npt.NDArray[np.float64] | None:
        """Frame ``i``'s pose, all poses read once on first use (for frames read without
        their color, which is how :class:`~pcdcodec.Frame` carries its pose)."""
        if self.poses is None:
            self.poses = self.recording.poses()
        return self.poses[i]


class Readers:
    """The recordings this process has open, opened on first use, at most ``max_open`` at once
    (the least recently used is closed first). Pickles as its settings alone, and a copy made
    by a fork opens its own files."""

    def __init__(self, threads: int | None, max_open: int) -> None:
        self.threads = threads
        self.max_open = max_open
        self._open: OrderedDict[str, Any] = OrderedDict()
        self._cameras: dict[tuple[str, str], Camera] = {}
        self._pid = os.getpid()

    def __getstate__(self) -> dict[str, Any]:
        return {"threads": self.threads, "max_open": self.max_open}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["threads"], state["max_open"])  # type: ignore[misc]

    def recording(self, source: str) -> Any:
        """The recording at ``source`` (a ``Recording`` or a ``RigRecording``), open."""
        if self._pid != os.getpid():  # a forked worker: the parent's files are not ours
            _INHERITED.append((self._open, self._cameras))
            self._open = OrderedDict()
            self._cameras = {}
            self._pid = os.getpid()
        rec = self._open.get(source)
        if rec is not None:
            self._open.move_to_end(source)
            return rec
        rec = open_recording(source, threads=self.threads)
        self._open[source] = rec
        while len(self._open) > self.max_open:
            old, oldest = self._open.popitem(last=False)
            self._cameras = {k: v for k, v in self._cameras.items() if k[0] != old}
            oldest.close()
        return rec

    def camera(self, source: str, name: str) -> Camera:
        """Camera ``name`` of the recording at ``source``."""
        rec = self.recording(source)
        key = (source, name)
        cam = self._cameras.get(key)
        if cam is None:
            frames = rec.frames(name)
            cam = Camera(
                frames,
                frames.timestamps,
                rec.rig_poses[name],
                frames.color_codec is not None,
            )
            self._cameras[key] = cam
        return cam

    def close(self) -> None:
        """Close every recording this process opened."""
        if self._pid == os.getpid():
            for rec in self._open.values():
                rec.close()
        else:
            _INHERITED.append((self._open, self._cameras))
        self._open = OrderedDict()
        self._cameras = {}
