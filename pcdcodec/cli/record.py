"""The commands that write and check recordings: ``encode``, ``decode``, ``verify``, ``recover``,
``join``.

Each takes the parsed command line and returns the exit status.
"""

from __future__ import annotations

import argparse
import operator
import sys
from pathlib import Path
from typing import Any

from .._progress import Progress
from ..errors import InputError
from .options import camera_defaults, cli_message, mib, parse_codec, source_options
from .show import print_kept, print_left_out


def cmd_encode(args: argparse.Namespace) -> int:
    """``pcdcodec encode SRC -o REC``: any input into a recording; says what camera it used.
    Several inputs, a rig file or a bag of several cameras make a recording of a rig."""
    from ..recording import encode
    from ..sources import open_source
    from ..sources.base import detect_kind

    sources = list(args.src)
    if args.rig is not None or len(sources) > 1 or _several_cameras(args):
        return _cmd_encode_rig(args)
    if not sources:
        raise InputError("encode needs an input (or --rig FILE naming the inputs)")
    args.src = sources[0]
    given = camera_defaults(args)
    options = source_options(args)
    with open_source(args.src, defaults=given, **options) as source:
        if source.intrinsics is None:
            # (a folder can carry its camera in a file; a bag or camera file cannot)
            beside = (
                ", or put a camera.json or intrinsics.K.txt in the folder"
                if detect_kind(args.src) == "folder"
                else " (the input has no CameraInfo or calibration of its own)"
            )
            raise InputError(
                f"no intrinsics for {args.src!r}: pass --intrinsics FILE, --camera NAME or --fx "
                f"--fy --cx --cy{beside}"
            )
        total = operator.length_hint(source) or None
        with Progress(total, "encoding", enabled=None if not args.quiet else False) as bar:
            summary = encode(
                source,
                args.output,
                color=parse_codec(args.color, "color"),
                depth=parse_codec(args.depth, "depth"),
                fps=args.fps,
                overwrite=args.overwrite,
                progress=bar.update,
                passthrough=args.passthrough,
                kept_images=args.kept_images,
            )
        used_camera, used_scale = source.intrinsics, source.depth_scale
        camera_from = _origin_text(source.intrinsics_origin)
        scale_from = _origin_text(source.depth_scale_origin)
    n = summary.frames
    print(
        f"wrote {n} frames to {args.output} ({mib(summary.bytes)}, "
        f"{summary.bytes / n / 1024:.1f} KiB/frame, {summary.fps:.1f} fps)"
    )
    print(f"  depth scale  {used_scale:g} units per metre (from {scale_from})")
    print(
        f"  intrinsics   {used_camera.width}x{used_camera.height}, fx={used_camera.fx:g} "
        f"fy={used_camera.fy:g} cx={used_camera.cx:g} cy={used_camera.cy:g} (from {camera_from})"
    )
    if given is not None and given.override:
        print("  override     the camera flags replace the input's own camera and depth scale")
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
    for note in [*info.get("camera_notes", []), *info.get("notes", [])]:
        print(f"  note         {cli_message(note)}")
    print_kept(summary.kept)
    print_left_out(summary.left_out)
    return 0


def _origin_text(origin: str) -> str:
    """Where a camera or depth scale came from, as the summary says it."""
    return "the input" if origin in ("input", "given") else origin


def _several_cameras(args: argparse.Namespace) -> bool:
    """Whether the one input is read as a rig: a bag of several cameras (unless a topic flag
    or pass-through picks what to read of it), or a recording of a rig."""
    from ..sources.rig import reads_as_rig

    picked = [args.depth_topic, args.color_topic, args.info_topic, args.cloud_topic]
    if len(args.src) != 1 or args.passthrough or any(t is not None for t in picked):
        return False
    return reads_as_rig(args.src[0])


def _cmd_encode_rig(args: argparse.Namespace) -> int:
    """Several cameras into one recording: the inputs, a rig file or a bag's cameras."""
    from ..recording import encode_rig

    flags = {
        "--intrinsics": args.intrinsics,
        "--camera": args.camera,
        "--fx": args.fx,
        "--fy": args.fy,
        "--cx": args.cx,
        "--cy": args.cy,
        "--depth-scale": args.depth_scale,
        "--override": args.override or None,
        "--depth-topic": args.depth_topic,
        "--color-topic": args.color_topic,
        "--info-topic": args.info_topic,
        "--cloud-topic": args.cloud_topic,
        "--passthrough": args.passthrough or None,
        "--depth-pattern": args.depth_pattern,
        "--color-pattern": args.color_pattern,
        "--color-intrinsics": args.color_intrinsics,
        "--depth-to-color": args.depth_to_color,
        "--depth-only": args.depth_only or None,
    }
    given = [k for k, v in flags.items() if v is not None]
    if given:
        raise InputError(
            f"{' '.join(given)} apply to one camera; for several cameras give each camera's "
            "settings in a rig file (--rig, docs/rig.md)"
        )
    options: dict[str, Any] = {} if args.max_frames is None else {"max_frames": args.max_frames}
    if args.max_difference is not None:
        from ..sync import parse_duration

        options["max_difference"] = parse_duration(args.max_difference, "--max-difference")
    with Progress(None, "encoding", enabled=None if not args.quiet else False) as bar:
        summary = encode_rig(
            args.src,
            args.output,
            rig=args.rig,
            color=parse_codec(args.color, "color"),
            depth=parse_codec(args.depth, "depth"),
            fps=args.fps,
            overwrite=args.overwrite,
            progress=bar.update,
            **options,
        )
    print_rig_summary(summary, args.output)
    return 0


def print_rig_summary(summary: Any, output: str) -> None:
    """The lines ``encode`` prints for a rig: per camera, then how the clocks compare."""
    n, cams = summary.frames, summary.cameras
    print(
        f"wrote {n} frames of {len(cams)} cameras to {output} ({mib(summary.bytes)}, "
        f"{summary.fps:.1f} fps)"
    )
    print(f"  rig frame    {summary.rig_frame}")
    width = max(len(name) for name in cams)
    for name, cam in cams.items():
        k = cam.source.get("intrinsics") or {}
        print(
            f"  camera {name:{width}}  {cam.frames} frames, {mib(cam.bytes)} (color "
            f"{mib(cam.bytes_color)}, depth {mib(cam.bytes_depth)}), {k.get('width')}x"
            f"{k.get('height')} fx={k.get('fx', 0):g}, scale {cam.source.get('depth_scale', 0):g}"
        )
        print(f"  {'':{width + 7}}  input {cam.input}; pose from {cam.pose_from}")
        for key in ("depth_topic", "color_topic", "cloud_topic"):
            if cam.source.get(key):
                print(f"  {'':{width + 7}}  {key.replace('_', ' ')} {cam.source[key]}")
    clocks = summary.clocks
    if clocks.reference is not None:
        print(f"  clocks       first and last stamp per camera, offset from {clocks.reference}:")
        for name, (first, last) in clocks.spans.items():
            print(
                f"    {name:{width}}  {first / 1e9:.6f} s to {last / 1e9:.6f} s "
                f"({(last - first) / 1e9:.3f} s), offset {clocks.offsets[name] / 1e9:+.6f} s"
            )
        if clocks.overlap is not None:
            start, end = clocks.overlap
            print(f"  overlap      {(end - start) / 1e9:.3f} s, every camera recording")
        else:
            print("  overlap      none")
    for path, items in summary.left_out.items():
        print(f"  input        {path}")
        print_left_out(items, "    ")
    for line in summary.warnings:
        print(f"warning: {line}")


def cmd_decode(args: argparse.Namespace) -> int:
    """``pcdcodec decode REC -o FOLDER``: a TUM-layout folder, with point clouds if asked; of a
    recording of several cameras, one such folder per camera and ``rig.json``."""
    from ..datasets import write_folder, write_kept_images
    from ..recording import open as open_recording
    from ..recording.rig_reader import RigRecording
    from ..sources.poses import DEFAULT_POSE_LAYOUT, POSE_LAYOUT_KEY, POSE_LAYOUTS

    clouds = tuple(ext for ext, on in (("ply", args.ply), ("pcd", args.pcd)) if on)
    with open_recording(args.input, threads=args.threads) as rec:
        if isinstance(rec, RigRecording):
            return _decode_rig(rec, args, clouds)
        # The poses go out as the input had them; recordings that do not say get TUM's file.
        layout = rec.metadata.get(POSE_LAYOUT_KEY, DEFAULT_POSE_LAYOUT)
        if layout not in POSE_LAYOUTS:
            raise InputError(
                f"{args.input!r} says its poses came as {layout!r}, a layout this pcdcodec "
                f"does not know (it knows {', '.join(POSE_LAYOUTS)}); a newer pcdcodec may"
            )
        poses = rec.has_poses
        with Progress(len(rec), "decoding", enabled=None if not args.quiet else False) as bar:
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
                pose_layout=layout,
            )
        # The images kept beside the frames (an Azure Kinect's IR), as 16-bit PNG files.
        images = write_kept_images(rec, args.output)
    print(f"wrote {count} frames to {args.output}")
    if poses:
        print(f"  poses        {POSE_LAYOUTS[layout]}")
    for topic, n in images.items():
        print(f"  kept images  {topic}: {n} 16-bit PNG files in {topic.strip('/')}/")
    return 0


def _decode_rig(rig: Any, args: argparse.Namespace, clouds: tuple[str, ...]) -> int:
    """One folder per camera (``OUT/<name>/``, as ``decode`` writes one camera's) and
    ``OUT/rig.json`` (:func:`pcdcodec.datasets.write_rig_folder`)."""
    from ..datasets import write_rig_folder

    out = Path(args.output)
    total = sum(len(rig.frames(name)) for name in rig.camera_names)
    with Progress(total, "decoding", enabled=None if not args.quiet else False) as bar:
        counts = write_rig_folder(
            rig, out, clouds=clouds, overwrite=args.overwrite, progress=bar.update
        )
    if not args.quiet:
        print(f"wrote {sum(counts.values())} frames of {len(counts)} cameras to {args.output}:")
        for name, count in counts.items():
            print(f"  {out / name}: camera {name}, {count} frames")
        print(f"  {out / 'rig.json'}: each camera's pose in the rig frame {rig.rig_frame_id!r}")
    return 0


def cmd_verify(args: argparse.Namespace) -> int:
    """``pcdcodec verify REC``: every frame decoded and checked; 1 on any problem."""
    from ..recording import open as open_recording
    from ..recording.rig_reader import RigRecording

    with open_recording(args.input) as rec:
        report = rec.verify()
        per_camera: dict[str, int] = (
            {name: len(rec.frames(name)) for name in rec.camera_names}
            if isinstance(rec, RigRecording)
            else {}
        )
        types = {t.topic: t.msgtype for t in getattr(rec, "kept_topics", [])}
        cameras = {t.topic for t in getattr(rec, "camera_topics", [])}
    if args.quiet and report.ok:
        return 0
    if not args.quiet:  # the kept topics read, with their messages
        print_kept(
            [
                {"name": n, "type": types.get(n, "?"), "messages": c}
                for n, c in report.kept.items()
                if n not in cameras
            ]
        )
        held = sum(c for n, c in report.kept.items() if n in cameras)
        if held:
            print(f"  camera       {held} messages of {len(cameras)} topics, checked")
    out = sys.stderr if args.quiet else sys.stdout  # -q: only a report of problems, on stderr
    for name, frames in per_camera.items():
        bad = sum(1 for e in report.errors if e.startswith(f"camera {name!r}:"))
        print(
            f"  camera {name}: {frames} frames, " + (f"{bad} problem(s)" if bad else "OK"), file=out
        )
    for error in report.errors:
        print(f"  {error}", file=out)
    if not report.indexed:
        print(
            "  note: the file has no index (unfinished writer); `pcdcodec recover` rewrites it",
            file=out,
        )
    status = "OK" if report.ok else f"{len(report.errors)} problem(s)"
    print(f"{args.input}: {report.frames} frames checked, {status}", file=out)
    return 0 if report.ok else 1


def cmd_recover(args: argparse.Namespace) -> int:
    """``pcdcodec recover REC -o OUT``: a damaged or unfinished recording rewritten."""
    from ..recording import recover

    got = recover(args.input, args.output, overwrite=args.overwrite)
    without = f", {got.color_missing} of them without color" if got.color_missing else ""
    print(f"recovered {got.frames} frames into {args.output}{without}")
    _per_camera(args.output)
    if got.lost or got.damage:
        print(f"  left out: {got.dropped} frame(s); color lost: {got.color_missing} frame(s)")
    for line in got.summary():
        print(f"  {line}")
    return 0


def cmd_join(args: argparse.Namespace) -> int:
    """``pcdcodec join A B ... -o OUT``: recordings written one after another, as one."""
    from ..recording.join import join

    count = join(args.parts, args.output, overwrite=args.overwrite)
    print(f"joined {count} frames of {len(args.parts)} recordings into {args.output}")
    _per_camera(args.output)
    return 0


def _per_camera(path: str) -> None:
    """Each camera's frames, for a recording of several cameras."""
    from ..recording import open as open_recording
    from ..recording.rig_reader import RigRecording

    with open_recording(path) as rec:
        if isinstance(rec, RigRecording):
            for name in rec.camera_names:
                print(f"  camera {name}: {len(rec.frames(name))} frames")
