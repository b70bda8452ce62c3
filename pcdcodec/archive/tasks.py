"""The tasks an archive run submits, each run on a worker: probe an input, encode one segment,
join the segments, verify the output against its source.

They take and return only plain values (paths as strings, dicts), so that any worker can run
them and the client can keep their results in the manifest.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .._atomic import partial_path
from ..errors import InputError, VerificationError
from .checks import check_frames, check_kept, kept_in
from .checks import depth_bound as _depth_bound
from .checks import depth_mismatch as _depth_mismatch  # noqa: F401 - its name here before
from .checks import digest as _digest
from .discover import _hash, _stat
from .manifest import _disk_full
from .plan import segment_plan
from .rig_tasks import (
    RigIndex,
    count_frames,
    encode_rig_segment,
    is_rig_input,
    probe_rig,
    rig_colors,
    verify_rig,
)

#: What an input without a camera needs, in the library's words (the CLI says its flags).
NO_CAMERA_HINT = "pass camera= (for every input that lacks one) or input_options= (for this input)"


def _probe(
    src: str, options: dict[str, Any], segment_frames: int | None, keyframes: int
) -> dict[str, Any]:
    """Size, hash and frame count of one input, and its frame index where it needs one."""
    import operator

    from ..sources import open_source

    path = Path(src)
    size, mtime = _stat(path)
    digest = _hash(path)
    if is_rig_input(path, options):

        def cut(most: int) -> bool:
            return most < 0 or len(segment_plan(most, size or 0, segment_frames, keyframes)) > 1

        rig = probe_rig(src, options, cut)
        return {"size": size, "mtime_ns": mtime, "hash": digest, **rig}
    index = None
    with open_source(path, **options) as source:
        if source.intrinsics is None:
            raise InputError(
                f"{src!r} does not say its camera intrinsics; {NO_CAMERA_HINT}, or put a "
                "camera.json in the folder"
            )
        camera = {
            "camera": source.intrinsics.to_dict(),
            "camera_from": source.intrinsics_origin,
            "depth_scale": float(source.depth_scale),
            "depth_scale_from": source.depth_scale_origin,
            "notes": list(source.camera_notes),
        }
        frames = source.frame_count
        # Index only inputs that may need more than one segment: a bag's message count bounds
        # its frame count from above.
        most = frames if frames is not None else operator.length_hint(source, -1)
        if most < 0 or len(segment_plan(most, size or 0, segment_frames, keyframes)) > 1:
            index = source.frame_index()
            if index is not None:
                frames = len(index)
    return {
        "size": size,
        "mtime_ns": mtime,
        "hash": digest,
        "frames": frames,
        "index": index,
        "camera": camera,
    }


def _encode_segment(
    src: str,
    options: dict[str, Any],
    part: str,
    start: int,
    stop: int | None,
    writer_options: dict[str, Any],
    digests: bool,
    index: Any = None,
    window: tuple[int | None, int | None] = (None, None),
) -> dict[str, Any]:
    """Write frames ``start:stop`` of ``src`` into the recording ``part`` (atomically); with
    ``index`` (a :class:`~pcdcodec.sources.FrameIndex` slice), the frames it lists. The
    input's other topics are kept: their messages whose log time falls in ``window`` (ns,
    ``[low, high)``, ``None`` open), merged with the frames by time."""
    from ..recording import Recording, RecordingWriter
    from ..ros.kept import by_time
    from ..sources import open_source

    target = Path(part)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = partial_path(target, unique=True)
    try:
        if isinstance(index, RigIndex) or (index is None and is_rig_input(src, options)):
            count = encode_rig_segment(src, options, tmp, writer_options, index)
            if count == 0:
                raise InputError(f"{src!r} has no frames in {start}:{stop}")
            digested = rig_colors(tmp) if digests else []
            os.replace(tmp, target)
            return {"frames": count, "bytes": target.stat().st_size, "colors": digested}
        with open_source(src, **options) as source:
            frames = source.frames_at(index) if index is not None else source.frames(start, stop)
            kept = source.kept_topics()
            if kept:
                frames = by_time(iter(frames), kept_in(source, window))
            meta = dict(source.metadata)
            opts = dict(writer_options)
            if not source.has_color:
                opts["color"] = None  # a depth-only input gives a depth-only recording
            with RecordingWriter(
                tmp,
                intrinsics=source.intrinsics,
                depth_scale=source.depth_scale,
                metadata=meta,
                # Sensors whose color camera is apart from the depth camera (RealSense bags).
                color_intrinsics=source.color_intrinsics,
                depth_to_color=source.depth_to_color,
                kept_topics=kept,
                **opts,
            ) as writer:
                count = writer.write_frames(frames)
        if count == 0:
            raise InputError(f"{src!r} has no frames in {start}:{stop}")
        colors: list[str] = []
        if digests:
            # The codec's own decode of this segment, read alone: the joined file must give
            # back exactly these frames.
            with Recording(tmp) as rec:
                colors = [_digest(f.color) for f in rec]
        os.replace(tmp, target)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        full = _disk_full(exc, target)
        if full is not None:
            raise full from None
        raise
    return {"frames": count, "bytes": target.stat().st_size, "colors": colors}


def _existing_segment(part: str, digests: bool) -> dict[str, Any]:
    """What :func:`_encode_segment` returns, for a segment an earlier run wrote."""
    from ..recording import Recording, RigRecording
    from ..recording import open as open_recording

    with open_recording(part) as any_rec:
        rig = isinstance(any_rec, RigRecording)
    if rig:
        colors = rig_colors(Path(part)) if digests else []
        size = Path(part).stat().st_size
        return {"frames": count_frames(Path(part)), "bytes": size, "colors": colors}
    with Recording(part) as rec:
        count = len(rec)
        colors = [_digest(f.color) for f in rec] if digests else []
    return {"frames": count, "bytes": Path(part).stat().st_size, "colors": colors}


def _join_parts(parts: list[str], output: str) -> dict[str, Any]:
    """Join the segments into ``output`` (atomically) and return its size."""
    from ..recording.join import join

    target = Path(output)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        if len(parts) == 1:
            os.replace(parts[0], target)  # already complete; a rename is atomic
            frames = -1
        else:
            frames = join(parts, target, overwrite=True)
    except BaseException as exc:
        full = _disk_full(exc, target)
        if full is not None:
            raise full from None
        raise
    return {"bytes": target.stat().st_size, "frames": frames}


def _verify(
    src: str, options: dict[str, Any], output: str, colors: list[str] | None
) -> dict[str, Any]:
    """Decode ``output`` and compare it with ``src`` read again; raise on any difference."""

    from ..recording import Recording
    from ..sources import open_source

    if is_rig_input(src, options):
        return verify_rig(src, options, output, colors)
    name = Path(output).name
    with open_source(src, **options) as source, Recording(output) as rec:
        if not rec.indexed:
            raise VerificationError(f"{name}: the output has no index")
        if colors is not None and len(colors) != len(rec):
            raise VerificationError(
                f"{name}: {len(rec)} frames, but its segments decoded {len(colors)}"
            )
        bound = _depth_bound(rec.codecs.get("depth") or {})
        n = check_frames(name, iter(rec), source, bound, colors)
        kept = check_kept(name, rec.kept_messages(), source.kept_messages())
    return {"frames": n, **({"kept": kept} if kept else {})}
