"""The ``pcdcodec`` command: a thin layer over the library.

Each command parses its arguments, calls the library, and on a pcdcodec error prints
``error: …`` to stderr and exits with status 1.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from . import __version__
from .codec import KINDS
from .errors import PcdcodecError
from .registry import codec_class, list_codecs


def _cmd_codecs(args: argparse.Namespace) -> int:
    kinds = KINDS if args.kind is None else (args.kind,)
    for kind in kinds:
        print(f"{kind} codecs:")
        for name in list_codecs(kind):
            cls = codec_class(name)
            reason = cls.unavailable_reason()
            params = (
                ", ".join(f"{k}={v!r}" for k, v in cls().get_config().items() if k != "id")
                if reason is None
                else ""
            )
            lossless = "lossless" if getattr(cls, "lossless", False) else "lossy"
            state = f"unavailable: {reason}" if reason else params
            print(f"  {name:14} {lossless:9} {state}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pcdcodec",
        description="Compress RGB-D point cloud streams and give them back as Open3D clouds.",
    )
    parser.add_argument("--version", action="version", version=f"pcdcodec {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    codecs = sub.add_parser("codecs", help="list the registered codecs and their defaults")
    codecs.add_argument("--kind", choices=KINDS, help="only codecs of this kind")
    codecs.set_defaults(func=_cmd_codecs)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        status: int = args.func(args)
    except PcdcodecError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return status


if __name__ == "__main__":
    sys.exit(main())
