"""The exception tree of pcdcodec.

Every error the library raises on purpose derives from :class:`PcdcodecError`, and each
one also derives from the builtin exception a caller would naturally catch, so
``except ValueError`` keeps working in code that does not know about pcdcodec.
"""

from __future__ import annotations

__all__ = [
    "ArchiveLockedError",
    "CodecUnavailableError",
    "DecodeError",
    "DiskFullError",
    "IncompleteRecordingWarning",
    "InputError",
    "InputTypeError",
    "OutputError",
    "PcdcodecError",
    "PcdcodecWarning",
    "UnknownCodecError",
    "VerificationError",
]


class PcdcodecError(Exception):
    """Root of every error raised by pcdcodec."""


class UnknownCodecError(PcdcodecError, LookupError):
    """A codec name or config that no registered codec answers to."""

    def __str__(self) -> str:
        # LookupError subclasses such as KeyError quote their message; we never want that.
        return str(self.args[0]) if self.args else ""


class CodecUnavailableError(PcdcodecError, ImportError):
    """A codec is known, but the library it needs is not installed or lacks a feature."""


class DecodeError(PcdcodecError, ValueError):
    """Encoded bytes are corrupt, truncated, or were not written by the expected codec."""


class InputError(PcdcodecError, ValueError):
    """An argument has a wrong value: shape, range, NaN where none is allowed, and so on."""


class InputTypeError(InputError, TypeError):
    """An argument has a wrong type or dtype. Also a ``TypeError`` and a ``ValueError``."""


class ArchiveLockedError(PcdcodecError, RuntimeError):
    """Another ``pcdcodec archive`` run holds the output folder."""


class DiskFullError(PcdcodecError, OSError):
    """The disk being written to is full; nothing half-written is left under a final name."""


class OutputError(PcdcodecError, OSError):
    """An output could not be written (a folder not writable, say); the message names the
    output and what to do."""


class VerificationError(PcdcodecError, ValueError):
    """A written recording does not give back what its source holds."""


class PcdcodecWarning(UserWarning):
    """Root of every warning pcdcodec gives: something a caller should know, that is no error."""


class IncompleteRecordingWarning(PcdcodecWarning):
    """A recording opened for reading ends before its writer closed it (cut short, or its
    writer was stopped): only the frames before that end are read. ``pcdcodec recover`` copies
    them into a closed file."""
