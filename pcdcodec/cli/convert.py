"""The commands that convert recordings to and from other layouts: ``export`` (a ROS bag, or
the original method's two-file layout) and ``import`` (that layout back into a recording).

Each takes the parsed command line and returns the exit status.
"""

from __future__ import annotations

import argparse
from typing import Any

from .._progress import Progress
from ..errors import InputError
from .options import mib, parse_codec


def cmd_export(args: argparse.Namespace) -> int:
    """``pcdcodec export REC OUT``: a ROS bag (``--to``) or the paper layout."""
    if args.output is not None and args.output_pos is not None:
        raise InputError("give the output folder once: as -o/--output or as the second argument")
    args.output = args.output if args.output is not None else args.output_pos
    if args.output is None:
        raise InputError("export needs an output: a second argument or -o/--output")
    if args.to is not None:
        from ..convert.rosbag import export_bag

        with Progress(None, "exporting", enabled=None if not args.quiet else False) as bar:
            summary = export_bag(
                args.input,
                args.output,
                to=args.to,
                storage=args.storage,
                cloud=args.cloud or None,
                compressed_depth=args.compressed_depth or None,
                kept=args.kept,
                overwrite=args.overwrite,
                progress=bar.update,
            )
        if not args.quiet:
            _print_export(summary, args.output)
        return 0
    from ..convert.paper import export_paper

    if args.layout != "paper":
        raise InputError(f"unknown layout {args.layout!r}; known layouts: paper")
    summary = export_paper(args.input, args.output, overwrite=args.overwrite)
    if not args.quiet:
        print(f"exported {summary['frames']} frames to {args.output} (layout {args.layout})")
    return 0


def _print_export(summary: dict[str, Any], output: str) -> None:
    fmt = summary["format"]
    print(
        f"exported {summary['frames']} frames to {output} ({fmt}"
        + (f", {summary['storage']}" if fmt == "rosbag2" else "")
        + f", {mib(summary['bytes'])}): {', '.join(summary['topics'])}"
    )
    for name, frames in summary.get("cameras", {}).items():
        print(f"  camera {name}: {frames} frames under /{name}")
    if "kept" in summary:
        kept = summary["kept"]
        print(
            f"  kept topics: {len(kept)}, {sum(kept.values())} messages as they came; camera "
            f"topics {summary['camera']}"
        )
    for note in summary.get("notes", []):
        print(f"  note: {note}")


def cmd_import(args: argparse.Namespace) -> int:
    """``pcdcodec import FOLDER -o REC``: the paper layout back into a recording."""
    from ..convert.paper import import_paper

    count = import_paper(
        args.input, args.output, depth=parse_codec(args.depth, "depth"), overwrite=args.overwrite
    )
    print(f"imported {count} frames into {args.output}")
    return 0
