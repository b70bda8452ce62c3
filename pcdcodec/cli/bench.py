"""The commands that measure: ``demo`` (the bundled sample, encoded and decoded) and ``bench``
(codecs compared on a recording or an input, or the lossy depth rate-distortion).

Each takes the parsed command line and returns the exit status.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..registry import parse_codec_specs
from .options import camera_defaults, cli_message, mib, source_options


def cmd_demo(args: argparse.Namespace) -> int:
    """``pcdcodec demo``: the bundled sample encoded and decoded, its numbers and frame 0 as PLY."""
    from ..bench.roundtrip import measure_roundtrip
    from ..datasets import load_sample
    from ..recording import open as open_recording

    seq = load_sample(max_frames=args.frames)
    n = len(seq)
    h, w = seq[0].depth.shape
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"bundled sample: {n} frames of {w}x{h} RGB-D (TUM fr1_rpy, CC BY 4.0)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sample.pcdc"
        m = measure_roundtrip(seq, path)
        with open_recording(path) as rec:
            from ..geometry.ply import write_ply

            ply = out_dir / "frame0000.ply"
            write_ply(ply, *rec[0].to_points())
    rows = [
        ("color stream", m.bytes_color, m.color_codec),
        ("depth stream", m.bytes_depth, m.depth_codec),
        ("whole .pcdc file", m.bytes_file, "container, index, camera"),
        ("raw RGB-D (RGB24 + uint16)", m.bytes_raw, ""),
        ("PointCloud2 XYZRGB, 32 B/point", m.bytes_pointcloud2, "organized, as ROS publishes it"),
    ]
    print()
    print(f"| {'what':32} | {'size':>11} | {'per frame':>10} | note")
    print(f"|{'-' * 34}|{'-' * 13}|{'-' * 12}|------")
    for what, nbytes, note in rows:
        print(f"| {what:32} | {mib(nbytes):>11} | {nbytes / n / 1024:7.1f} KiB | {note}")
    print()
    print(f"ratio against raw RGB-D:        {m.ratio_raw:6.1f}x")
    print(f"ratio against PointCloud2:      {m.ratio_pointcloud2:6.1f}x (organized: every pixel)")
    print(f"  of the pixels with depth only:  {m.ratio_pointcloud2_points:6.1f}x")
    print(f"encode:                         {m.encode_fps:6.1f} fps")
    print(f"decode (color + depth):         {m.decode_fps:6.1f} fps")
    print(
        f"decode + point cloud (tensor):  {m.decode_cloud_fps:6.1f} fps "
        f"({m.points_per_frame:,.0f} points per frame)"
    )
    print(f"depth bit-exact:                {'yes' if m.depth_exact else 'NO'}")
    print(f"point cloud of frame 0:         {ply}")
    return 0 if m.depth_exact else 1


def _depth_rd(
    args: argparse.Namespace,
    source: Any,
    frames: int,
    intrinsics: Any,
    depth_scale: float | None,
    say: Any,
) -> int:
    """``bench --depth-rd``: lossy depth rate-distortion of the first frames."""
    from ..bench.depth_rd import depth_rd, plot_depth_rd, rd_markdown, write_rd_csv
    from ..bench.evaluation import frames_of

    name, items, _, scale = frames_of(source, frames, intrinsics, depth_scale, need_color=False)
    depths = [f.depth for f in items]
    if not depths or str(depths[0].dtype) != "uint16":
        raise InputError(f"{source!r} holds no uint16 depth frames for the depth RD comparison")
    points = depth_rd(depths, scale, sequence=name, progress=say)
    print(rd_markdown(points))
    if args.output:
        out = Path(args.output)
        out.mkdir(parents=True, exist_ok=True)
        written = [write_rd_csv(points, out / "depth_rd.csv")]
        if not args.no_plots:
            written.append(plot_depth_rd(points, out / "depth_rd.png", title=name))
        print(f"wrote {', '.join(p.name for p in written)} to {args.output}")
    return 0


def _bench_input(args: argparse.Namespace, frames: int) -> Any:
    """The first ``frames`` frames of the input as a sequence, read as ``encode`` reads it: the
    input's own camera and depth scale win, the camera flags fill in what it lacks (or, with
    --override, replace it); each contradiction is printed as a note on stderr."""
    from ..datasets import RGBDSequence
    from ..sources import open_source

    if getattr(args, "passthrough", False):
        raise InputError("--passthrough records a bag's video as it is: `pcdcodec encode` takes it")
    options: dict[str, Any] = {**source_options(args), "max_frames": frames}
    with open_source(args.src, defaults=camera_defaults(args), **options) as src:
        taken = list(src)
        for note in src.camera_notes:
            print(f"note: {cli_message(note)}", file=sys.stderr)
        if not args.depth_rd and any(f.color is None for f in taken):
            raise InputError(f"{args.src!r} has no color stream to compare codecs on")
        name = Path(args.src).stem if Path(args.src).is_file() else Path(args.src).name
        return RGBDSequence(taken, src.intrinsics, src.depth_scale, name=name)


def cmd_bench(args: argparse.Namespace) -> int:
    """``pcdcodec bench SRC``: codecs compared on the first frames (or ``--depth-rd``)."""
    from ..bench.evaluation import evaluate

    frames = args.frames
    if frames < 1:
        raise InputError(f"--frames must be at least 1, got {frames}")
    source = _bench_input(args, frames)
    intrinsics, depth_scale = None, None  # the sequence's own, settled by the one rule
    quiet = args.quiet or not sys.stderr.isatty()

    def say(step: str) -> None:
        if not quiet:
            print(f"  {step}", file=sys.stderr, flush=True)

    if args.depth_rd:
        return _depth_rd(args, source, frames, intrinsics, depth_scale, say)
    result = evaluate(
        source,
        depth=parse_codec_specs(args.depth, "depth") if args.depth else None,
        color=parse_codec_specs(args.color, "color") if args.color else None,
        frames=frames,
        intrinsics=intrinsics,
        depth_scale=depth_scale,
        rd=not args.no_rd,
        peers=args.peers,
        progress=say,
    )
    print(result.to_markdown())
    if args.output:
        written = result.write(args.output, plots=not args.no_plots)
        print(f"wrote {', '.join(p.name for p in written)} to {args.output}")
    return 0
