"""The ``pcdcodec`` command: a thin layer over the library.

Each command parses its arguments, calls the library, and on a pcdcodec error prints
``error: …`` to stderr and exits with status 1 (2 for bad command-line arguments).

The parser is in :mod:`.parser`; the commands are grouped by what they touch in :mod:`.record`,
:mod:`.live` (``record``, with its capture loop in :mod:`.capture`), :mod:`.show`,
:mod:`.convert`, :mod:`.bench` and :mod:`.archive`; :mod:`.options` turns the parsed options
into the library's arguments.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from ..errors import PcdcodecError
from .options import cli_message, parse_codec
from .parser import build_parser, parse_args

__all__ = ["build_parser", "cli_message", "main", "parse_args", "parse_codec"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = parse_args(argv)
    try:
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
