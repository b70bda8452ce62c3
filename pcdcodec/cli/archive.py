"""The ``archive`` command: many inputs compressed on a Dask cluster, with the camera flags
that fill in what an input lacks (``--camera``, ``--intrinsics``, ``--depth-scale``) and
``--input-camera`` for one input.

It takes the parsed command line and returns the exit status.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from ..errors import InputError
from .options import cli_message, parse_codec


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
    return CameraDefaults(
        intrinsics, scale, origin, scale_origin, how_to_override="--input-camera INPUT=CAMERA"
    )


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


def cmd_archive(args: argparse.Namespace) -> int:
    """``pcdcodec archive SRC... -o OUT``: every input compressed; 1 if any failed."""
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
