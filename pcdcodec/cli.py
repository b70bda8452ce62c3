"""The ``pcdcodec`` command: a thin layer over the library.

Each command parses its arguments, calls the library, and on a pcdcodec error prints
``error: …`` to stderr and exits with status 1 (2 for bad command-line arguments).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from ._progress import Progress
from .codec import KINDS, Codec
from .errors import InputError, PcdcodecError
from .registry import codec_class, get_codec, list_codecs

# -- helpers ---------------------------------------------------------------------------------


def parse_codec(spec: str, kind: str) -> Codec:
    """``"h264"`` or ``"h264:crf=20,preset=fast"`` to a codec; values are read as JSON when
    they parse (numbers, true/false/null), else as strings."""
    name, _, rest = spec.partition(":")
    params: dict[str, Any] = {}
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise InputError(f"codec option {item!r} in {spec!r} is not key=value")
        try:
            params[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            params[key.strip()] = value
    return get_codec(name.strip(), kind=kind, **params)


def _intrinsics_from_args(args: argparse.Namespace, width: int, height: int) -> Any:
    from .camera import CameraIntrinsics

    given = {k: getattr(args, k) for k in ("fx", "fy", "cx", "cy")}
    if all(v is None for v in given.values()):
        return None
    missing = [f"--{k}" for k, v in given.items() if v is None]
    if missing:
        raise InputError(f"intrinsics need --fx --fy --cx --cy; missing {' '.join(missing)}")
    return CameraIntrinsics(width, height, given["fx"], given["fy"], given["cx"], given["cy"])


def _add_camera_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("camera (default: camera.json in the folder)")
    for k, what in (
        ("fx", "focal length x"),
        ("fy", "focal length y"),
        ("cx", "principal point x"),
        ("cy", "principal point y"),
    ):
        g.add_argument(f"--{k}", type=float, help=f"{what} in pixels")
    g.add_argument("--depth-scale", type=float, help="depth units per metre (1000 for mm)")


def _mib(n: float) -> str:
    return f"{n / 2**20:.2f} MiB"


# -- commands ----------------------------------------------------------------------------------


def _cmd_codecs(args: argparse.Namespace) -> int:
    kinds = KINDS if args.kind is None else (args.kind,)
    for kind in kinds:
        print(f"{kind} codecs:")
        for name in list_codecs(kind):
            cls = codec_class(name)
            reason = cls.unavailable_reason()
            lossless = "lossless" if getattr(cls, "lossless", False) else "lossy"
            if reason is not None:
                state = f"unavailable: {reason}"
            else:
                config = cls().get_config()
                state = ", ".join(f"{k}={v!r}" for k, v in config.items() if k != "id")
            print(f"  {name:14} {lossless:9} {state or '(no parameters)'}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .datasets import load_sample
    from .recording import open as open_recording

    seq = load_sample(max_frames=args.frames)
    n = len(seq)
    h, w = seq[0].depth.shape
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"bundled sample: {n} frames of {w}x{h} RGB-D (TUM fr1_rpy, CC BY 4.0)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sample.pcdc"

        def record(target: Path, frames: Any) -> Any:
            with open_recording(
                target, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale
            ) as writer:
                writer.write_frames(frames)
            return writer

        # A short warm-up loads the codec libraries, so the timings below are steady-state.
        record(Path(tmp) / "warmup.pcdc", seq.frames[:2])
        start = time.perf_counter()
        writer = record(path, seq)
        t_encode = time.perf_counter() - start
        size = path.stat().st_size
        exact = True
        with open_recording(path) as rec:
            codecs = rec.codecs
            for frame, original in zip(rec, seq, strict=True):  # warm-up pass, checked
                exact &= bool(np.array_equal(frame.depth, original.depth))
                frame.to_points()
        # Steady-state rates: from the second frame on (the first pays the decoders' start-up).
        with open_recording(path) as rec:
            rec[0]
            start = time.perf_counter()
            for i in range(1, n):
                rec[i]
            t_decode = time.perf_counter() - start
        with open_recording(path) as rec:
            points = len(rec[0].to_points()[0])
            start = time.perf_counter()
            for i in range(1, n):
                points += len(rec[i].to_points()[0])
            t_cloud = time.perf_counter() - start
            import open3d as o3d

            ply = out_dir / "frame0000.ply"
            o3d.io.write_point_cloud(ply, rec[0].to_point_cloud())
    raw = n * h * w * (3 + 2)
    color_id = str((codecs["color"] or {}).get("id", "none"))
    depth_id = str((codecs["depth"] or {}).get("id"))
    pc2 = n * h * w * 32
    rows = [
        ("color stream", writer.bytes_color, color_id),
        ("depth stream", writer.bytes_depth, depth_id),
        ("whole .pcdc file", size, "container, index, camera"),
        ("raw RGB-D (RGB24 + uint16)", raw, ""),
        ("PointCloud2 XYZRGB, 32 B/point", pc2, "organized, as ROS publishes it"),
    ]
    print()
    print(f"| {'what':32} | {'size':>11} | {'per frame':>10} | note")
    print(f"|{'-' * 34}|{'-' * 13}|{'-' * 12}|------")
    for what, nbytes, note in rows:
        print(f"| {what:32} | {_mib(nbytes):>11} | {nbytes / n / 1024:7.1f} KiB | {note}")
    print()
    print(f"ratio against raw RGB-D:        {raw / size:6.1f}x")
    print(f"ratio against PointCloud2:      {pc2 / size:6.1f}x")
    print(f"encode:                         {n / t_encode:6.1f} fps")
    print(f"decode (color + depth):         {n / t_decode:6.1f} fps")
    print(
        f"decode + point cloud:           {n / (t_decode + t_cloud):6.1f} fps "
        f"({points / n:,.0f} points per frame)"
    )
    print(f"depth bit-exact:                {'yes' if exact else 'NO'}")
    print(f"point cloud of frame 0:         {ply}")
    return 0 if exact else 1


def _cmd_encode(args: argparse.Namespace) -> int:
    from .datasets import open_folder
    from .recording import open as open_recording

    source = open_folder(
        args.src, max_frames=args.max_frames, depth_scale=args.depth_scale, fps=args.fps
    )
    first = next(iter(source))
    h, w = first.depth.shape
    from_args = _intrinsics_from_args(args, w, h)
    intrinsics = from_args or source.intrinsics
    if intrinsics is None:
        raise InputError(
            f"no intrinsics for {args.src!r}: pass --fx --fy --cx --cy, or put a camera.json "
            "with width, height, fx, fy, cx, cy (and depth_scale) in the folder"
        )
    with (
        open_recording(
            args.output,
            "w",
            intrinsics=intrinsics,
            depth_scale=source.depth_scale,
            color=parse_codec(args.color, "color"),
            depth=parse_codec(args.depth, "depth"),
            fps=args.fps,
            overwrite=args.overwrite,
        ) as writer,
        Progress(len(source), "encoding", enabled=None if not args.quiet else False) as bar,
    ):
        count = writer.write_frames(source, progress=bar.update)
    size = Path(args.output).stat().st_size
    scale_from = "--depth-scale" if args.depth_scale is not None else source.depth_scale_origin
    camera_from = "--fx/--fy/--cx/--cy" if from_args is not None else "camera.json"
    print(
        f"wrote {count} frames to {args.output} ({_mib(size)}, {size / count / 1024:.1f} KiB/frame)"
    )
    print(f"  depth scale: {source.depth_scale:g} units per metre (from {scale_from})")
    print(
        f"  intrinsics:  {intrinsics.width}x{intrinsics.height}, fx={intrinsics.fx:g} "
        f"fy={intrinsics.fy:g} cx={intrinsics.cx:g} cy={intrinsics.cy:g} (from {camera_from})"
    )
    return 0


def _cmd_decode(args: argparse.Namespace) -> int:
    import imagecodecs

    from .recording import open as open_recording

    out = Path(args.output)
    if out.exists() and any(out.iterdir()) and not args.overwrite:
        raise InputError(f"{str(out)!r} is not empty; pass --overwrite to write into it")
    with open_recording(args.input) as rec:
        (out / "rgb").mkdir(parents=True, exist_ok=True)
        (out / "depth").mkdir(exist_ok=True)
        if args.ply or args.pcd:
            (out / "clouds").mkdir(exist_ok=True)
        rgb_list, depth_list = (
            ["# color images", "# timestamp filename"],
            ["# depth maps", "# timestamp filename"],
        )
        with Progress(len(rec), "decoding", enabled=None if not args.quiet else False) as bar:
            for frame in rec:
                stamp = f"{frame.timestamp // 1_000_000_000}.{frame.timestamp % 1_000_000_000:09d}"
                name = f"{frame.index:06d}"
                if frame.color is not None:
                    (out / "rgb" / f"{name}.png").write_bytes(imagecodecs.png_encode(frame.color))
                    rgb_list.append(f"{stamp} rgb/{name}.png")
                if frame.depth.dtype == np.uint16:
                    depth_file = f"depth/{name}.png"
                    data = imagecodecs.png_encode(frame.depth)
                else:
                    depth_file = f"depth/{name}.tiff"
                    data = imagecodecs.tiff_encode(frame.depth)
                (out / depth_file).write_bytes(data)
                depth_list.append(f"{stamp} {depth_file}")
                if args.ply or args.pcd:
                    import open3d as o3d

                    cloud = frame.to_point_cloud()
                    for flag, ext in ((args.ply, "ply"), (args.pcd, "pcd")):
                        if flag:
                            o3d.io.write_point_cloud(out / "clouds" / f"{name}.{ext}", cloud)
                bar.update(frame.index + 1)
        (out / "rgb.txt").write_text("\n".join(rgb_list) + "\n")
        (out / "depth.txt").write_text("\n".join(depth_list) + "\n")
        camera = {**rec.intrinsics.to_dict(), "depth_scale": rec.depth_scale}
        (out / "camera.json").write_text(json.dumps(camera, indent=2) + "\n")
        print(f"wrote {len(rec)} frames to {out}")
    return 0


def _info(rec: Any) -> dict[str, Any]:
    size = rec.path.stat().st_size
    return {
        "path": str(rec.path),
        "format_version": rec.format_version,
        "frames": len(rec),
        "duration_s": round(rec.duration, 3),
        "fps": rec.fps,
        "size_bytes": size,
        "bytes_per_frame": round(size / len(rec)) if len(rec) else None,
        "intrinsics": rec.intrinsics.to_dict(),
        "depth_scale": rec.depth_scale,
        "codecs": rec.codecs,
        "indexed": rec.indexed,
        "metadata": rec.metadata,
        "first_timestamp_ns": int(rec.timestamps[0]) if len(rec) else None,
    }


def _cmd_info(args: argparse.Namespace) -> int:
    from .recording import open as open_recording

    with open_recording(args.input) as rec:
        info = _info(rec)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    cam = info["intrinsics"]
    print(f"{info['path']}: pcdcodec recording, format version {info['format_version']}")
    print(f"  frames     {info['frames']} over {info['duration_s']} s (nominal {info['fps']} fps)")
    print(
        f"  size       {_mib(info['size_bytes'])}"
        + (f", {info['bytes_per_frame'] / 1024:.1f} KiB per frame" if info["frames"] else "")
    )
    print(
        f"  camera     {cam['width']}x{cam['height']}, fx={cam['fx']} fy={cam['fy']} "
        f"cx={cam['cx']} cy={cam['cy']}, depth scale {info['depth_scale']} per metre"
    )
    print(f"  color      {json.dumps(info['codecs']['color'])}")
    print(f"  depth      {json.dumps(info['codecs']['depth'])}")
    if info["metadata"]:
        print(f"  metadata   {json.dumps(info['metadata'])}")
    if not info["indexed"]:
        print("  index      missing: the writer did not finish; `pcdcodec recover` rewrites it")
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    from .recording import open as open_recording

    with open_recording(args.input) as rec:
        report = rec.verify()
    for error in report.errors:
        print(f"  {error}")
    if not report.indexed:
        print("  note: the file has no index (unfinished writer); `pcdcodec recover` rewrites it")
    status = "OK" if report.ok else f"{len(report.errors)} problem(s)"
    print(f"{args.input}: {report.frames} frames checked, {status}")
    return 0 if report.ok else 1


def _cmd_recover(args: argparse.Namespace) -> int:
    from .recording import recover

    count = recover(args.input, args.output, overwrite=args.overwrite)
    print(f"recovered {count} frames into {args.output}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from .recording.paper import export_paper

    if args.layout != "paper":
        raise InputError(f"unknown layout {args.layout!r}; known layouts: paper")
    summary = export_paper(args.input, args.output, overwrite=args.overwrite)
    print(f"exported {summary['frames']} frames to {args.output} (layout {args.layout})")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from .evaluation import evaluate, parse_list

    frames = args.frames
    if frames < 1:
        raise InputError(f"--frames must be at least 1, got {frames}")
    source: Any = args.src
    intrinsics = None
    if any(getattr(args, k) is not None for k in ("fx", "fy", "cx", "cy")):
        from .datasets import open_folder

        first = next(iter(open_folder(args.src, max_frames=1, depth_scale=args.depth_scale)))
        h, w = first.depth.shape
        intrinsics = _intrinsics_from_args(args, w, h)
    quiet = args.quiet or not sys.stderr.isatty()

    def say(step: str) -> None:
        if not quiet:
            print(f"  {step}", file=sys.stderr, flush=True)

    result = evaluate(
        source,
        depth=parse_list(args.depth) if args.depth else None,
        color=parse_list(args.color),
        frames=frames,
        intrinsics=intrinsics,
        depth_scale=args.depth_scale,
        rd=not args.no_rd,
        peers=args.peers,
        progress=say,
    )
    print(result.to_markdown())
    if args.output:
        written = result.write(args.output, plots=not args.no_plots)
        print(f"wrote {', '.join(p.name for p in written)} to {args.output}")
    return 0


def _cmd_import(args: argparse.Namespace) -> int:
    from .recording.paper import import_paper

    count = import_paper(
        args.input, args.output, depth=parse_codec(args.depth, "depth"), overwrite=args.overwrite
    )
    print(f"imported {count} frames into {args.output}")
    return 0


# -- parser ------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pcdcodec",
        description="Compress RGB-D point cloud streams and give them back as Open3D clouds.",
    )
    parser.add_argument("--version", action="version", version=f"pcdcodec {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("demo", help="encode and decode the bundled sample, print the numbers")
    p.add_argument(
        "-o",
        "--output",
        default="pcdcodec-demo",
        help="folder for the PLY of frame 0 (default: %(default)s)",
    )
    p.add_argument("--frames", type=int, default=None, help="use only the first N frames")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("encode", help="encode an RGB-D folder (TUM layout or rgb/ + depth/)")
    p.add_argument("src", help="folder with rgb.txt/depth.txt, or rgb/ and depth/ images")
    p.add_argument("-o", "--output", required=True, help="the .pcdc file to write")
    p.add_argument("--color", default="h264", help="color codec, e.g. h264 or h264:crf=20")
    p.add_argument("--depth", default="jpegxl", help="depth codec, e.g. jpegxl or zstd:level=9")
    p.add_argument("--fps", type=float, default=30.0, help="nominal frame rate")
    p.add_argument("--max-frames", type=int, default=None, help="encode only the first N")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    _add_camera_options(p)
    p.set_defaults(func=_cmd_encode)

    p = sub.add_parser("decode", help="write PNG color, 16-bit PNG depth and point clouds")
    p.add_argument("input", help="the .pcdc file")
    p.add_argument("-o", "--output", required=True, help="output folder (TUM layout)")
    p.add_argument("--ply", action="store_true", help="also write a PLY point cloud per frame")
    p.add_argument("--pcd", action="store_true", help="also write a PCD point cloud per frame")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=_cmd_decode)

    p = sub.add_parser("info", help="describe a recording")
    p.add_argument("input")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("verify", help="decode every frame and check every checksum")
    p.add_argument("input")
    p.set_defaults(func=_cmd_verify)

    p = sub.add_parser("recover", help="rewrite a damaged or unfinished recording")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=_cmd_recover)

    p = sub.add_parser("export", help="write a recording in another layout")
    p.add_argument("input")
    p.add_argument("output", help="output folder")
    p.add_argument("--layout", default="paper", help="paper: video + LZ4 depth + JSON")
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("import", help="read the paper layout back into a .pcdc file")
    p.add_argument("input", help="folder written by `export --layout paper`")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--depth", default="jpegxl", help="depth codec for the new file")
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=_cmd_import)

    p = sub.add_parser("bench", help="compare codecs on a recording or an RGB-D folder")
    p.add_argument("src", help="a .pcdc recording or a folder that `encode` accepts")
    p.add_argument("--depth", default=None, help="depth codecs, comma-separated (default: all)")
    p.add_argument("--color", default="h264", help="color codecs, comma-separated")
    p.add_argument("--frames", type=int, default=30, help="frames to use (default: %(default)s)")
    p.add_argument("-o", "--output", default=None, help="folder for report, CSV, JSON and plots")
    p.add_argument("--no-rd", action="store_true", help="skip the color quality sweep")
    p.add_argument("--no-plots", action="store_true", help="write no PNG plots")
    p.add_argument("--peers", action="store_true", help="add peer rows (pcdcodec[peers])")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    _add_camera_options(p)
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("codecs", help="list the registered codecs and their defaults")
    p.add_argument("--kind", choices=KINDS, help="only codecs of this kind")
    p.set_defaults(func=_cmd_codecs)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        status: int = args.func(args)
    except PcdcodecError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return status


if __name__ == "__main__":
    sys.exit(main())
