"""``pcdcodec record``: record live RealSense cameras (or ``.bag`` files played back) into one
recording, compressing the frames as they arrive.

The cameras are opened through :func:`pcdcodec.sources.realsense_live`, read by
:class:`~pcdcodec.cli.capture.Capture` and written by the recording writer: one camera with
:class:`~pcdcodec.RecordingWriter`, several with the multi-camera writer. A status line on
stderr shows each camera's frame rate and drops, the MB/s written and the ratio so far; Ctrl-C
ends the capture, writes what was captured, closes the file and prints the summary.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..sync import parse_duration
from .capture import POINTCLOUD2_BYTES_PER_POINT, Camera, Capture, CaptureStats, file_bytes
from .options import mib, parse_codec
from .show import print_left_out

__all__ = ["QUEUE_PER_CAMERA", "camera_names", "cmd_record"]

#: Frames of each camera that may wait for the encoder: half a second at 30 fps, which rides
#: out the encoder's stalls on a busy machine (about 23 MB a camera at 640 x 480).
QUEUE_PER_CAMERA = 15


def camera_names(given: list[str] | None, serials: list[str | None]) -> list[str]:
    """The cameras' names in the recording: ``given`` (``--name``), else ``rs_<serial>`` when
    every camera has a serial of its own, else ``cam0``, ``cam1``, ..."""
    n = len(serials)
    if given:
        if len(given) != n:
            raise InputError(f"{len(given)} --name for {n} cameras; give one name per camera")
        if len(set(given)) != n:
            raise InputError(f"camera names must differ, got {given}")
        return list(given)
    if all(serials) and len(set(serials)) == n:
        return [f"rs_{s}" for s in serials]
    return [f"cam{i}" for i in range(n)]


def read_rig_file(path: str, count: int) -> Any:
    """The rig file ``path`` for ``count`` live cameras: its cameras name them in order, place
    them on the rig (``extrinsic``; the identity where it has none) and may set their codecs and
    rate. A live camera is its own source and calibration, so ``source``, ``namespace``,
    ``intrinsics`` and ``depth_scale`` are errors."""
    from ..sources.rigfile import read_rig

    rig = read_rig(path)
    if len(rig.cameras) != count:
        raise InputError(
            f"rig file {path!r} has {len(rig.cameras)} cameras for {count} live cameras; give "
            "one entry per --serial or --playback, in the same order"
        )
    for entry in rig.cameras:
        given = [k for k in ("source", "namespace") if getattr(entry, k) is not None]
        given += sorted(entry.source_options)
        if given:
            raise InputError(
                f"rig file {path!r}, camera {entry.name}: {', '.join(given)} cannot be set for a "
                "live camera (it is its own source and calibration)"
            )
    return rig


def _open_sources(args: argparse.Namespace) -> list[Any]:
    """One live source per ``--playback`` file or ``--serial`` (or per connected camera)."""
    from ..sources.live import connected_serials, realsense_live

    common: dict[str, Any] = {
        "width": args.width,
        "height": args.height,
        "fps": args.fps,
        "color_width": args.color_width,
        "color_height": args.color_height,
        "color_fps": args.color_fps,
        "color": not args.depth_only,
        "align": args.align,
        "max_frames": args.frames,
    }
    if args.max_difference is not None:
        if args.depth_only:
            raise InputError("--max-difference pairs color with depth; --depth-only has no color")
        common["max_difference"] = parse_duration(args.max_difference, "--max-difference")
    if args.playback and args.serial:
        raise InputError("give --playback files or --serial cameras, not both")
    targets: list[dict[str, Any]]
    if args.playback:
        targets = [
            {"playback": p, "real_time": args.real_time, "loop": args.loop} for p in args.playback
        ]
    else:
        if args.real_time or args.loop:
            raise InputError("--real-time and --loop are for --playback files")
        serials = args.serial or connected_serials()
        if not serials:
            raise InputError(
                "no RealSense camera is connected; pass --playback FILE.bag to record from a file"
            )
        several = len(serials) > 1
        targets = [
            {
                "serial": s,
                "global_time": True if several or args.global_time else None,
                "sync": None if not args.sync else ("master" if i == 0 else "slave"),
            }
            for i, s in enumerate(serials)
        ]
    sources: list[Any] = []
    try:
        for target in targets:
            sources.append(realsense_live(**common, **target))
    except BaseException:
        for s in sources:
            s.close()
        raise
    return sources


class _Output:
    """The recording: one camera's writer, or the multi-camera writer, behind ``write``."""

    def __init__(
        self, args: argparse.Namespace, names: list[str], sources: list[Any], rig: Any
    ) -> None:
        from ..recording.rig import CameraSpec, RigWriter
        from ..recording.writer import RecordingWriter

        color = None if args.depth_only else parse_codec(args.color, "color")
        depth = parse_codec(args.depth, "depth")
        self.path = Path(args.output)
        self.names = names
        if len(sources) == 1 and rig is None:
            s = sources[0]
            self.writer: Any = RecordingWriter(
                self.path,
                intrinsics=s.intrinsics,
                depth_scale=s.depth_scale,
                color=color,
                depth=depth,
                fps=s.fps,
                metadata={**s.metadata, "camera": names[0]},
                overwrite=args.overwrite,
                color_intrinsics=s.color_intrinsics,
                depth_to_color=s.depth_to_color,
            )
            self.rig = False
            return
        entries = rig.cameras if rig is not None else [None] * len(sources)
        specs = []
        for name, s, entry in zip(names, sources, entries, strict=True):
            own = entry.overrides if entry is not None else {}
            specs.append(
                CameraSpec(
                    name=name,
                    intrinsics=s.intrinsics,
                    depth_scale=s.depth_scale,
                    fps=own.get("fps", s.fps),
                    color=None if args.depth_only else own.get("color", color),
                    depth=own.get("depth", depth),
                    color_intrinsics=s.color_intrinsics,
                    depth_to_color=s.depth_to_color,
                    rig_pose=entry.extrinsic if entry is not None else None,
                    frame_id=entry.frame_id if entry is not None else None,
                )
            )
        metadata = {"source": "realsense-live"}
        for name, s in zip(names, sources, strict=True):
            metadata.update({f"{name}.{k}": v for k, v in s.metadata.items()})
        self._color = [spec.color is not None for spec in specs]
        self.writer = RigWriter(
            self.path,
            specs,
            overwrite=args.overwrite,
            metadata=metadata,
            rig_frame_id=rig.frame if rig is not None else "rig",
        )
        self.rig = True

    def write(self, index: int, frame: Any) -> None:
        if self.rig:
            color = frame.color if self._color[index] else None  # a camera recorded depth only
            self.writer.write(self.names[index], color, frame.depth, frame.timestamp_ns)
        else:
            self.writer.write(frame.color, frame.depth, frame.timestamp_ns)

    def bytes_written(self) -> int:
        """Bytes of encoded frames written so far."""
        return int(self.writer.bytes_color) + int(self.writer.bytes_depth)

    def close(self) -> None:
        self.writer.close()


class _Status:
    """The status line: rewritten in place on a terminal, a line every few seconds in a log."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self._last = 0.0
        self._warned = False

    def __call__(self, stats: CaptureStats) -> None:
        if self.quiet:
            return
        behind = [c["name"] for c in stats.cameras if c["dropped_by_us"]]
        if behind and not self._warned:
            self._warned = True
            self._print(
                f"warning: compression cannot keep up with {', '.join(behind)}; frames are "
                "dropped (try faster codecs, e.g. --depth zstd --color h264:preset=ultrafast, "
                "or fewer frames per second)",
                newline=True,
            )
        if self.tty:
            self._print(stats.line())
        elif stats.elapsed - self._last >= 5.0:
            self._last = stats.elapsed
            self._print(stats.line(), newline=True)

    def _print(self, text: str, newline: bool = False) -> None:
        if self.tty:
            sys.stderr.write("\r\033[K" + text + ("\n" if newline else ""))
        else:
            sys.stderr.write(text + "\n")
        sys.stderr.flush()

    def done(self) -> None:
        if self.tty and not self.quiet:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _viewer(args: argparse.Namespace, names: list[str], sources: list[Any]) -> Any:
    if not (args.view or args.view_save):
        return None
    from ..geometry.projector import Projector
    from ..viewer import LiveView

    cameras = [
        (
            name,
            Projector(
                s.intrinsics,
                s.depth_scale,
                color_intrinsics=s.color_intrinsics,
                depth_to_color=s.depth_to_color,
            ),
        )
        for name, s in zip(names, sources, strict=True)
    ]
    return LiveView(cameras, save=args.view_save)


def cmd_record(args: argparse.Namespace) -> int:
    """``pcdcodec record -o REC``: cameras (or playback files) into one recording, live."""
    for name in ("duration", "frames", "queue"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise InputError(f"--{name} must be positive, got {value}")
    sources = _open_sources(args)
    try:
        rig = None
        if args.rig is not None:
            if args.name:
                raise InputError("give camera names with --name or in the --rig file, not both")
            rig = read_rig_file(args.rig, len(sources))
            names = [entry.name for entry in rig.cameras]
        else:
            names = camera_names(args.name, [s.serial for s in sources])
        view = _viewer(args, names, sources)
        output = _Output(args, names, sources, rig)
        cameras = [Camera(n, s) for n, s in zip(names, sources, strict=True)]
        # Played back at full speed, a file waits for the encoder; a camera never does.
        block = all(s.playback and not s.real_time for s in sources)
        capture = Capture(
            cameras,
            output.write,
            output.bytes_written,
            queue_size=args.queue or QUEUE_PER_CAMERA * len(sources),
            block=block,
            duration=args.duration,
            on_frame=None if view is None else view.log,
        )
        status = _Status(args.quiet)
        interrupted: list[int] = []

        def on_sigint(signum: int, frame: Any) -> None:
            if interrupted:  # a second Ctrl-C: stop at once
                signal.signal(signal.SIGINT, signal.default_int_handler)
                raise KeyboardInterrupt
            interrupted.append(signum)
            capture.stop()

        previous = signal.signal(signal.SIGINT, on_sigint)
        try:
            try:
                capture.run(status)
            finally:
                output.close()
                status.done()
                if view is not None:
                    view.close()
        finally:
            signal.signal(signal.SIGINT, previous)
    finally:
        for s in sources:
            s.close()
    _summary(args, capture.stats(), sources, bool(interrupted), block)
    return 0


def _summary(
    args: argparse.Namespace, stats: CaptureStats, sources: list[Any], stopped: bool, block: bool
) -> None:
    size = file_bytes(args.output)
    total = sum(int(c["written"]) for c in stats.cameras)
    how = "stopped by Ctrl-C" if stopped else "done"
    print(
        f"wrote {total} frames of {len(sources)} camera(s) to {args.output} ({mib(size)}) in "
        f"{stats.elapsed:.1f} s ({how})"
    )
    raw = stats.points * POINTCLOUD2_BYTES_PER_POINT
    if size:
        print(
            f"  ratio        {raw / size:.1f}x against PointCloud2 XYZRGB (32 bytes per valid "
            f"point: {mib(raw)})"
        )
    for c, s in zip(stats.cameras, sources, strict=True):
        drops = s.camera_drops
        domain = s.metadata.get("timestamp_domain", "unknown")
        print(
            f"  {c['name']:12} {c['written']} frames, dropped by the camera: {drops['depth']} "
            f"depth / {drops['color']} color, dropped by us: {c['dropped_by_us']} "
            f"(timestamps: {domain})"
        )
        unpaired = s.dropped
        if any(unpaired.values()):
            print(
                f"  {'':12} dropped {unpaired['color']} color and {unpaired['depth']} depth "
                f"images without a partner within {s.max_difference / 1e6:g} ms"
            )
    for s in sources:
        left_out = [item.to_dict() for item in s.left_out]
        if left_out:
            print(f"  input        {s.path}")
            print_left_out(left_out, "    ")
    if any(c["dropped_by_us"] for c in stats.cameras):
        print("  note         compression did not keep up: frames were dropped before encoding")
    elif block:
        print("  note         played back at full speed: the files waited for the encoder")
