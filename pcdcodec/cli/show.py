"""The commands that show what is there: ``info`` (a recording, or an input and what ``encode``
would make of it), ``codecs`` and ``view``.

Each takes the parsed command line and returns the exit status.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from ..codec import KINDS
from ..errors import InputError
from ..registry import codec_class, list_codecs
from .options import camera_defaults, cli_message, mib, source_options


def print_left_out(items: list[dict[str, Any]], indent: str = "  ") -> None:
    """The lines that name what of an input a recording does not hold: every topic, track or
    file left out, with its type and message count where known."""
    if not items:
        return
    print(f"{indent}{'left out':12} {len(items)} of the input's topics/tracks (not recorded):")
    width = max(len(str(item["name"])) for item in items)
    for item in items:
        count = item.get("messages")
        msgs = "" if count is None else f", {count} msgs"
        print(f"{indent}  {item['name']!s:{width}}  [{item['type']}{msgs}]")


def print_kept(items: list[dict[str, Any]], indent: str = "  ") -> None:
    """The lines that name the input's other topics a recording keeps as they came, with
    their message counts (and bytes, once written)."""
    if not items:
        return
    print(f"{indent}{'kept':12} {len(items)} other topics, as they came:")
    width = max(len(str(item["name"])) for item in items)
    for item in items:
        count = item.get("messages")
        size = item.get("bytes")
        extra = ("" if count is None else f", {count} msgs") + (
            "" if size is None else f", {mib(size)}"
        )
        print(f"{indent}  {item['name']!s:{width}}  [{item['type']}{extra}]")


def _raw_bytes(rec: Any) -> int:
    """Raw RGB-D of the recording's frames, as the benchmarks count it: uint16 depth (2 bytes a
    pixel) plus RGB24 color (3 bytes a pixel of the color camera; none without color)."""
    h, w = rec.intrinsics.shape
    per_frame = w * h * 2
    if rec.color_codec is not None:
        ch, cw = rec.color_shape
        per_frame += cw * ch * 3
    return int(len(rec) * per_frame)


def _gop(rec: Any) -> dict[str, Any] | None:
    """The color stream's keyframe interval as the encoder used it (a ``gop`` of ``null`` in
    the codec's config is its default for the recording's rate) and the keyframes the file
    holds; ``None`` without color."""
    codec = rec.color_codec
    if codec is None:
        return None
    interval = getattr(codec, "keyframe_interval", None)
    return {
        "gop": int(interval(rec.fps)) if callable(interval) else None,
        "configured": (rec.codecs.get("color") or {}).get("gop"),
        "keyframes": len(rec.keyframes),
    }


def _poses(rec: Any) -> dict[str, Any]:
    """How many frames carry a pose, and the span of their stamps."""
    times = rec.pose_timestamps
    n = len(times)
    return {
        "count": n,
        "frames": len(rec),
        "first_ns": int(times[0]) if n else None,
        "last_ns": int(times[-1]) if n else None,
        "span_s": round((int(times[-1]) - int(times[0])) / 1e9, 3) if n else None,
    }


def _info(rec: Any) -> dict[str, Any]:
    """What ``info`` says of a recording, as JSON-ready values."""
    size = rec.path.stat().st_size
    raw = _raw_bytes(rec)
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
        "poses": _poses(rec),
        "raw_rgbd_bytes": raw,
        "ratio_raw_rgbd": round(raw / size, 2) if size else None,
        "color_gop": _gop(rec),
        "frames_without_color": rec.color_missing,
        "kept": _kept_info(rec),
    }


def _kept_info(rec: Any) -> list[dict[str, Any]]:
    """The recording's kept topics: name, type and messages."""
    counts = rec.kept_counts()
    from ..ros.kept import kept_listing
    from ..sources.base import InputStream

    return kept_listing(rec.kept_topics, [InputStream(t, "", n) for t, n in counts.items()])


def _print_ratio(info: dict[str, Any], color: bool) -> None:
    if info["ratio_raw_rgbd"] is None or not info["frames"]:
        return
    what = "uint16 depth + RGB24 color" if color else "uint16 depth"
    print(
        f"  ratio      {info['ratio_raw_rgbd']:g}x against raw RGB-D ({what} per pixel: "
        f"{mib(info['raw_rgbd_bytes'])})"
    )


def _print_gop(gop: dict[str, Any] | None, fps: float, indent: str) -> None:
    if gop is None or gop["gop"] is None:
        return
    how = "as set" if gop["configured"] is not None else f"the default at {fps} fps"
    print(
        f"{indent}           gop {gop['gop']} (a keyframe at least every {gop['gop']} frames, "
        f"{how}); {gop['keyframes']} keyframes in the file"
    )


def _print_poses(poses: dict[str, Any], indent: str) -> None:
    if not poses["count"]:
        print(f"{indent}poses      none")
        return
    print(
        f"{indent}poses      {poses['count']} of {poses['frames']} frames, over "
        f"{poses['span_s']} s ({poses['first_ns'] / 1e9:.6f} s to {poses['last_ns'] / 1e9:.6f} s)"
    )


def _is_rig(rec: Any) -> bool:
    from ..recording.rig_reader import RigRecording

    return isinstance(rec, RigRecording)


def _rig_info(rec: Any) -> dict[str, Any]:
    """What ``info`` says of a recording of several cameras, as JSON-ready values."""
    size = rec.path.stat().st_size
    cameras = []
    for name, cam in rec.cameras.items():
        frames = rec.frames(name)
        cameras.append(
            {
                "name": name,
                "frame_id": cam.frame_id,
                "frames": len(frames),
                "duration_s": round(frames.duration, 3),
                "fps": cam.fps,
                "intrinsics": cam.intrinsics.to_dict(),
                "color_intrinsics": cam.color_intrinsics.to_dict()
                if cam.color_intrinsics
                else None,
                "depth_to_color": cam.depth_to_color.tolist()
                if cam.depth_to_color is not None
                else None,
                "depth_scale": cam.depth_scale,
                "codecs": {"color": cam.color_codec, "depth": cam.depth_codec},
                "rig_pose": cam.rig_pose.tolist(),
                "first_timestamp_ns": int(frames.timestamps[0]) if len(frames) else None,
                "poses": _poses(frames),
                "raw_rgbd_bytes": _raw_bytes(frames),
                "color_gop": _gop(frames),
            }
        )
    raw = sum(c["raw_rgbd_bytes"] for c in cameras)
    return {
        "path": str(rec.path),
        "format_version": rec.format_version,
        "ratio_raw_rgbd": round(raw / size, 2) if size else None,
        "raw_rgbd_bytes": raw,
        "rig_frame_id": rec.rig_frame_id,
        "frames": sum(c["frames"] for c in cameras),
        "duration_s": round(rec.duration, 3),
        "size_bytes": size,
        "indexed": rec.index.indexed,
        "summary_problem": rec.index.summary_problem,
        "metadata": rec.metadata,
        "cameras": cameras,
    }


def _print_rig(info: dict[str, Any], as_json: bool) -> int:
    if as_json:
        print(json.dumps(info, indent=2))
        return 0
    print(
        f"{info['path']}: pcdcodec recording of {len(info['cameras'])} cameras, format version "
        f"{info['format_version']}"
    )
    print(f"  frames     {info['frames']} over {info['duration_s']} s, all cameras")
    print(f"  size       {mib(info['size_bytes'])}")
    _print_ratio(info, any(c["codecs"]["color"] for c in info["cameras"]))
    print(f"  rig frame  {info['rig_frame_id']}")
    for cam in info["cameras"]:
        intr = cam["intrinsics"]
        pose = np.asarray(cam["rig_pose"])
        angle = np.degrees(np.arccos(np.clip((np.trace(pose[:3, :3]) - 1) / 2, -1.0, 1.0)))
        t = [round(float(v), 4) for v in pose[:3, 3]]
        print(f"  camera {cam['name']} (frame {cam['frame_id']})")
        print(
            f"    frames     {cam['frames']} over {cam['duration_s']} s (nominal {cam['fps']} fps)"
        )
        print(
            f"    camera     {intr['width']}x{intr['height']}, fx={intr['fx']} fy={intr['fy']} "
            f"cx={intr['cx']} cy={intr['cy']}, depth scale {cam['depth_scale']} per metre"
        )
        color_cam = cam["color_intrinsics"]
        if color_cam:
            print(
                f"    color cam  {color_cam['width']}x{color_cam['height']}, fx={color_cam['fx']} "
                f"fy={color_cam['fy']} cx={color_cam['cx']} cy={color_cam['cy']}"
            )
        print(f"    color      {json.dumps(cam['codecs']['color'])}")
        _print_gop(cam["color_gop"], cam["fps"], "    ")
        print(f"    depth      {json.dumps(cam['codecs']['depth'])}")
        _print_poses(cam["poses"], "    ")
        print(f"    rig pose   translation {t} m, rotation {angle:.2f} deg")
    if info["metadata"]:
        print(f"  metadata   {json.dumps(info['metadata'])}")
    if info["summary_problem"]:
        print(
            f"  index      unusable ({info['summary_problem']}); frames found by reading the "
            "whole file"
        )
    elif not info["indexed"]:
        print("  index      missing: the writer did not finish; `pcdcodec recover` rewrites it")
    return 0


def _open_described(path: str, given: Any, options: dict[str, Any]) -> Any:
    """The input opened as ``encode`` opens it; one that does not say its depth scale (and
    is given none) is opened with a stand-in scale marked ``"unknown"``, to describe the rest."""
    from ..sources import CameraDefaults, open_source, settle_camera

    try:
        return open_source(path, defaults=given, **options)
    except InputError as first:
        if given is not None and given.depth_scale is not None:
            raise
        stand_in = CameraDefaults(depth_scale=1.0, origin="unknown")
        try:
            source = open_source(path, defaults=stand_in, **options)
        except InputError:
            raise first from None
    if given is not None:
        settle_camera(source, given)  # the camera flags, by the same rule
    return source


def _info_of_source(args: argparse.Namespace) -> int:
    """``info`` of an input (a folder, a bag...): what it holds and what ``encode`` would use."""
    args.src = args.input
    given = camera_defaults(args)
    options = source_options(args)
    with _open_described(args.input, given, options) as source:
        info = source.describe()
        if source.depth_scale_origin == "unknown":
            info["depth_scale"] = None
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
            f"(from {_origin_text(info['intrinsics_from'])})"
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
            f"    depth scale  {info['depth_scale']:g} per metre "
            f"(from {_origin_text(info['depth_scale_from'])})"
        )
    if given is not None and given.override:
        print("    override     the camera flags replace the input's own camera and depth scale")
    for note in [*info.get("camera_notes", []), *info.get("notes", [])]:
        print(f"    note         {cli_message(note)}")
    print_kept(info.get("kept", []))
    print_left_out(info.get("left_out", []))
    return 0


def _origin_text(origin: str) -> str:
    """Where a camera or depth scale came from, as ``info`` says it."""
    return "the input" if origin in ("input", "given") else origin


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


def cmd_info(args: argparse.Namespace) -> int:
    """``pcdcodec info PATH``: a recording described, or an input and what ``encode`` would use."""
    from ..recording import open as open_recording
    from ..sources.base import detect_kind

    path = Path(args.input)
    # A ROS 2 bag stored as MCAP starts with the same magic as a recording: the readers'
    # probes tell them apart by the MCAP profile. A recording is described as a recording.
    if detect_kind(path) not in (None, "recording") or path.is_dir():
        return _info_of_source(args)  # a folder is an input: say what it holds or lacks
    given = [
        "--" + key.replace("_", "-")
        for key in _INPUT_FLAGS
        if getattr(args, key, None) not in (None, False)
    ]
    if given and path.is_file():
        raise InputError(
            f"{' '.join(given)} {'describes' if len(given) == 1 else 'describe'} how to read "
            f"an input; {args.input!r} is not one "
            "(a recording keeps its own camera and depth scale)"
        )
    with open_recording(args.input) as rec:
        if _is_rig(rec):
            return _print_rig(_rig_info(rec), args.json)
        info = _info(rec)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    cam = info["intrinsics"]
    print(f"{info['path']}: pcdcodec recording, format version {info['format_version']}")
    print(f"  frames     {info['frames']} over {info['duration_s']} s (nominal {info['fps']} fps)")
    print(
        f"  size       {mib(info['size_bytes'])}"
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
    _print_ratio(info, bool(info["codecs"]["color"]))
    print(f"  color      {json.dumps(info['codecs']['color'])}")
    _print_gop(info["color_gop"], info["fps"], "  ")
    print(f"  depth      {json.dumps(info['codecs']['depth'])}")
    _print_poses(info["poses"], "  ")
    lost = info["frames_without_color"]
    if lost:
        print(
            f"  no color   {len(lost)} frame(s) kept by `pcdcodec recover` without their color, "
            f"lost to damage (first: frame {lost[0]})"
        )
    print_kept(info["kept"])
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


def cmd_codecs(args: argparse.Namespace) -> int:
    """``pcdcodec codecs``: the registered codecs, lossless or lossy, and their defaults."""
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


def cmd_view(args: argparse.Namespace) -> int:
    """``pcdcodec view REC``: the recording in the Rerun viewer (or Open3D's)."""
    from ..viewer import view, view_open3d

    if args.open3d:
        view_open3d(args.input, every=args.every, threads=args.threads)
        return 0
    saved = view(
        args.input,
        save=args.save,
        every=args.every,
        max_frames=args.max_frames,
        stride=args.stride,
        threads=args.threads,
        points=args.points,
        depth_format=args.depth,
        video=not args.no_video,
    )
    if saved is not None:
        print(f"wrote {saved} (open it with: rerun {saved})")
    return 0
