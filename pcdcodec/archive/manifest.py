"""The output folder's bookkeeping: the manifest that makes a run resumable, the lock that
refuses a second run, the sweep of half-written files a dead run left, and the reading of a
full disk out of any error."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import socket
import time
from pathlib import Path
from typing import IO, Any

from .._atomic import is_partial, partial_path
from .._version import __version__
from ..errors import ArchiveLockedError, DiskFullError, InputError

MANIFEST = "pcdcodec-archive.json"
LOCK = "pcdcodec-archive.lock"
PARTS = ".pcdcodec-parts"

#: states an input goes through in the manifest
DONE_STATES = ("done", "verified", "source-deleted")


def _disk_full(exc: BaseException, where: Path) -> DiskFullError | None:
    """The :class:`~pcdcodec.DiskFullError` that ``exc`` (or an error behind it) amounts to,
    naming ``where``; ``None`` when it is not about a full disk or quota."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, DiskFullError):
            return e
        if isinstance(e, OSError) and e.errno in (errno.ENOSPC, errno.EDQUOT):
            return DiskFullError(
                f"no space left on the device holding {str(where)!r} ({e.strerror}); "
                "free space and run again: finished outputs are kept and skipped"
            )
        e = e.__cause__ or e.__context__
    return None


class _Lock:
    """An exclusive lock on the output folder, released by the OS if the process dies."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / LOCK
        self._file: IO[str] | None = None

    def __enter__(self) -> _Lock:
        f = self.path.open("a+")
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX
            fcntl = None  # type: ignore[assignment]
        if fcntl is not None:
            try:
                fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.seek(0)
                holder = f.read().strip() or "another process"
                f.close()
                raise ArchiveLockedError(
                    f"{str(self.path.parent)!r} is in use by another archive run ({holder}); "
                    "wait for it to finish or give another output folder"
                ) from None
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.ctime()}\n")
        f.flush()
        self._file = f
        return self

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.close()  # closing releases the lock
            self._file = None


class _Manifest:
    """The JSON manifest, rewritten atomically (at most every ``interval`` seconds)."""

    def __init__(self, folder: Path, interval: float = 1.0) -> None:
        self.path = folder / MANIFEST
        self.interval = interval
        self._last = 0.0
        self._dirty = False
        #: Why the last save failed for a full disk (the previous manifest stays in place).
        self.disk_full: str | None = None
        self.entries: dict[str, dict[str, Any]] = {}
        if self.path.exists():
            try:
                data = json.loads(self.path.read_text())
                self.entries = dict(data["inputs"])
            except (ValueError, KeyError, TypeError) as exc:
                raise InputError(
                    f"the manifest {str(self.path)!r} is damaged ({exc}); move it away to "
                    "start over (finished outputs are then encoded again)"
                ) from None

    def update(self, key: str, **values: Any) -> None:
        self.entries.setdefault(key, {}).update(values)
        self._dirty = True
        self.save(force=False)

    def save(self, force: bool = True) -> None:
        if not self._dirty or (not force and time.monotonic() - self._last < self.interval):
            return
        data = {"pcdcodec": __version__, "inputs": self.entries}
        tmp = partial_path(self.path, unique=True)
        try:
            with tmp.open("w") as f:
                json.dump(data, f, indent=1, sort_keys=True)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            full = _disk_full(exc, self.path)
            if full is None:
                raise
            # The manifest written before stays whole (it is only ever replaced); the run
            # stops with the reason, and the next save tries again.
            self.disk_full = str(full)
            return
        self._last = time.monotonic()
        self._dirty = False
        self.disk_full = None


def _sweep(out: Path) -> None:
    """Remove half-written files a dead run left (only names this module writes)."""
    for dirpath, _, filenames in os.walk(out):
        for name in filenames:
            if is_partial(name):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(dirpath, name))


def _prune(folder: Path) -> None:
    """Remove the empty folders under ``folder`` (segments are gone once joined)."""
    if not folder.is_dir():
        return
    for dirpath, _, _ in sorted(os.walk(folder), key=lambda w: -len(w[0])):
        with contextlib.suppress(OSError):
            os.rmdir(dirpath)  # only succeeds when empty
