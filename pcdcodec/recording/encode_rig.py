"""Several inputs, or a bag of several cameras, into one recording of a rig: :func:`encode_rig`.

The cameras come from a rig file (:mod:`pcdcodec.sources.rigfile`), or from the inputs as they
are (:func:`pcdcodec.sources.rig.open_inputs`: a camera per namespace of a bag of several
cameras, placed by its ``/tf_static``). Their frames are written interleaved in timestamp order
(:func:`pcdcodec.sources.rig.merge_by_time`, one frame per camera read ahead), on the stamps the
inputs carry; :class:`ClockReport` says how far apart the cameras' clocks are.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..color import DEFAULT_COLOR_CODEC
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import InputError
from ..sources.base import Source

if TYPE_CHECKING:
    from ..sources.rig import CameraInput
    from .rig import CameraSpec

__all__ = ["CameraSummary", "ClockReport", "RigSummary", "encode_rig", "rig_specs", "write_rig"]

_NS = 1e9


@dataclass
class CameraSummary:
    """One camera of :func:`encode_rig`: its input, frames and bytes written, first and last
    stamps (ns; ``None`` without frames), rig pose and where that came from, and what its
    source reported (:meth:`pcdcodec.Source.describe`)."""

    name: str
    input: str
    frames: int = 0
    bytes_color: int = 0
    bytes_depth: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    rig_pose: list[list[float]] = field(default_factory=list)
    pose_from: str = ""
    source: dict[str, Any] = field(default_factory=dict)

    @property
    def bytes(self) -> int:
        """Bytes of encoded color and depth of this camera."""
        return self.bytes_color + self.bytes_depth

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "input": self.input,
            "frames": self.frames,
            "bytes": self.bytes,
            "bytes_color": self.bytes_color,
            "bytes_depth": self.bytes_depth,
            "first_ns": self.first_ns,
            "last_ns": self.last_ns,
            "rig_pose": self.rig_pose,
            "pose_from": self.pose_from,
            "source": self.source,
        }


@dataclass
class ClockReport:
    """How far apart the cameras' clocks are, from the stamps written.

    ``reference`` is the camera whose first stamp is earliest; ``offsets`` gives each camera's
    first stamp minus the reference's (ns). ``overlap`` is the stretch every camera covers,
    ``(start, end)`` in ns, or ``None`` when some camera ends before another starts (then the
    inputs' clocks are probably not one clock, and ``warnings`` says so).
    """

    spans: dict[str, tuple[int, int]]
    reference: str | None
    offsets: dict[str, int]
    overlap: tuple[int, int] | None
    warnings: list[str]

    @classmethod
    def of(cls, cameras: Sequence[CameraSummary]) -> ClockReport:
        spans = {
            c.name: (c.first_ns, c.last_ns)
            for c in cameras
            if c.first_ns is not None and c.last_ns is not None
        }
        warnings = [f"camera {c.name} gave no frames" for c in cameras if c.name not in spans]
        if not spans:
            return cls({}, None, {}, None, warnings)
        reference = min(spans, key=lambda n: spans[n][0])
        offsets = {n: s[0] - spans[reference][0] for n, s in spans.items()}
        start = max(s[0] for s in spans.values())
        end = min(s[1] for s in spans.values())
        overlap = (start, end) if end >= start else None
        if overlap is None and len(spans) > 1:
            late = max(spans, key=lambda n: spans[n][0])
            early = min(spans, key=lambda n: spans[n][1])
            warnings.append(
                f"the cameras' stamps do not overlap: {early} ends at "
                f"{spans[early][1] / _NS:.3f} s before {late} starts at "
                f"{spans[late][0] / _NS:.3f} s ({(start - end) / _NS:.3f} s apart); were the "
                "inputs recorded on one clock?"
            )
        return cls(spans, reference, offsets, overlap, warnings)

    def to_dict(self) -> dict[str, Any]:
        return {
            "spans": {n: list(s) for n, s in self.spans.items()},
            "reference": self.reference,
            "offsets": self.offsets,
            "overlap": None if self.overlap is None else list(self.overlap),
            "warnings": list(self.warnings),
        }


@dataclass
class RigSummary:
    """What :func:`encode_rig` did: the file, its size, each camera's summary, the rig frame,
    how the cameras' clocks compare, and warnings (cameras not placed, clocks apart)."""

    path: Path
    bytes: int
    seconds: float
    rig_frame: str
    cameras: dict[str, CameraSummary]
    clocks: ClockReport
    warnings: list[str] = field(default_factory=list)
    #: per input path, its topics, tracks or cameras that no camera records (name, type,
    #: messages), as :func:`pcdcodec.sources.rig.left_out_of` finds them
    left_out: dict[str, list[dict[str, Any]]] = field(default_factory=dict)

    @property
    def frames(self) -> int:
        """Frames written, all cameras."""
        return sum(c.frames for c in self.cameras.values())

    @property
    def bytes_color(self) -> int:
        return sum(c.bytes_color for c in self.cameras.values())

    @property
    def bytes_depth(self) -> int:
        return sum(c.bytes_depth for c in self.cameras.values())

    @property
    def fps(self) -> float:
        """Frames encoded per second of wall time, all cameras."""
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": str(self.path),
            "frames": self.frames,
            "bytes": self.bytes,
            "bytes_color": self.bytes_color,
            "bytes_depth": self.bytes_depth,
            "seconds": self.seconds,
            "fps": self.fps,
            "rig_frame": self.rig_frame,
            "cameras": {n: c.to_dict() for n, c in self.cameras.items()},
            "clocks": self.clocks.to_dict(),
            "warnings": list(self.warnings),
            "left_out": {k: list(v) for k, v in self.left_out.items()},
        }


def encode_rig(
    inputs: Sequence[str | os.PathLike[str] | Source] | str | os.PathLike[str] = (),
    out: str | os.PathLike[str] | None = None,
    *,
    rig: Any = None,
    color: Any = DEFAULT_COLOR_CODEC,
    depth: Any = DEFAULT_DEPTH_CODEC,
    fps: float | None = None,
    metadata: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
    **source_options: Any,
) -> RigSummary:
    """Record several cameras into one ``.pcdc`` file (format version 3).

    ``inputs`` are paths (bags, folders, camera files) or open sources; a bag of several
    cameras gives a camera per namespace. ``rig`` is a rig file (its path or a parsed
    :class:`~pcdcodec.sources.rigfile.RigFile`) naming the cameras, their sources and
    extrinsics; its cameras that name no source take the ``inputs`` in order. Without a rig
    file the cameras are named after their namespaces or files, and placed where their bags'
    ``/tf_static`` says (the rig frame is that tree's root); a camera nothing places gets the
    identity, and a warning.

    ``color``, ``depth`` and ``fps`` apply to every camera but where the rig file sets its own;
    without ``fps``, each camera keeps the rate its input records (a recording's), else 30.
    A recording of a rig gives its cameras with their names, rig poses and frame names, and
    its rig frame and metadata. ``source_options`` go to every source opened
    (``max_frames``, ``max_difference``, ...).
    Frames are written in timestamp order across cameras, on the stamps the inputs carry.
    Raises :class:`~pcdcodec.InputError` for a camera without intrinsics, an output that
    exists (without ``overwrite``), inputs that give no frames, and what the sources and the
    rig file raise; an interrupted run leaves nothing under ``out`` (an older file there
    intact).
    """
    from .._atomic import atomic_output  # not loaded by `import pcdcodec`
    from ..sources.rig import close_inputs, left_out_of, open_inputs
    from ..sources.rigfile import RigFile, open_rig, read_rig

    if out is None:
        raise InputError("encode_rig needs out=, the .pcdc file to write")
    if isinstance(inputs, (str, os.PathLike, Source)):
        inputs = [inputs]
    target = _check_target(Path(out), overwrite)
    if rig is not None:
        parsed = rig if isinstance(rig, RigFile) else read_rig(rig)
        paths = [p for p in inputs if not isinstance(p, Source)]
        if len(paths) != len(inputs):
            raise InputError("with a rig file, inputs are paths: the rig file opens them")
        cams = open_rig(parsed, paths, **source_options)
        rig_frame = parsed.frame
    else:
        if not inputs:
            raise InputError("encode_rig needs inputs, or a rig file naming them")
        cams, root = open_inputs(inputs, **source_options)
        rig_frame = root or "rig"
    try:
        specs, warnings = rig_specs(cams, rig_frame, color=color, depth=depth, fps=fps)
        meta: dict[str, Any] = {k: v for cam in cams for k, v in cam.rig_metadata.items()}
        meta.update({f"{cam.name}.{k}": v for cam in cams for k, v in cam.source.metadata.items()})
        meta.update(metadata or {})
        start = time.perf_counter()
        with atomic_output(target) as partial:
            summaries = write_rig(partial, cams, specs, rig_frame, metadata=meta, progress=progress)
            if not any(s.frames for s in summaries):
                raise InputError(
                    f"the inputs gave no frames ({', '.join(repr(s.input) for s in summaries)})"
                )
        seconds = time.perf_counter() - start
        for done, cam in zip(summaries, cams, strict=True):
            # What a camera leaves out of its input is the rig's to say (other cameras read
            # the rest of a bag): see RigSummary.left_out.
            done.source = {k: v for k, v in cam.source.describe().items() if k != "left_out"}
        clocks = ClockReport.of(summaries)
        left_out = {path: [s.to_dict() for s in items] for path, items in left_out_of(cams).items()}
        return RigSummary(
            target,
            target.stat().st_size,
            seconds,
            rig_frame,
            {s.name: s for s in summaries},
            clocks,
            warnings + clocks.warnings,
            left_out,
        )
    finally:
        close_inputs(cams)


def rig_specs(
    cams: Sequence[CameraInput],
    rig_frame: str,
    *,
    color: Any,
    depth: Any,
    fps: float | None,
) -> tuple[list[CameraSpec], list[str]]:
    """The :class:`~pcdcodec.recording.CameraSpec` of each camera: its source's camera and
    depth scale, the codecs and rate given (or the camera's own overrides; no color for a
    source without it; without ``fps``, the rate its source records, else 30), its rig pose
    (the identity where none is known, with a warning when the rig has several cameras) and
    its frame name (kept where the names differ). Raises :class:`~pcdcodec.InputError` for a
    camera without intrinsics."""
    from .rig import CameraSpec

    specs, warnings = [], []
    frame_ids = [c.frame_id for c in cams]
    unique = len(set(frame_ids)) == len(frame_ids) and rig_frame not in frame_ids
    for cam in cams:
        src = cam.source
        if src.intrinsics is None:
            raise InputError(
                f"camera {cam.name} ({str(src.path)!r}) has no intrinsics: give them in a "
                "rig file (intrinsics:), or give the input a camera (CameraInfo, camera.json)"
            )
        if cam.rig_pose is None:
            if len(cams) > 1:
                warnings.append(
                    f"camera {cam.name}: nothing places it on the rig (no /tf_static, no "
                    "rig file): recorded at the rig's origin"
                )
            cam.rig_pose, cam.pose_from = np.eye(4), "none (identity)"
        chosen = cam.overrides.get("color", color)
        specs.append(
            CameraSpec(
                cam.name,
                src.intrinsics,
                src.depth_scale,
                fps=float(cam.overrides.get("fps", _rate(fps, src))),
                color=chosen if src.has_color else None,
                depth=cam.overrides.get("depth", depth),
                color_intrinsics=src.color_intrinsics,
                depth_to_color=src.depth_to_color,
                rig_pose=cam.rig_pose,
                frame_id=cam.frame_id if unique and cam.frame_id else None,
            )
        )
    return specs, warnings


def _rate(fps: float | None, source: Source) -> float:
    """The rate given, else the one the source records, else 30."""
    if fps is not None:
        return fps
    return source.fps if source.fps is not None else 30.0


def write_rig(
    path: Path,
    cams: Sequence[CameraInput],
    specs: Sequence[CameraSpec],
    rig_frame: str,
    *,
    metadata: dict[str, Any] | None = None,
    frames: Sequence[Iterable[Any]] | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[CameraSummary]:
    """Write the cameras' frames into a new rig recording at ``path``, in timestamp order
    across cameras: each camera's ``frames`` (default: its whole source). Returns each camera's
    summary (frames, bytes, first and last stamps, pose)."""
    from ..sources.rig import merge_by_time
    from .rig import RigWriter

    summaries = [
        CameraSummary(
            c.name,
            str(c.source.path),
            rig_pose=np.asarray(c.rig_pose if c.rig_pose is not None else np.eye(4)).tolist(),
            pose_from=c.pose_from,
        )
        for c in cams
    ]
    with RigWriter(path, list(specs), metadata=metadata, rig_frame_id=rig_frame) as writer:
        writers = [writer.camera(c.name) for c in cams]
        keep_color = [s.color is not None for s in specs]
        for count, (k, frame) in enumerate(merge_by_time(cams, frames), 1):
            ts = int(frame.timestamp_ns)
            writers[k].write(
                frame.color if keep_color[k] else None, frame.depth, ts, pose=frame.pose
            )
            done = summaries[k]
            done.frames += 1
            done.first_ns = ts if done.first_ns is None else done.first_ns
            done.last_ns = ts
            if progress is not None:
                progress(count)
    for done, w in zip(summaries, writers, strict=True):
        done.bytes_color, done.bytes_depth = w.bytes_color, w.bytes_depth
    return summaries


def _check_target(target: Path, overwrite: bool) -> Path:
    if target.exists() and not overwrite:
        raise InputError(f"{str(target)!r} already exists; pass overwrite=True to replace it")
    if target.is_dir():
        raise InputError(f"{str(target)!r} is a folder, not a file")
    if not target.parent.is_dir():
        raise InputError(
            f"the folder of the output {str(target)!r} does not exist; create "
            f"{str(target.parent)!r} first"
        )
    return target
