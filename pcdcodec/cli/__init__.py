"""The ``pcdcodec`` command: a thin layer over the library.

Each command parses its arguments, calls the library, and on a pcdcodec error prints
``error: …`` to stderr and exits with status 1 (2 for bad command-line arguments).

The parser is in :mod:`.parser`; the commands are grouped by what they touch in :mod:`.record`,
:mod:`.live` (``record``, with its capture loop in :mod:`.capture`), :mod:`.show`,
:mod:`.convert`, :mod:`.bench` and :mod:`.archive`; :mod:`.options` turns the parsed options
into the library's arguments.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Sequence
from contextlib import nullcontext, redirect_stdout
from typing import Any, TextIO

from ..errors import PcdcodecError, PcdcodecWarning
from .options import cli_message, parse_codec
from .parser import build_parser, parse_args

__all__ = ["build_parser", "cli_message", "main", "parse_args", "parse_codec"]

#: The commands whose ``-q`` means "only errors": no progress and no summary; their warnings
#: and errors still go to stderr.
ONLY_ERRORS_WHEN_QUIET = frozenset({"encode", "decode", "export", "recover", "join"})


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status. pcdcodec's warnings (a recording cut
    short, ...) are printed to stderr as ``warning: …`` lines."""
    args = parse_args(argv)
    with warnings.catch_warnings():  # (restores the caller's filters and showwarning)
        warnings.simplefilter("always", PcdcodecWarning)
        warnings.showwarning = _show_warning
        return _run(args)


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    if issubclass(category, PcdcodecWarning):
        print(f"warning: {cli_message(str(message))}", file=sys.stderr)
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def _run(args: Any) -> int:
    quiet = getattr(args, "quiet", False) and args.command in ONLY_ERRORS_WHEN_QUIET
    try:
        with _stdout_silenced() if quiet else nullcontext():
            status: int = args.func(args)
    except PcdcodecError as exc:
        print(f"error: {cli_message(str(exc))}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return status


def _stdout_silenced() -> Any:
    """A context in which what a command prints to stdout goes nowhere."""
    from contextlib import ExitStack

    stack = ExitStack()
    sink = stack.enter_context(open(os.devnull, "w"))  # noqa: SIM115  # closed by the stack
    stack.enter_context(redirect_stdout(sink))
    return stack
