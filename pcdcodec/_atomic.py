"""Write beside, then rename: the one way pcdcodec puts an output file or folder in place.

An output is written under a hidden name beside its target, ``.NAME.partial-PID`` (plus
``-XXXXXXXX``, eight random hex digits, where several writers of one process may aim at the
same target), and renamed onto the target once complete. A rename within one folder is
atomic, so a reader sees the old output or the new one, never half of one, and a failed or
killed writer leaves its target as it was. A leftover of a killed process is recognised by
:func:`is_partial`.

An error met writing the output (a read-only folder, a full disk) is raised naming the target,
the user's own path, and what to do, not the hidden partial name (:func:`output_error`).
"""

from __future__ import annotations

import errno
import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from .errors import DiskFullError, OutputError

__all__ = [
    "MARK",
    "atomic_output",
    "is_partial",
    "named_output_errors",
    "output_error",
    "partial_path",
    "remove",
]

MARK = ".partial-"
"""What every partial name holds after the target's name."""


def partial_path(target: str | os.PathLike[str], *, unique: bool = False, suffix: str = "") -> Path:
    """The hidden name beside ``target`` that its output is written under.

    ``.NAME.partial-PID``; with ``unique``, ``-`` and eight random hex digits follow, so that
    several writers in one process get distinct names. ``suffix`` (such as ``".mp4"``) is
    appended, for writers that pick the format from the extension.
    """
    path = Path(target)
    tail = f"-{uuid.uuid4().hex[:8]}" if unique else ""
    return path.with_name(f".{path.name}{MARK}{os.getpid()}{tail}{suffix}")


def is_partial(name: str) -> bool:
    """Whether the file name ``name`` (no folder) is one :func:`partial_path` gives."""
    return name.startswith(".") and MARK in name


def remove(path: Path) -> None:
    """Remove ``path``, a file or a folder tree, if it is there; errors are ignored."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with suppress(OSError):
            path.unlink(missing_ok=True)


@contextmanager
def atomic_output(
    target: str | os.PathLike[str],
    *,
    unique: bool = False,
    place: Callable[[Path, Path], None] | None = None,
) -> Iterator[Path]:
    """Yield the partial path for ``target``; move it onto ``target`` when the block succeeds.

    A leftover under the same partial name is removed first. The caller creates the file or
    folder at the yielded path. When the block ends without an exception, ``place(partial,
    target)`` puts it in place (default :func:`os.replace`, which replaces an existing file or
    empty folder); when the block or ``place`` raises, the exception propagates unchanged. In
    both cases whatever is still at the partial path is then removed, so nothing but the
    target (old or new) is left. Checking an existing target (``overwrite``) is the caller's.
    """
    final = Path(target)
    tmp = partial_path(final, unique=unique)
    remove(tmp)
    try:
        with named_output_errors(final):
            yield tmp
            (place or os.replace)(tmp, final)
    finally:
        remove(tmp)


_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
_NOT_WRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS)


def _is_output(name: object, target: Path) -> bool:
    """Whether the file ``name`` (an ``OSError``'s filename) is ``target``, in it, or a partial
    file or folder beside it (or in one)."""
    if not isinstance(name, (str, os.PathLike)):
        return False
    path = Path(os.fsdecode(name))
    return any(p == target or is_partial(p.name) for p in (path, *path.parents))


def output_error(target: str | os.PathLike[str], exc: BaseException) -> BaseException:
    """The error to raise for ``exc``, met writing the output ``target``: one that names
    ``target`` and says what to do when ``exc`` (or an error behind it) is a full disk
    (:class:`~pcdcodec.DiskFullError`) or a failure to write ``target`` or its partial file
    (:class:`~pcdcodec.OutputError`); else ``exc`` itself (an error of the input, say)."""
    final = Path(target)
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, (DiskFullError, OutputError)):
            return e
        if isinstance(e, OSError) and e.errno in _NO_SPACE:
            return DiskFullError(
                f"no space left to write {str(final)!r} ({e.strerror}): free space on its disk, "
                "or write it elsewhere; nothing half-written was left under that name"
            )
        if isinstance(e, OSError) and (
            _is_output(e.filename, final) or _is_output(e.filename2, final)
        ):
            if e.errno in _NOT_WRITABLE:
                what = "a read-only file system" if e.errno == errno.EROFS else "not writable"
                hint = (
                    f"its folder {str(final.parent)!r} is {what} for this user: write it to a "
                    "folder you can write to, or change the folder's permissions"
                )
            else:
                hint = "nothing half-written was left under that name"
            return OutputError(f"cannot write {str(final)!r} ({e.strerror}): {hint}")
        e = e.__cause__ or e.__context__
    return exc


@contextmanager
def named_output_errors(target: str | os.PathLike[str]) -> Iterator[None]:
    """Raise an error met in the block as :func:`output_error` gives it for ``target``."""
    try:
        yield
    except Exception as exc:
        named = output_error(target, exc)
        if named is exc:
            raise
        raise named from exc
