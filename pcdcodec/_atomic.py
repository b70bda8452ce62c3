"""Write beside, then rename: the one way pcdcodec puts an output file or folder in place.

An output is written under a hidden name beside its target, ``.NAME.partial-PID`` (plus
``-XXXXXXXX``, eight random hex digits, where several writers of one process may aim at the
same target), and renamed onto the target once complete. A rename within one folder is
atomic, so a reader sees the old output or the new one, never half of one, and a failed or
killed writer leaves its target as it was. A leftover of a killed process is recognised by
:func:`is_partial`.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

__all__ = ["MARK", "atomic_output", "is_partial", "partial_path", "remove"]

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
        yield tmp
        (place or os.replace)(tmp, final)
    finally:
        remove(tmp)
