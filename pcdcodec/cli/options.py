"""From parsed options to the library's arguments, one rule for every command.

The camera flags (``--camera``, ``--intrinsics``, ``--fx``..., ``--override``) become a
:class:`~pcdcodec.sources.CameraDefaults` (:func:`camera_defaults`); the RGB-D folder flags and the
bag topic flags become reader options here; codec specs become codecs; and :func:`cli_message`
puts a library error message in the CLI's words (flags instead of keyword arguments).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..registry import parse_codec_spec

#: ``"h264:crf=20,preset=fast"`` to a codec (:func:`pcdcodec.registry.parse_codec_spec`).
parse_codec = parse_codec_spec


def _pinhole_flags(args: argparse.Namespace) -> dict[str, float] | None:
    """``--fx --fy --cx --cy`` (all or none) as a camera without its image size."""
    given = {k: getattr(args, k) for k in ("fx", "fy", "cx", "cy")}
    if all(v is None for v in given.values()):
        return None
    missing = [f"--{k}" for k, v in given.items() if v is None]
    if missing:
        raise InputError(f"intrinsics need --fx --fy --cx --cy; missing {' '.join(missing)}")
    return {k: float(v) for k, v in given.items()}


def camera_defaults(args: argparse.Namespace) -> Any:
    """The camera flags as a :class:`~pcdcodec.sources.CameraDefaults` (or ``None`` without
    any), one rule for ``encode`` and ``info``: the input's own camera and depth scale win and
    the flags fill in what it lacks, a contradiction said in a note; with ``--override`` the
    flags replace the input's own, said in a note too. At most one of --fx/--fy/--cx/--cy,
    --intrinsics FILE and --camera NAME; --depth-scale wins over a preset's."""
    from ..geometry.camera import camera_preset
    from ..sources.base import CameraDefaults

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
    override = bool(getattr(args, "override", False))
    intrinsics: Any = None
    scale = args.depth_scale
    origin = "--depth-scale"
    if args.camera is not None:
        preset = camera_preset(args.camera)
        intrinsics, origin = preset.intrinsics, f"--camera {args.camera}"
        scale = scale if scale is not None else preset.depth_scale
    elif args.intrinsics is not None:
        intrinsics, origin = args.intrinsics, f"--intrinsics {args.intrinsics}"
    elif by_values:
        intrinsics, origin = _pinhole_flags(args), "--fx --fy --cx --cy"
    if intrinsics is None and scale is None:
        if override:
            raise InputError(
                "--override replaces the input's camera or depth scale with the flags' own: "
                "give --camera NAME, --intrinsics FILE, --fx --fy --cx --cy or --depth-scale"
            )
        return None
    scale_origin = "--depth-scale" if args.depth_scale is not None else None
    return CameraDefaults(intrinsics, scale, origin, scale_origin, override=override)


#: Library wording (keyword arguments) and the CLI flag that says the same.
_CLI_WORDS = (
    ("pass overwrite=True", "pass --overwrite"),
    ("overwrite=True", "--overwrite"),
    ("override=True", "--override"),
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
    (
        "pass depth_to_color= (the 4x4 depth-to-color transform in metres, 16 numbers "
        "row-major), or color_topic='' for depth only",
        "pass --depth-to-color FILE (a text file of the 16 numbers of the 4x4 depth-to-color "
        "transform in metres, row-major), or --color-topic '' for depth only",
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


def folder_options(args: argparse.Namespace) -> dict[str, Any]:
    """The folder flags as options of :func:`pcdcodec.datasets.open_folder`."""
    opts: dict[str, Any] = {}
    for key in ("depth_pattern", "color_pattern", "color_intrinsics", "depth_to_color"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    if getattr(args, "depth_only", False):
        opts["color"] = False
    return opts


#: The readers that pair color and depth by time, and take ``max_difference``.
PAIRING_KINDS = ("rosbag", "realsense", "azure_kinect", "folder")

#: ``--depth-only`` as each reader's option.
DEPTH_ONLY: dict[str, dict[str, Any]] = {
    "rosbag": {"color_topic": ""},
    "realsense": {"color_topic": ""},
    "azure_kinect": {"color": False},
    "folder": {"color": False},
}

#: The topic flags each kind of input takes.
TOPIC_FLAGS = {
    "rosbag": ("depth_topic", "color_topic", "info_topic", "cloud_topic"),
    "realsense": ("color_topic",),
}


def source_options(args: argparse.Namespace) -> dict[str, Any]:
    """The reader options of ``args.src`` from the flags (``--max-frames``, the folder and the
    topic flags), refusing flags that do not apply to that kind of input. The camera flags
    (``--depth-scale`` among them) are :func:`camera_defaults`."""
    from ..sources.base import detect_kind

    opts: dict[str, Any] = {}
    if args.max_frames is not None:
        opts["max_frames"] = args.max_frames
    kind = detect_kind(args.src)
    folder = folder_options(args)
    if kind is None and folder.get("depth_pattern") is not None and Path(args.src).is_dir():
        kind = "folder"  # a folder of files named as the patterns say
    if getattr(args, "max_difference", None) is not None:
        from ..sync import parse_duration

        if kind not in (None, *PAIRING_KINDS):
            raise InputError(
                f"--max-difference applies to inputs whose color and depth are paired by time "
                f"({', '.join(PAIRING_KINDS)}); {args.src!r} is a {kind}"
            )
        opts["max_difference"] = parse_duration(args.max_difference, "--max-difference")
    if kind == "rosbag" and "depth_to_color" in folder and "color_intrinsics" not in folder:
        opts["depth_to_color"] = folder.pop("depth_to_color")  # a color camera apart in a bag
    topics = {
        "depth_topic": args.depth_topic,
        "color_topic": args.color_topic,
        "info_topic": args.info_topic,
        "cloud_topic": args.cloud_topic,
    }
    given = {k: v for k, v in topics.items() if v is not None}
    if kind in DEPTH_ONLY and folder.pop("color", True) is False:
        if (given.get("color_topic") or "none").strip().lower() not in ("", "none"):
            raise InputError("--depth-only and --color-topic contradict each other; give one")
        opts.update(DEPTH_ONLY[kind])  # --depth-only, in the reader's own words
    if kind == "folder":
        if getattr(args, "fps", None) is not None:
            opts["fps"] = args.fps
        opts.update(folder)
    elif folder and kind is not None:
        names = ["--depth-only" if k == "color" else "--" + k.replace("_", "-") for k in folder]
        raise InputError(
            f"{' '.join(names)} {'applies' if len(names) == 1 else 'apply'} to RGB-D folders; "
            f"{args.src!r} is a {kind}"
        )
    allowed = TOPIC_FLAGS.get(kind or "rosbag", ())
    refused = [k for k in given if k not in allowed]
    if refused:
        flags = " ".join("--" + k.replace("_", "-") for k in refused)
        where = "ROS bags" if kind == "realsense" else "bags"
        raise InputError(
            f"{flags} {'applies' if len(refused) == 1 else 'apply'} to {where}; {args.src!r} is "
            f"a {kind}" + (" (its depth alone: --depth-only)" if kind in DEPTH_ONLY else "")
        )
    opts.update(given)
    patterns = {
        k: v
        for k, v in (
            ("include_topics", getattr(args, "include_topic", None)),
            ("exclude_topics", getattr(args, "exclude_topic", None)),
        )
        if v
    }
    if patterns and kind not in KEEPING_KINDS:
        raise InputError(
            f"--include-topic and --exclude-topic choose the other topics of a bag kept beside "
            f"the camera; {args.src!r} is a {kind}"
        )
    opts.update(patterns)
    return opts


#: The readers that keep their input's other topics (``include_topics``, ``exclude_topics``).
KEEPING_KINDS = (None, "rosbag", "realsense", "azure_kinect", "recording")


def mib(n: float) -> str:
    """A byte count in MiB, as the commands print it."""
    return f"{n / 2**20:.2f} MiB"
