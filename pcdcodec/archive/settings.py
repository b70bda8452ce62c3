"""One archive run's settings (:class:`RunSettings`), and the checks that turn the arguments of
:func:`~pcdcodec.archive.archive` into them: the default camera, each input's own options and
what the manifest records of them."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError


@dataclass(frozen=True)
class RunSettings:
    """What one run was asked to do, checked: the same for every input and task of the run."""

    #: the output folder
    out: Path
    #: where the tasks run: a scheduler's address, or a local cluster of ``workers`` (``None``:
    #: one per CPU core) processes, or threads of this process with ``processes=False``
    scheduler: str | None
    workers: int | None
    processes: bool
    #: per input (keyed by its output name, relative to ``out``), the options its reader gets
    options: dict[str, dict[str, Any]]
    #: per input, the settings the manifest records: a change of them redoes the input
    recorded: dict[str, dict[str, Any]]
    #: the recording writer's ``color`` and ``depth`` codec configs and ``fps``
    writer_options: dict[str, Any]
    #: the most frames a segment holds (``None``: by size, see
    #: :func:`~pcdcodec.archive.segment_plan`), and the color codec's keyframe interval
    segment_frames: int | None
    keyframes: int
    #: decode every output and compare it with its source; then delete the source
    verify: bool
    delete_source: bool
    #: given (bytes done, bytes total) as the run goes, if given
    progress: Callable[[int, int], None] | None
    #: whether the progress line is shown on stderr
    show: bool
    #: where messages go (the dashboard link), and warnings (an input's camera notes)
    say: Callable[[str], None]
    warn: Callable[[str], None]


def _check_counts(scheduler: str | None, workers: int | None, segment_frames: int | None) -> None:
    """Refuse a scheduler together with a number of workers, and counts that are not positive."""
    if scheduler is not None and workers is not None:
        raise InputError("give either a scheduler address or a number of workers, not both")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise InputError(f"workers must be a positive int, got {workers!r}")
    if segment_frames is not None and (
        isinstance(segment_frames, bool)
        or not isinstance(segment_frames, int)
        or segment_frames < 1
    ):
        raise InputError(f"segment_frames must be a positive int, got {segment_frames!r}")


def _writer_options(color: Any, depth: Any, fps: float) -> tuple[dict[str, Any], int]:
    """The writer's codec configs and rate (``color``, ``depth``, ``fps``), and the color
    codec's keyframe interval, on which segments are cut (one for intra-only codecs)."""
    from ..codec import ColorCodec
    from ..registry import as_codec

    color_codec = as_codec(color, "color") if color is not None else None
    color_config = color_codec.get_config() if color_codec is not None else None
    keyframes = (
        color_codec.keyframe_interval(float(fps)) if isinstance(color_codec, ColorCodec) else 1
    )
    depth_config = as_codec(depth, "depth").get_config()
    return {"color": color_config, "depth": depth_config, "fps": float(fps)}, keyframes


def _camera_defaults(camera: Any, common: dict[str, Any]) -> Any:
    """The :class:`~pcdcodec.sources.CameraDefaults` for inputs that lack a camera, from
    ``camera`` and the ``intrinsics``/``depth_scale`` taken out of ``common``; or None."""
    from ..geometry.camera import CameraIntrinsics, camera_preset
    from ..sources.base import CameraDefaults

    intrinsics = common.pop("intrinsics", None)
    scale = common.pop("depth_scale", None)
    origin = "source_options"
    if isinstance(camera, CameraDefaults):
        if intrinsics is not None or scale is not None:
            raise InputError(
                "give the default camera once: as camera= or in source_options, not both"
            )
        return camera
    if isinstance(camera, str):
        preset = camera_preset(camera)
        origin = f"camera preset {camera}"
        if intrinsics is not None:
            raise InputError("give the default camera once: as camera= or in source_options")
        intrinsics = preset.intrinsics
        scale = scale if scale is not None else preset.depth_scale
    elif camera is not None:
        if intrinsics is not None:
            raise InputError("give the default camera once: as camera= or in source_options")
        intrinsics, origin = camera, "camera="
    if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
        raise InputError(
            "the default camera must be a preset name, a pcdcodec.CameraIntrinsics or a "
            f"CameraDefaults, got {type(intrinsics).__name__}"
        )
    if scale is not None:
        try:
            value = None if isinstance(scale, bool) else float(scale)
        except (TypeError, ValueError):
            value = None
        if value is None or not (math.isfinite(value) and value > 0):
            raise InputError(
                f"depth_scale must be a positive finite number of units per metre, got {scale!r}"
            )
    if intrinsics is None and scale is None:
        return None
    return CameraDefaults(
        intrinsics,
        None if scale is None else float(scale),
        origin,
        how_to_override="input_options= for this input",
    )


def _input_options(
    inputs: list[tuple[Path, str]],
    given: Mapping[Any, dict[str, Any]] | None,
) -> dict[str, dict[str, Any]]:
    """``input_options`` keyed by each input's output name; a key naming no input is refused."""
    if not given:
        return {}
    by_path = {p.resolve(): rel for p, rel in inputs}
    out: dict[str, dict[str, Any]] = {}
    for key, opts in given.items():
        rel = by_path.get(Path(key).resolve())
        if rel is None:
            raise InputError(
                f"input_options names {str(key)!r}, which is not one of the inputs: "
                + ", ".join(repr(str(p)) for p, _ in inputs[:5])
                + (" ..." if len(inputs) > 5 else "")
            )
        if not isinstance(opts, dict):
            raise InputError(
                f"input_options for {str(key)!r} must be a dict of options, got {opts!r}"
            )
        out[rel] = dict(opts)
    return out


def _jsonable(options: dict[str, Any]) -> dict[str, Any]:
    """Per-input options as the manifest keeps them, to notice when they change."""
    out: dict[str, Any] = {}
    for k, v in sorted(options.items()):
        to_dict = getattr(v, "to_dict", None)
        out[k] = (
            to_dict() if callable(to_dict) else v if isinstance(v, (int, float, bool)) else str(v)
        )
    return out
