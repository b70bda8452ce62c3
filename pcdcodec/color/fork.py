"""What a forked process does with the video streams, readers and writers of its parent.

A fork copies a process's memory but only the thread that called it. FFmpeg's encoders and
decoders run worker threads, and a recording's writer and reader run Python threads and hold
the parent's open files. In the child, freeing an inherited encoder or decoder waits for
threads that do not exist there (a hang) or frees what they own (a crash), and closing an
inherited writer would write the parent's half-finished file from the child. The child frees
them whenever its garbage collector finds a cycle left over in the parent, or it drops its
last reference, so ``multiprocessing`` (which forks by default on Linux) would hang or crash.

So every such object registers itself when it is made (:func:`keep_in_child`). In a forked
child, every object registered in another process is dropped without being freed: its
reference count is raised once, so it lives, untouched, until the child exits (memory the
parent already holds, shared copy-on-write). :func:`inherited` tells an object that it came
from a parent, so that its ``close()`` leaves the parent's file and threads alone and using it
raises :class:`~pcdcodec.InputError`. The child opens its own streams, readers and writers,
which work as in any process.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import weakref
from typing import Any

from ..errors import InputError

__all__ = ["check_not_inherited", "inherited", "keep_in_child"]

#: Each registered object and the process that made it.
_OWNER: weakref.WeakKeyDictionary[Any, int] = weakref.WeakKeyDictionary()
#: How many objects this process keeps for its parents (for tests and diagnostics).
kept = 0


def keep_in_child(obj: Any) -> None:
    """Register ``obj`` (an object owning threads, FFmpeg state or an open file) so that a
    process forked from this one never frees it."""
    _OWNER[obj] = os.getpid()


def inherited(obj: Any) -> bool:
    """Whether ``obj`` was made by another process, which this one was forked from."""
    pid = _OWNER.get(obj)
    return pid is not None and pid != os.getpid()


def check_not_inherited(obj: Any, what: str) -> None:
    """Raise :class:`~pcdcodec.InputError` when ``obj`` (described as ``what``) was made by
    the process this one was forked from."""
    if inherited(obj):
        raise InputError(
            f"{what} was opened by process {_OWNER.get(obj)}, which this process was forked "
            "from; it cannot be used here: open a new one in this process"
        )


def _after_fork_in_child() -> None:
    global kept
    pid = os.getpid()
    # No lock here: a thread of the parent may have held it at the fork, and it never returns.
    for obj in list(_OWNER.keys()):
        if _OWNER.get(obj) != pid and not getattr(obj, "_pcdcodec_kept", False):
            # A reference no one holds: the object (and what it refers to) is never freed, by
            # reference count, by the garbage collector, or at interpreter exit.
            ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))
            with contextlib.suppress(AttributeError):  # __slots__: it may be kept twice
                obj._pcdcodec_kept = True
            kept += 1


os.register_at_fork(after_in_child=_after_fork_in_child)
