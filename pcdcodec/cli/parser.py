"""The ``pcdcodec`` command line: its parser, one subcommand per entry of :data:`_COMMANDS`.

The option groups that several commands share (the camera and RGB-D folder flags, the bag
topics) are built once here. :func:`parse_args` lets every command take its options anywhere
among its positional arguments. The commands themselves live beside this module: ``record``
(encode, decode, verify, recover), ``live`` (record: live cameras), ``show`` (info, codecs,
view), ``convert`` (export, import), ``bench`` (demo, bench) and ``archive``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

from .._version import __version__
from ..codec import KINDS
from ..color import DEFAULT_COLOR_CODEC
from ..depth import DEFAULT_DEPTH_CODEC
from .archive import cmd_archive
from .bench import cmd_bench, cmd_demo
from .convert import cmd_export, cmd_import
from .live import cmd_record
from .record import cmd_decode, cmd_encode, cmd_join, cmd_recover, cmd_verify
from .show import cmd_codecs, cmd_info, cmd_view

# -- option groups shared by several commands --------------------------------------------------


class _CameraFlag(argparse.Action):
    """``--camera NAME``; ``--camera list`` prints the presets with their values and exits."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option: Any = None) -> None:
        if values == "list":
            _print_presets()
            parser.exit()
        setattr(namespace, self.dest, values)


def _add_camera_options(p: argparse.ArgumentParser) -> None:
    """The camera flags and the RGB-D folder flags, for the commands that read an input."""
    from ..geometry.camera import CAMERA_PRESETS

    g = p.add_argument_group(
        "camera (the input's own always wins: a recording's or a bag's camera, a folder's "
        "camera.json, intrinsics.K.txt, camera-intrinsics.txt, CameraInfo YAML or Open3D "
        "intrinsic JSON, or its dataset's convention; these flags fill in what the input "
        "lacks, with a note where they contradict it; --override makes them replace it)"
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
    g.add_argument(
        "--override",
        action="store_true",
        help="the camera flags replace the input's own camera and depth scale (the summary "
        "says what was replaced)",
    )
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
        help="the 4x4 depth-to-color transform in metres, a text file of 16 numbers "
        "row-major: with --color-intrinsics for a folder (default: identity), or for a bag "
        "whose color camera is apart from depth and whose tf does not place it",
    )
    f.add_argument("--depth-only", action="store_true", help="read depth, leave color out")


def _print_presets() -> int:
    """The camera presets as a table (``--camera list``)."""
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
    """The bag topic flags, for the commands that read an input."""
    g = p.add_argument_group("bag topics (default: chosen by type and namespace)")
    g.add_argument("--depth-topic", help="depth Image or CompressedImage topic")
    g.add_argument("--color-topic", help="color topic ('' for depth only)")
    g.add_argument("--info-topic", help="CameraInfo topic")
    g.add_argument("--cloud-topic", help="organized PointCloud2 topic (read instead of images)")
    g.add_argument(
        "--include-topic",
        action="append",
        metavar="PATTERN",
        help="keep only the other topics matching PATTERN (shell-style, e.g. '/imu*'; "
        "repeatable). By default every topic of a bag not made into frames is kept as it came",
    )
    g.add_argument(
        "--exclude-topic",
        action="append",
        metavar="PATTERN",
        help="leave out the other topics matching PATTERN (repeatable; '*' keeps the camera only)",
    )
    g.add_argument(
        "--max-difference",
        metavar="DURATION",
        help="the largest time between a color and a depth image paired into one frame, with "
        "its unit: 150ms, 0.15s, 500us (default 20ms; bags, RealSense .bag, Azure Kinect .mkv, "
        "TUM lists)",
    )
    g.add_argument(
        "--passthrough",
        nargs="?",
        const=True,
        default=False,
        metavar="TOPIC",
        help="record the bag's h264/h265 video packets as they are (CompressedVideo, FFMPEGPacket)",
    )


# -- each command's options ---------------------------------------------------------------


def _demo_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "-o",
        "--output",
        default="pcdcodec-demo",
        help="folder for the PLY of frame 0 (default: %(default)s)",
    )
    p.add_argument("--frames", type=int, default=None, help="use only the first N frames")


def _encode_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "src",
        nargs="*",
        help="an RGB-D folder, a ROS 1 bag, a ROS 2 bag folder or file, a RealSense .bag, an "
        "Azure Kinect .mkv, ...; several inputs, or a bag of several cameras, make one "
        "recording of a rig",
    )
    p.add_argument("-o", "--output", required=True, help="the .pcdc file to write")
    p.add_argument(
        "--rig",
        metavar="FILE",
        help="a rig file (YAML): the cameras' names, sources and extrinsics (docs/rig.md)",
    )
    p.add_argument(
        "--color", default=DEFAULT_COLOR_CODEC, help="color codec, e.g. h264 or h264:crf=20"
    )
    p.add_argument(
        "--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec, e.g. depthac or zstd:level=9"
    )
    p.add_argument(
        "--fps",
        type=float,
        default=None,
        help="nominal frame rate (default: a recording's own, else 30)",
    )
    p.add_argument("--max-frames", type=int, default=None, help="encode only the first N")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )
    _add_camera_options(p)
    _add_topic_options(p)
    p.add_argument(
        "--kept-images",
        choices=("lossless", "raw"),
        default="lossless",
        help="kept Image and organized PointCloud2 topics of a bag: compressed, given back byte "
        "for byte, readable by pcdcodec only (lossless, the default); or as they came (raw)",
    )


def _record_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", required=True, help="the .pcdc file to write")
    g = p.add_argument_group("cameras (default: every RealSense camera connected)")
    g.add_argument(
        "--serial", action="append", metavar="SERIAL", help="a camera's serial number; repeatable"
    )
    g.add_argument(
        "--playback",
        action="append",
        metavar="FILE",
        help="play a RealSense .bag back as a camera (instead of --serial); repeatable",
    )
    g.add_argument(
        "--name",
        action="append",
        metavar="NAME",
        help="the cameras' names in the recording, in order (default: rs_<serial>, else cam0, "
        "cam1, ...); repeatable",
    )
    g.add_argument(
        "--rig",
        metavar="FILE",
        help="rig file (docs/rig.md): the cameras' names, poses on the rig, codecs and rates, "
        "one entry per camera in order",
    )
    g.add_argument("--width", type=int, help="depth width (default: the camera's)")
    g.add_argument("--height", type=int, help="depth height")
    g.add_argument("--fps", type=int, help="depth frame rate")
    g.add_argument("--color-width", type=int, help="color width (default: as depth)")
    g.add_argument("--color-height", type=int, help="color height (default: as depth)")
    g.add_argument("--color-fps", type=int, help="color frame rate (default: as depth)")
    g.add_argument(
        "--align",
        action="store_true",
        help="color aligned to depth by librealsense (default: as the camera gives it, with "
        "both cameras and the extrinsic)",
    )
    g.add_argument("--depth-only", action="store_true", help="record depth, leave color out")
    g.add_argument(
        "--max-difference",
        metavar="DURATION",
        help="the largest time between a color and a depth image paired into one frame, with "
        "its unit: 150ms, 0.15s, 500us (default 20ms, as for every input)",
    )
    g.add_argument(
        "--global-time",
        action="store_true",
        help="the devices' global timestamps (on by default with several cameras)",
    )
    g.add_argument(
        "--sync",
        action="store_true",
        help="hardware sync of cameras wired together: the first is the master, the others slaves",
    )
    g.add_argument(
        "--real-time",
        action="store_true",
        help="play --playback files at their recorded pace, dropping frames as a camera does "
        "(default: as fast as the encoder takes them)",
    )
    g.add_argument("--loop", action="store_true", help="play --playback files again and again")
    s = p.add_argument_group("when to stop (default: Ctrl-C, or the end of the playback files)")
    s.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    s.add_argument("--frames", type=int, metavar="N", help="stop after N frames of each camera")
    p.add_argument(
        "--color", default=DEFAULT_COLOR_CODEC, help="color codec, e.g. h264 or h264:crf=20"
    )
    p.add_argument(
        "--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec, e.g. depthac or zstd:level=9"
    )
    p.add_argument(
        "--queue",
        type=int,
        metavar="N",
        help="frames that may wait for the encoder before new ones are dropped, all cameras "
        "together (default: 15 per camera, half a second at 30 fps)",
    )
    p.add_argument(
        "--view", action="store_true", help="show the frames in a Rerun viewer (pcdcodec[view])"
    )
    p.add_argument("--view-save", metavar="OUT.rrd", help="write what --view shows to a file")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.add_argument("-q", "--quiet", action="store_true", help="no status line")


def _add_threads_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--threads",
        type=int,
        default=None,
        metavar="N",
        help="cores that reading may use: with 2 or more, frames decode ahead on N threads "
        "(default: one frame at a time)",
    )


def _decode_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="the .pcdc file")
    p.add_argument("-o", "--output", required=True, help="output folder (TUM layout)")
    p.add_argument("--ply", action="store_true", help="also write a PLY point cloud per frame")
    p.add_argument("--pcd", action="store_true", help="also write a PCD point cloud per frame")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )
    _add_threads_option(p)


def _info_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--fps", type=float, default=30.0, help="nominal frame rate of a folder")
    _add_camera_options(p)
    _add_topic_options(p)
    p.set_defaults(max_frames=None)  # options.source_options reads it; info has no flag for it


def _verify_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="print only problems (on stderr), if any"
    )


def _recover_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--overwrite", action="store_true")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )


def _join_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("parts", nargs="+", metavar="PART", help="closed recordings, in time order")
    p.add_argument("-o", "--output", required=True, help="the joined .pcdc file")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )


def _export_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input")
    p.add_argument(
        "output_pos",
        nargs="?",
        metavar="OUTPUT",
        help="output bag (file for rosbag1, folder for rosbag2) or folder (or -o OUTPUT)",
    )
    p.add_argument("-o", "--output", help="the output, as the second argument says")
    p.add_argument(
        "--to",
        choices=("rosbag", "rosbag1", "rosbag2"),
        help="write a ROS bag; rosbag: the kind the recording's input was (else ROS 1)",
    )
    p.add_argument(
        "--storage", choices=("mcap", "sqlite3"), help="ROS 2 storage (default: the input's, mcap)"
    )
    p.add_argument("--cloud", action="store_true", help="add the organized PointCloud2 XYZRGB")
    p.add_argument(
        "--compressed-depth", action="store_true", help="depth as compressedDepth (16UC1 mm)"
    )
    p.add_argument(
        "--no-kept",
        dest="kept",
        action="store_false",
        help="the camera alone: leave out the topics the recording kept as they came",
    )
    p.add_argument("--layout", default="paper", help="without --to: paper (video + LZ4 + JSON)")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="only errors: no progress, no summary"
    )


def _import_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="folder written by `export --layout paper`")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--depth", default=DEFAULT_DEPTH_CODEC, help="depth codec for the new file")
    p.add_argument("--overwrite", action="store_true")


def _bench_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "src", help="a .pcdc recording, or what `encode` accepts: a folder, bag or camera file"
    )
    p.add_argument("--depth", default=None, help="depth codecs, comma-separated (default: all)")
    p.add_argument(
        "--color",
        default=None,
        help="color codecs, comma-separated (default: h264, h265, av1: those available)",
    )
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
    _add_topic_options(p)
    p.set_defaults(max_frames=None)  # --frames says how many; options.source_options reads it


def _archive_options(p: argparse.ArgumentParser) -> None:
    from ..geometry.camera import CAMERA_PRESETS

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


def _view_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="the .pcdc file")
    p.add_argument("--save", metavar="OUT.rrd", help="write a Rerun file instead of a window")
    p.add_argument("--every", type=int, default=1, help="show every n-th frame")
    p.add_argument("--max-frames", type=int, default=None, help="show at most N frames")
    p.add_argument(
        "--points",
        action="store_true",
        help="log the point cloud too (Rerun draws one from the depth image itself)",
    )
    p.add_argument(
        "--stride", type=int, default=2, help="point cloud of every n-th pixel (default: 2)"
    )
    p.add_argument(
        "--depth",
        choices=("png", "rvl", "raw"),
        default="png",
        help="depth as a lossless 16-bit PNG (default, smallest), RVL (fastest) or raw pixels",
    )
    p.add_argument(
        "--no-video",
        action="store_true",
        help="color as JPEG images, not the recording's own H.264/H.265/AV1 packets",
    )
    p.add_argument("--open3d", action="store_true", help="play in Open3D's window instead")
    _add_threads_option(p)


def _codecs_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--kind", choices=KINDS, help="only codecs of this kind")


_Command = tuple[
    str, str, Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int]
]

#: Each command: its name, its help line, the function that adds its options, and the
#: function that runs it (it takes the parsed command line, returns the exit status).
_COMMANDS: tuple[_Command, ...] = (
    ("demo", "encode and decode the bundled sample, print the numbers", _demo_options, cmd_demo),
    (
        "encode",
        "encode any input: RGB-D folder, ROS 1/2 bag, RealSense .bag, Azure Kinect .mkv",
        _encode_options,
        cmd_encode,
    ),
    (
        "record",
        "record live RealSense cameras (pcdcodec[realsense]), compressing as frames arrive",
        _record_options,
        cmd_record,
    ),
    ("decode", "write PNG color, 16-bit PNG depth and point clouds", _decode_options, cmd_decode),
    (
        "info",
        "describe a recording, or an input (folder, bag...) and what encode would use",
        _info_options,
        cmd_info,
    ),
    ("verify", "decode every frame and check every checksum", _verify_options, cmd_verify),
    ("recover", "rewrite a damaged or unfinished recording", _recover_options, cmd_recover),
    ("join", "join recordings written one after another into one", _join_options, cmd_join),
    (
        "export",
        "write a recording as a ROS bag or in the paper's layout",
        _export_options,
        cmd_export,
    ),
    ("import", "read the paper layout back into a .pcdc file", _import_options, cmd_import),
    ("bench", "compare codecs on a recording or an RGB-D folder", _bench_options, cmd_bench),
    ("archive", "compress many inputs on a Dask cluster, resumably", _archive_options, cmd_archive),
    ("view", "show a recording in the Rerun viewer (pcdcodec[view])", _view_options, cmd_view),
    ("codecs", "list the registered codecs and their defaults", _codecs_options, cmd_codecs),
)


def _build() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The parser, and the parser of each command by name."""
    parser = argparse.ArgumentParser(
        prog="pcdcodec",
        description="Compress RGB-D point cloud streams and give them back as Open3D clouds.",
    )
    parser.add_argument("--version", action="version", version=f"pcdcodec {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands: dict[str, argparse.ArgumentParser] = {}
    for name, what, add_options, run in _COMMANDS:
        p = sub.add_parser(name, help=what)
        add_options(p)
        p.set_defaults(func=run)
        commands[name] = p
    return parser, commands


def build_parser() -> argparse.ArgumentParser:
    """The ``pcdcodec`` parser, with a subcommand for each command."""
    return _build()[0]


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """The command line as parsed by :func:`build_parser`, with each command's options taken
    anywhere among its positional arguments (``export run.pcdc --layout paper out/``)."""
    parser, commands = _build()
    words = list(sys.argv[1:] if argv is None else argv)
    if not words or words[0] not in commands:  # --help, --version, or a missing command
        return parser.parse_args(words)
    args = commands[words[0]].parse_intermixed_args(words[1:])
    args.command = words[0]
    return args
