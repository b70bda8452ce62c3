"""The ``pcdcodec`` command: a thin layer over the library.

Each command parses its arguments, calls the library, and on a pcdcodec error prints
``error: …`` to stderr and exits with status 1 (2 for bad command-line arguments).
"""

from __future__ import annotations

import argparse
import json
import math
import operator
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .. import __version__
from .._progress import Progress
from ..codec import KINDS
from ..color import DEFAULT_COLOR_CODEC
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import InputError, PcdcodecError
from ..registry import codec_class, list_codecs, parse_codec_spec, parse_codec_specs

# -- helpers ---------------------------------------------------------------------------------


#: ``"h264:crf=20,preset=fast"`` to a codec (:func:`pcdcodec.registry.parse_codec_spec`).
parse_codec = parse_codec_spec


def _intrinsics_from_args(args: argparse.Namespace, width: int, height: int) -> Any:
    from ..geometry.camera import CameraIntrinsics

    given = {k: getattr(args, k) for k in ("fx", "fy", "cx", "cy")}
    if all(v is None for v in given.values()):
        return None
    missing = [f"--{k}" for k, v in given.items() if v is None]
    if missing:
        raise InputError(f"intrinsics need --fx --fy --cx --cy; missing {' '.join(missing)}")
    return CameraIntrinsics(width, height, given["fx"], given["fy"], given["cx"], given["cy"])


def _frame_size(
    src: str, depth_scale: float | None, options: dict[str, Any] | None = None
) -> tuple[int, int]:
    """(width, height) of the input's frames: a recording's camera, or a folder's first frame."""
    from ..sources.base import detect_kind

    path = Path(src)
    if path.is_file() and detect_kind(src) is None:
        from ..recording import open as open_recording

        with open_recording(path) as rec:
            return rec.intrinsics.width, rec.intrinsics.height
    from ..sources import open_source

    opts = {**(options or {}), "max_frames": 1, "depth_scale": depth_scale or 1000.0}
    with open_source(path, **opts) as source:
        first = next(iter(source), None)
    if first is None:
        raise InputError(f"{src!r} gives no frames")
    h, w = first.depth.shape
    return w, h


def _camera_from_args(args: argparse.Namespace) -> tuple[Any, float | None]:
    """The camera flags, one rule for ``encode`` and ``bench``: at most one of --fx/--fy/--cx/--cy,
    --intrinsics FILE and --camera NAME; without them the input's own camera (a recording's, or
    the intrinsics file a folder ships with). Returns (intrinsics or None, depth scale or None);
    --depth-scale wins over a preset's."""
    from ..geometry.camera import camera_preset, read_intrinsics

    by_values = any(getattr(args, k) is not None for k in ("fx", "fy", "cx", "cy"))
    chosen = [
        flag
        for flag, on in (
            ("--fx/--fy/--cx/--cy", by_values),
            ("--intrinsics", args.intrinsics is not None),
            ("--camera", args.camera is not None),
        )
        if on
    ]
    if len(chosen) > 1:
        raise InputError(f"give the camera one way: {' and '.join(chosen)} were both given")
    scale = args.depth_scale
    if args.camera is not None:
        preset = camera_preset(args.camera)
        return preset.intrinsics, scale if scale is not None else preset.depth_scale
    if args.intrinsics is not None:
        w, h = _frame_size(args.src, scale, _folder_options(args))
        return read_intrinsics(args.intrinsics, w, h), scale
    if by_values:
        w, h = _frame_size(args.src, scale, _folder_options(args))
        return _intrinsics_from_args(args, w, h), scale
    return None, scale


#: Library wording (keyword arguments) and the CLI flag that says the same.
_CLI_WORDS = (
    ("pass overwrite=True", "pass --overwrite"),
    ("overwrite=True", "--overwrite"),
    (
        "pass intrinsics=pcdcodec.CameraIntrinsics(width, height, fx, fy, cx, cy)",
        "pass --intrinsics FILE, --camera NAME or --fx --fy --cx --cy",
    ),
    ("pass depth_scale=", "pass --depth-scale "),
    (
        "pass color_intrinsics= (and depth_to_color=, the 4x4 depth-to-color transform in metres)",
        "pass --color-intrinsics FILE (and --depth-to-color FILE, the 4x4 depth-to-color "
        "transform in metres)",
    ),
    ("(color=False)", "(--depth-only)"),
    ("need depth_pattern= and color_pattern=", "need --depth-pattern and --color-pattern"),
    ("color_pattern needs depth_pattern", "--color-pattern needs --depth-pattern"),
    ("with depth_pattern= and color_pattern=", "with --depth-pattern and --color-pattern"),
    ("input_options names", "--input-camera names"),
    ("matching depth_pattern", "matching --depth-pattern"),
    ("matching color_pattern", "matching --color-pattern"),
    ("or no color_pattern for depth only", "or no --color-pattern for depth only"),
    (
        "pass camera= (for every input that lacks one) or input_options= (for this input)",
        "pass --camera NAME or --intrinsics FILE (for every input that lacks one) or "
        "--input-camera INPUT=CAMERA (for this input)",
    ),
)


def cli_message(message: str) -> str:
    """A library error message in the CLI's words: flags instead of keyword arguments."""
    for library, flag in _CLI_WORDS:
        message = message.replace(library, flag)
    return message


class _CameraFlag(argparse.Action):
    """``--camera NAME``; ``--camera list`` prints the presets with their values and exits."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        if values == "list":
            _print_presets()
            parser.exit()
        setattr(namespace, self.dest, values)


def _add_camera_options(p: argparse.ArgumentParser) -> None:
    from ..geometry.camera import CAMERA_PRESETS

    g = p.add_argument_group(
        "camera (default: the input's own: a recording's camera, or a folder's camera.json, "
        "intrinsics.K.txt, camera-intrinsics.txt, CameraInfo YAML or Open3D intrinsic JSON)"
    )
    g.add_argument(
        "--intrinsics",
        metavar="FILE",
        help="intrinsics file: 3x3 K text, ROS CameraInfo YAML, Open3D intrinsic JSON",
    )
    g.add_argument(
        "--camera",
        metavar="NAME",
        action=_CameraFlag,
        help="a dataset camera's published intrinsics and depth scale ('--camera list' prints "
        "them): "
        + "; ".join(
            f"{n} (fx={c.intrinsics.fx:g} fy={c.intrinsics.fy:g} cx={c.intrinsics.cx:g} "
            f"cy={c.intrinsics.cy:g}, scale {c.depth_scale:g})"
            for n, c in CAMERA_PRESETS.items()
            if c.depth_scale is not None
        ),
    )
    for k, what in (
        ("fx", "focal length x"),
        ("fy", "focal length y"),
        ("cx", "principal point x"),
        ("cy", "principal point y"),
    ):
        g.add_argument(f"--{k}", type=float, help=f"{what} in pixels")
    g.add_argument("--depth-scale", type=float, help="depth units per metre (1000 for mm)")
    f = p.add_argument_group(
        "RGB-D folders (default: TUM lists, rgb/ and depth/, or files named *depth* and *rgb*)"
    )
    f.add_argument("--depth-pattern", metavar="GLOB", help="depth files, e.g. 'frame_*_depth.tiff'")
    f.add_argument(
        "--color-pattern",
        metavar="GLOB",
        help="color files, e.g. 'frame_*_rgb.tiff'; paired with depth by the text the "
        "wildcards match (without it: depth only)",
    )
    f.add_argument(
        "--color-intrinsics",
        metavar="FILE",
        help="the color camera, for color images of another size than depth (not registered)",
    )
    f.add_argument(
        "--depth-to-color",
        metavar="FILE",
        help="with --color-intrinsics: the 4x4 depth-to-color transform in metres, 16 numbers "
        "row-major (default: identity)",
    )
    f.add_argument("--depth-only", action="store_true", help="read depth, leave color out")


def _folder_options(args: argparse.Namespace) -> dict[str, Any]:
    """The folder flags as options of :func:`pcdcodec.datasets.open_folder`."""
    opts: dict[str, Any] = {}
    for key in ("depth_pattern", "color_pattern", "color_intrinsics", "depth_to_color"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    if getattr(args, "depth_only", False):
        opts["color"] = False
    return opts


def _print_presets() -> int:
    from ..geometry.camera import CAMERA_PRESETS

    print(f"{'name':10} {'size':8} {'fx':>7} {'fy':>7} {'cx':>7} {'cy':>7} {'scale':>6}  source")
    for name, c in CAMERA_PRESETS.items():
        k = c.intrinsics
        scale = f"{c.depth_scale:g}" if c.depth_scale is not None else "-"
        print(
            f"{name:10} {k.width}x{k.height:<4} {k.fx:7g} {k.fy:7g} {k.cx:7g} {k.cy:7g} "
            f"{scale:>6}  {c.source}"
        )
    return 0


def _add_topic_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("bag topics (default: chosen by type and namespace)")
    g.add_argument("--depth-topic", help="depth Image or CompressedImage topic")
    g.add_argument("--color-topic", help="color topic ('' for depth only)")
    g.add_argument("--info-topic", help="CameraInfo topic")
    g.add_argument("--cloud-topic", help="organized PointCloud2 topic (read instead of images)")
    g.add_argument(
        "--passthrough",
        nargs="?",
        const=True,
        default=False,
        metavar="TOPIC",
        help="record the bag's h264/h265 video packets as they are (CompressedVideo, FFMPEGPacket)",
    )


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
            codec = cls()
            lossless = "lossless" if getattr(codec, "lossless", False) else "lossy"
            if reason is not None:
                state = f"unavailable: {reason}"
            else:
                config = codec.get_config()
                state = ", ".join(f"{k}={v!r}" for k, v in config.items() if k != "id")
            if "max_rel_error" in cls.param_names():
                bounded = "or lossy within max_error=, max_rel_error="
                state = f"{state}; {bounded}" if state else bounded
            print(f"  {name:14} {lossless:9} {state or '(no parameters)'}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
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
            import open3d as o3d

            ply = out_dir / "frame0000.ply"
            o3d.io.write_point_cloud(ply, rec[0].to_point_cloud())
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
        print(f"| {what:32} | {_mib(nbytes):>11} | {nbytes / n / 1024:7.1f} KiB | {note}")
    print()
    print(f"ratio against raw RGB-D:        {m.ratio_raw:6.1f}x")
    print(f"ratio against PointCloud2:      {m.ratio_pointcloud2:6.1f}x")
    print(f"encode:                         {m.encode_fps:6.1f} fps")
    print(f"decode (color + depth):         {m.decode_fps:6.1f} fps")
    print(
        f"decode + point cloud:           {m.decode_cloud_fps:6.1f} fps "
        f"({m.points_per_frame:,.0f} points per frame)"
    )
    print(f"depth bit-exact:                {'yes' if m.depth_exact else 'NO'}")
    print(f"point cloud of frame 0:         {ply}")
    return 0 if m.depth_exact else 1


def _source_options(args: argparse.Namespace) -> dict[str, Any]:
    from ..sources.base import detect_kind

    opts: dict[str, Any] = {}
    if args.max_frames is not None:
        opts["max_frames"] = args.max_frames
    if args.depth_scale is not None:
        opts["depth_scale"] = args.depth_scale
    kind = detect_kind(args.src)
    folder = _folder_options(args)
    if kind is None and folder.get("depth_pattern") is not None and Path(args.src).is_dir():
        kind = "folder"  # a folder of files named as the patterns say
    if kind == "folder":
        opts["fps"] = args.fps
        opts.update(folder)
    elif folder and kind is not None:
        names = ["--depth-only" if k == "color" else "--" + k.replace("_", "-") for k in folder]
        hint = ""
        if "color" in folder and kind == "rosbag":  # topic flags are for ROS bags only
            hint = " (a bag's depth alone: --color-topic '')"
        raise InputError(
            f"{' '.join(names)} apply to RGB-D folders; {args.src!r} is a {kind}{hint}"
        )
    topics = {
        "depth_topic": args.depth_topic,
        "color_topic": args.color_topic,
        "info_topic": args.info_topic,
        "cloud_topic": args.cloud_topic,
    }
    given = {k: v for k, v in topics.items() if v is not None}
    if given and kind != "rosbag" and kind is not None:
        flags = " ".join("--" + k.replace("_", "-") for k in given)
        raise InputError(f"{flags} apply to bags; {args.src!r} is a {kind}")
    opts.update(given)
    return opts


def _cmd_encode(args: argparse.Namespace) -> int:
    from ..recording import encode
    from ..sources import open_source

    camera, depth_scale = _camera_from_args(args)
    options = _source_options(args)
    if depth_scale is not None:
        options["depth_scale"] = depth_scale
    with open_source(args.src, **options) as source:
        intrinsics = camera
        if intrinsics is None and source.intrinsics is None:
            raise InputError(
                f"no intrinsics for {args.src!r}: pass --intrinsics FILE, --camera NAME or --fx "
                "--fy --cx --cy, or put a camera.json or intrinsics.K.txt in the folder"
            )
        total = operator.length_hint(source) or None
        with Progress(total, "encoding", enabled=None if not args.quiet else False) as bar:
            summary = encode(
                source,
                args.output,
                color=parse_codec(args.color, "color"),
                depth=parse_codec(args.depth, "depth"),
                intrinsics=intrinsics,
                fps=args.fps,
                overwrite=args.overwrite,
                progress=bar.update,
                passthrough=args.passthrough,
            )
        # encode() put the camera and scale it recorded into the source.
        used_camera, used_scale = source.intrinsics, source.depth_scale
        assert used_camera is not None  # encode() refuses a source without a camera
        if args.depth_scale is not None:
            scale_from = "--depth-scale"
        elif args.camera is not None:
            scale_from = f"--camera {args.camera}"
        else:
            origin = source.depth_scale_origin
            scale_from = "the input" if origin in ("input", "given") else origin
    camera_from = "the input" if camera is None else "the camera flags"
    n = summary.frames
    print(
        f"wrote {n} frames to {args.output} ({_mib(summary.bytes)}, "
        f"{summary.bytes / n / 1024:.1f} KiB/frame, {summary.fps:.1f} fps)"
    )
    print(f"  depth scale  {used_scale:g} units per metre (from {scale_from})")
    print(
        f"  intrinsics   {used_camera.width}x{used_camera.height}, fx={used_camera.fx:g} "
        f"fy={used_camera.fy:g} cx={used_camera.cx:g} cy={used_camera.cy:g} (from {camera_from})"
    )
    info = summary.source
    for key in ("depth_topic", "color_topic", "info_topic", "cloud_topic"):
        if info.get(key):
            print(f"  {key.replace('_', ' '):12} {info[key]}")
    dropped = summary.dropped
    if any(dropped.values()):
        print(
            f"  dropped      {dropped.get('color', 0)} color and {dropped.get('depth', 0)} depth "
            "images without a partner"
        )
    if info.get("out_of_order"):
        print(f"  skipped      {info['out_of_order']} messages whose stamp did not increase")
    for note in info.get("notes", []):
        print(f"  note         {note}")
    return 0


def _cmd_decode(args: argparse.Namespace) -> int:
    from ..datasets import write_folder
    from ..recording import open as open_recording

    clouds = tuple(ext for ext, on in (("ply", args.ply), ("pcd", args.pcd)) if on)
    with (
        open_recording(args.input) as rec,
        Progress(len(rec), "decoding", enabled=None if not args.quiet else False) as bar,
    ):
        count = write_folder(
            rec,
            args.output,
            intrinsics=rec.intrinsics,
            depth_scale=rec.depth_scale,
            color_intrinsics=rec.color_intrinsics,
            depth_to_color=rec.depth_to_color,
            clouds=clouds,
            overwrite=args.overwrite,
            progress=bar.update,
        )
    if not args.quiet:
        print(f"wrote {count} frames to {args.output}")
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
        "color_intrinsics": rec.color_intrinsics.to_dict() if rec.color_intrinsics else None,
        "depth_to_color": rec.depth_to_color.tolist() if rec.depth_to_color is not None else None,
        "depth_scale": rec.depth_scale,
        "codecs": rec.codecs,
        "indexed": rec.indexed,
        "metadata": rec.metadata,
        "first_timestamp_ns": int(rec.timestamps[0]) if len(rec) else None,
    }


def _cmd_info_source(args: argparse.Namespace) -> int:
    from ..sources import CameraDefaults, open_source

    args.src = args.input
    camera, depth_scale = _camera_from_args(args)
    options = _source_options(args)
    if camera is not None:
        options["intrinsics"] = camera
    if depth_scale is not None:
        options["depth_scale"] = depth_scale
    # Without a depth scale, describe what can be known: a stand-in scale is marked unknown.
    unknown = CameraDefaults(depth_scale=1.0, origin="unknown") if depth_scale is None else None
    with open_source(args.input, defaults=unknown, **options) as source:
        info = source.describe()
        if source.depth_scale_origin == "unknown":
            info["depth_scale"] = None
        info["intrinsics_from"] = (
            "the camera flags" if camera is not None else source.intrinsics_origin
        )
        info["depth_scale_from"] = (
            "the camera flags" if depth_scale is not None else source.depth_scale_origin
        )
        candidates = getattr(source, "candidates", None)
        topics = [c.to_dict() for c in candidates()] if callable(candidates) else []
    if args.json:
        print(json.dumps({**info, "topics": topics}, indent=2, default=str))
        return 0
    print(f"{args.input}: {info['source']}")
    for key, label in (("layout", "layout"), ("frames", "frames"), ("size", "size")):
        if info.get(key) is not None:
            print(f"  {label:12} {info[key]}")
    if info.get("timestamps"):
        print(f"  {'timestamps':12} {info['timestamps']}")
    if topics:
        print("  topics (role from the type and the first message):")
        for t in topics:
            role = t["role"] or "-"
            extra = " ".join(x for x in (t["encoding"], t["size"], t["note"]) if x)
            print(f"    {role:6} {t['topic']}  [{t['type']}, {t['messages']} msgs] {extra}")
    print("  chosen:")
    for key in ("mode", "depth_topic", "color_topic", "info_topic", "cloud_topic"):
        if info.get(key):
            print(f"    {key.replace('_', ' '):12} {info[key]}")
    cam = info.get("intrinsics")
    if cam:
        print(
            f"    camera       {cam['width']}x{cam['height']}, fx={cam['fx']:.6g} "
            f"fy={cam['fy']:.6g} cx={cam['cx']:.6g} cy={cam['cy']:.6g} "
            f"(from {info['intrinsics_from']})"
        )
    else:
        print("    camera       unknown (pass --camera NAME, --intrinsics FILE or --fx ...)")
    color_cam = info.get("color_intrinsics")
    if color_cam:
        print(
            f"    color camera {color_cam['width']}x{color_cam['height']}, "
            f"fx={color_cam['fx']:.6g} fy={color_cam['fy']:.6g} cx={color_cam['cx']:.6g} "
            f"cy={color_cam['cy']:.6g}"
        )
    if info["depth_scale"] is None:
        print("    depth scale  unknown (pass --depth-scale UNITS_PER_METRE)")
    else:
        print(
            f"    depth scale  {info['depth_scale']:g} per metre (from {info['depth_scale_from']})"
        )
    for note in info.get("notes", []):
        print(f"    note         {note}")
    return 0


#: Options of ``info`` that say how to read an input (a folder, a bag), not a recording.
_INPUT_FLAGS = (
    "intrinsics",
    "camera",
    "fx",
    "fy",
    "cx",
    "cy",
    "depth_scale",
    "depth_pattern",
    "color_pattern",
    "color_intrinsics",
    "depth_to_color",
    "depth_only",
    "depth_topic",
    "color_topic",
    "info_topic",
    "cloud_topic",
    "passthrough",
)


def _cmd_info(args: argparse.Namespace) -> int:
    from ..recording import open as open_recording
    from ..sources.base import detect_kind

    path = Path(args.input)
    # A ROS 2 bag stored as MCAP starts with the same magic as a recording: the readers'
    # probes tell them apart by the MCAP profile.
    if detect_kind(path) is not None:
        return _cmd_info_source(args)
    given = [
        "--" + key.replace("_", "-")
        for key in _INPUT_FLAGS
        if getattr(args, key, None) not in (None, False)
    ]
    if given and path.is_file():
        raise InputError(
            f"{' '.join(given)} describe how to read an input; {args.input!r} is not one "
            "(a recording keeps its own camera and depth scale)"
        )
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
    if cam.get("distortion_model"):
        print(f"             lens {cam['distortion_model']} {cam['distortion']}")
    color_cam = info.get("color_intrinsics")
    if color_cam:
        t = [round(v[3] * 1000, 2) for v in info["depth_to_color"][:3]]
        print(
            f"  color cam  {color_cam['width']}x{color_cam['height']}, fx={color_cam['fx']} "
            f"fy={color_cam['fy']} cx={color_cam['cx']} cy={color_cam['cy']}"
            + (
                f", lens {color_cam['distortion_model']}"
                if color_cam.get("distortion_model")
                else ""
            )
            + f"; depth-to-color translation {t} mm"
        )
    print(f"  color      {json.dumps(info['codecs']['color'])}")
    print(f"  depth      {json.dumps(info['codecs']['depth'])}")
    stamps = info["metadata"].get("timestamps", "")
    if stamps.startswith("not recorded"):
        print(f"  times      {stamps} (the input had no timestamps)")
    if info["metadata"]:
        print(f"  metadata   {json.dumps(info['metadata'])}")
    problem = rec.index.summary_problem
    if problem:
        print(f"  index      unusable ({problem}); frames found by reading the whole file")
    elif not info["indexed"]:
        print("  index      missing: the writer did not finish; `pcdcodec recover` rewrites it")
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    from ..recording import open as open_recording

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
    from ..recording import recover

    count = recover(args.input, args.output, overwrite=args.overwrite)
    print(f"recovered {count} frames into {args.output}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
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
                cloud=args.cloud,
                compressed_depth=args.compressed_depth,
                overwrite=args.overwrite,
                progress=bar.update,
            )
        print(
            f"exported {summary['frames']} frames to {args.output} ({args.to}"
            + (f", {args.storage}" if args.to == "rosbag2" else "")
            + f", {_mib(summary['bytes'])}): {', '.join(summary['topics'])}"
        )
        return 0
    from ..convert.paper import export_paper

    if args.layout != "paper":
        raise InputError(f"unknown layout {args.layout!r}; known layouts: paper")
    summary = export_paper(args.input, args.output, overwrite=args.overwrite)
    print(f"exported {summary['frames']} frames to {args.output} (layout {args.layout})")
    return 0


def _depth_rd(
    args: argparse.Namespace,
    source: Any,
    frames: int,
    intrinsics: Any,
    depth_scale: float | None,
    say: Any,
) -> int:
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


def _cmd_bench(args: argparse.Namespace) -> int:
    from ..bench.evaluation import evaluate

    frames = args.frames
    if frames < 1:
        raise InputError(f"--frames must be at least 1, got {frames}")
    source: Any = args.src
    intrinsics, depth_scale = _camera_from_args(args)
    folder = _folder_options(args)
    if folder:  # a folder read with the folder flags, then compared as a sequence
        from ..datasets import load_folder

        source = load_folder(
            args.src, max_frames=frames, intrinsics=intrinsics, depth_scale=depth_scale, **folder
        )
    quiet = args.quiet or not sys.stderr.isatty()

    def say(step: str) -> None:
        if not quiet:
            print(f"  {step}", file=sys.stderr, flush=True)

    if args.depth_rd:
        return _depth_rd(args, source, frames, intrinsics, depth_scale, say)
    result = evaluate(
        source,
        depth=parse_codec_specs(args.depth, "depth") if args.depth else None,
        color=parse_codec_specs(args.color, "color"),
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


def _cmd_import(args: argparse.Namespace) -> int:
    from ..convert.paper import import_paper

    count = import_paper(
        args.input, args.output, depth=parse_codec(args.depth, "depth"), overwrite=args.overwrite
    )
    print(f"imported {count} frames into {args.output}")
    return 0


def _archive_defaults(args: argparse.Namespace) -> Any:
    """The camera of inputs that lack one: --camera NAME or --intrinsics FILE, --depth-scale."""
    from ..geometry.camera import camera_preset, read_intrinsics
    from ..sources.base import CameraDefaults

    if args.camera is not None and args.intrinsics is not None:
        raise InputError("give the camera one way: --camera and --intrinsics were both given")
    intrinsics, scale, origin = None, args.depth_scale, "--depth-scale"
    if args.camera is not None:
        preset = camera_preset(args.camera)
        intrinsics, origin = preset.intrinsics, f"--camera {args.camera}"
        scale = scale if scale is not None else preset.depth_scale
    elif args.intrinsics is not None:
        try:
            intrinsics = read_intrinsics(args.intrinsics)
        except InputError:
            try:
                read_intrinsics(args.intrinsics, 1 << 30, 1 << 30)  # read with a size: bare
                bare = True
            except InputError:
                bare = False
            if not bare:
                raise
            raise InputError(
                f"--intrinsics {args.intrinsics!r} is a camera matrix without the image size, "
                "which inputs of any size would take: give a file with the size (ROS "
                "CameraInfo YAML, Open3D intrinsic JSON, camera.json), or give the matrix to "
                f"each input with --input-camera INPUT={args.intrinsics}"
            ) from None
        origin = f"--intrinsics {args.intrinsics}"
    if intrinsics is None and scale is None:
        return None
    scale_origin = "--depth-scale" if args.depth_scale is not None else None
    return CameraDefaults(intrinsics, scale, origin, scale_origin)


def _input_camera(spec: str) -> tuple[str, dict[str, Any]]:
    """``INPUT=CAMERA[,depth_scale=N]`` (CAMERA: a preset name or an intrinsics file) to the
    input and its reader options."""
    from ..geometry.camera import CAMERA_PRESETS, read_intrinsics

    path, sep, what = spec.partition("=")
    if not sep or not path or not what:
        raise InputError(
            f"--input-camera takes INPUT=CAMERA[,depth_scale=N] (CAMERA: a preset name or an "
            f"intrinsics file), got {spec!r}"
        )
    options: dict[str, Any] = {}
    for item in what.split(","):
        key, eq, value = item.partition("=")
        if eq and key.strip() == "depth_scale":
            try:
                scale = float(value)
            except ValueError:
                scale = math.nan
            if not (math.isfinite(scale) and scale > 0):
                raise InputError(
                    f"--input-camera {spec!r}: depth_scale must be a positive number of depth "
                    f"units per metre, got {value!r}"
                )
            options["depth_scale"] = scale
        elif item in CAMERA_PRESETS:
            preset = CAMERA_PRESETS[item]
            options["intrinsics"] = preset.intrinsics
            if preset.depth_scale is not None:
                options.setdefault("depth_scale", preset.depth_scale)
        elif Path(item).is_file():
            try:
                options["intrinsics"] = read_intrinsics(item)
            except InputError:
                options["intrinsics"] = item  # a bare K: the folder gives the image size
        else:
            raise InputError(
                f"--input-camera {spec!r}: {item!r} is neither a camera preset "
                f"({', '.join(CAMERA_PRESETS)}), an intrinsics file nor depth_scale=N"
            )
    return path, options


def _cmd_archive(args: argparse.Namespace) -> int:
    from ..archive import archive

    input_options = dict(_input_camera(s) for s in args.input_camera or ())
    summary = archive(
        args.src,
        args.output,
        camera=_archive_defaults(args),
        input_options=input_options or None,
        scheduler=args.scheduler,
        workers=args.workers,
        color=parse_codec(args.color, "color") if args.color != "none" else None,
        depth=parse_codec(args.depth, "depth"),
        fps=args.fps,
        segment_frames=args.segment_frames,
        verify=args.verify,
        delete_source_after_verify=args.delete_source_after_verify,
        processes=not args.threads,
        progress=False if args.quiet else None,
    )
    for item in summary.items:
        if item.error is not None:
            item.error = cli_message(item.error)
    print(json.dumps(summary.to_dict(), indent=2) if args.json else summary.to_text())
    return 0 if summary.ok else 1


def _cmd_view(args: argparse.Namespace) -> int:
    from ..viewer import view, view_open3d

    if args.open3d:
        view_open3d(args.input, every=args.every)
        return 0
    saved = view(
        args.input,
        save=args.save,
        every=args.every,
        max_frames=args.max_frames,
        stride=args.stride,
    )
    if saved is not None:
        print(f"wrote {saved} (open it with: rerun {saved})")
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

    p = sub.add_parser(
        "encode",
        help="encode any input: RGB-D folder, ROS 1/2 bag, RealSense .bag, Azure Kinect .mkv",
    )
    p.add_argument(
        "src",
        help="an RGB-D folder, a ROS 1 bag, a ROS 2 bag folder or file, a RealSense .bag, an "
        "Azure Kinect .mkv, ...",
    )
    p.add_argument("-o", "--output", required=True, help="the .pcdc file to write")
    p.add_argument(
        "--color", default=DEFAULT_COLOR_CODEC, help="color codec, e.g. h264 or h264:crf=20"
    )
    p.add_argument(
        "--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec, e.g. depthac or zstd:level=9"
    )
    p.add_argument("--fps", type=float, default=30.0, help="nominal frame rate")
    p.add_argument("--max-frames", type=int, default=None, help="encode only the first N")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    _add_camera_options(p)
    _add_topic_options(p)
    p.set_defaults(func=_cmd_encode)

    p = sub.add_parser("decode", help="write PNG color, 16-bit PNG depth and point clouds")
    p.add_argument("input", help="the .pcdc file")
    p.add_argument("-o", "--output", required=True, help="output folder (TUM layout)")
    p.add_argument("--ply", action="store_true", help="also write a PLY point cloud per frame")
    p.add_argument("--pcd", action="store_true", help="also write a PCD point cloud per frame")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )
    p.set_defaults(func=_cmd_decode)

    p = sub.add_parser(
        "info", help="describe a recording, or an input (folder, bag...) and what encode would use"
    )
    p.add_argument("input")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--fps", type=float, default=30.0, help="nominal frame rate of a folder")
    _add_camera_options(p)
    _add_topic_options(p)
    p.set_defaults(func=_cmd_info, max_frames=None)

    p = sub.add_parser("verify", help="decode every frame and check every checksum")
    p.add_argument("input")
    p.set_defaults(func=_cmd_verify)

    p = sub.add_parser("recover", help="rewrite a damaged or unfinished recording")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=_cmd_recover)

    p = sub.add_parser("export", help="write a recording as a ROS bag or in the paper's layout")
    p.add_argument("input")
    p.add_argument(
        "output_pos",
        nargs="?",
        metavar="OUTPUT",
        help="output bag (file for rosbag1, folder for rosbag2) or folder (or -o OUTPUT)",
    )
    p.add_argument("-o", "--output", help="the output, as the second argument says")
    p.add_argument("--to", choices=("rosbag1", "rosbag2"), help="write a ROS bag")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="ROS 2 storage")
    p.add_argument("--cloud", action="store_true", help="add the organized PointCloud2 XYZRGB")
    p.add_argument(
        "--compressed-depth", action="store_true", help="depth as compressedDepth (16UC1 mm)"
    )
    p.add_argument("--layout", default="paper", help="without --to: paper (video + LZ4 + JSON)")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("import", help="read the paper layout back into a .pcdc file")
    p.add_argument("input", help="folder written by `export --layout paper`")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec for the new file")
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=_cmd_import)

    p = sub.add_parser("bench", help="compare codecs on a recording or an RGB-D folder")
    p.add_argument(
        "src", help="a .pcdc recording, or what `encode` accepts: a folder, bag or camera file"
    )
    p.add_argument("--depth", default=None, help="depth codecs, comma-separated (default: all)")
    p.add_argument("--color", default=DEFAULT_COLOR_CODEC, help="color codecs, comma-separated")
    p.add_argument("--frames", type=int, default=30, help="frames to use (default: %(default)s)")
    p.add_argument(
        "-o",
        "--output",
        default=None,
        help="folder for report, CSV, JSON and plots (with --depth-rd: its CSV and plot)",
    )
    p.add_argument("--no-rd", action="store_true", help="skip the color quality sweep")
    p.add_argument("--no-plots", action="store_true", help="write no PNG plots")
    p.add_argument("--peers", action="store_true", help="add peer rows (pcdcodec[peers])")
    p.add_argument(
        "--depth-rd",
        action="store_true",
        help="instead: lossy depth rate-distortion, bounded depthac against HEVC 12-bit, "
        "JPEG XL lossy, LERC and log quantisation",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    _add_camera_options(p)
    p.set_defaults(func=_cmd_bench)

    from ..geometry.camera import CAMERA_PRESETS

    p = sub.add_parser("archive", help="compress many inputs on a Dask cluster, resumably")
    p.add_argument("src", nargs="+", help="inputs, or folders searched for inputs")
    p.add_argument("-o", "--output", required=True, help="output folder (mirrors the sources)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of a running Dask scheduler")
    where.add_argument("--workers", type=int, help="local workers (default: one per core)")
    p.add_argument("--threads", action="store_true", help="local workers as threads")
    p.add_argument("--color", default="h264", help="color codec, or none for depth only")
    p.add_argument(
        "--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec, e.g. depthac or zstd:level=9"
    )
    p.add_argument("--fps", type=float, default=30.0, help="nominal frame rate")
    g = p.add_argument_group(
        "cameras (an input's own camera and depth scale always win: recorded, in its "
        "folder's camera.json or intrinsics file, or by its dataset; these fill in what an "
        "input lacks, with a warning where they contradict it)"
    )
    g.add_argument(
        "--camera",
        metavar="NAME",
        action=_CameraFlag,
        help="camera (and depth scale) of inputs that do not carry one: "
        + ", ".join(CAMERA_PRESETS)
        + " (--camera list prints their values)",
    )
    g.add_argument(
        "--intrinsics",
        metavar="FILE",
        help="camera of inputs that do not carry one, from a file that gives the image size "
        "(ROS CameraInfo YAML, Open3D intrinsic JSON, camera.json)",
    )
    g.add_argument(
        "--depth-scale",
        type=float,
        help="depth units per metre of inputs that do not say it (1000 for mm)",
    )
    g.add_argument(
        "--input-camera",
        action="append",
        metavar="INPUT=CAMERA",
        help="one input's own camera, replacing what it says: a preset name or an intrinsics "
        "file, and/or depth_scale=N (INPUT=tum-fr1, INPUT=K.txt,depth_scale=1000); repeatable",
    )
    p.add_argument(
        "--segment-frames",
        type=int,
        default=None,
        help="frames per parallel segment of a long input (default: about 1 GB of source "
        "and at least 300 frames, on keyframe boundaries)",
    )
    p.add_argument("--verify", action="store_true", help="decode and compare every output")
    p.add_argument(
        "--delete-source-after-verify",
        action="store_true",
        help="delete each source once its output is verified (implies --verify)",
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=_cmd_archive)

    p = sub.add_parser("view", help="show a recording in the Rerun viewer (pcdcodec[view])")
    p.add_argument("input", help="the .pcdc file")
    p.add_argument("--save", metavar="OUT.rrd", help="write a Rerun file instead of a window")
    p.add_argument("--every", type=int, default=1, help="show every n-th frame")
    p.add_argument("--max-frames", type=int, default=None, help="show at most N frames")
    p.add_argument(
        "--stride", type=int, default=2, help="point cloud of every n-th pixel (default: 2)"
    )
    p.add_argument("--open3d", action="store_true", help="play in Open3D's window instead")
    p.set_defaults(func=_cmd_view)

    p = sub.add_parser("codecs", help="list the registered codecs and their defaults")
    p.add_argument("--kind", choices=KINDS, help="only codecs of this kind")
    p.set_defaults(func=_cmd_codecs)
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line as parsed by :func:`build_parser`, with each command's options taken
    anywhere among its positional arguments (``export run.pcdc --layout paper out/``)."""
    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    commands: dict[str, argparse.ArgumentParser] = next(
        a for a in parser._actions if isinstance(a, argparse._SubParsersAction)
    ).choices
    if not words or words[0] not in commands:  # --help, --version, or a missing command
        return parser.parse_args(words)
    args = commands[words[0]].parse_intermixed_args(words[1:])
    args.command = words[0]
    return args


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


if __name__ == "__main__":
    sys.exit(main())
