"""How an input is cut into segments, each one task: :func:`segment_plan`."""

from __future__ import annotations

import math

__all__ = ["SEGMENT_BYTES", "SEGMENT_MIN_FRAMES", "segment_plan"]

#: default segment size: about this many bytes of source per segment ...
SEGMENT_BYTES = 1_000_000_000
#: ... and at least this many frames (a segment's fixed costs: a task, opening the source)
SEGMENT_MIN_FRAMES = 300


def segment_plan(
    frames: int | None, size: int, segment_frames: int | None = None, keyframes: int = 1
) -> list[tuple[int, int | None]]:
    """The segments ``(start, stop)`` an input of ``frames`` frames and ``size`` bytes is cut
    into; ``[(0, None)]`` (one task) when it is not cut.

    A segment holds at most ``segment_frames`` frames; by default (``None``) as many as make
    about :data:`SEGMENT_BYTES` of source, and at least :data:`SEGMENT_MIN_FRAMES`. Segments
    are then made about equal, and where a segment is at least ``keyframes`` frames (the color
    codec's keyframe interval) their lengths are multiples of it: each segment starts with a
    keyframe (a new encoder) and holds whole keyframe intervals, so the joined stream has
    keyframes about as often as one writer's and cutting costs almost no compression.
    """
    if frames is None or frames < 2:
        return [(0, None)]
    if segment_frames is None:
        per_frame = max(size, 1) / frames
        segment_frames = max(SEGMENT_MIN_FRAMES, math.ceil(SEGMENT_BYTES / per_frame))
        align = max(keyframes, 1)
        segment_frames = -(-segment_frames // align) * align
    else:
        align = keyframes if keyframes > 1 and segment_frames >= keyframes else 1
        segment_frames -= segment_frames % align
    if frames <= segment_frames:
        return [(0, None)]
    k = math.ceil(frames / segment_frames)
    length = align * math.ceil(frames / (k * align))
    bounds = [min(i * length, frames) for i in range(k)] + [frames]
    return [(bounds[i], bounds[i + 1]) for i in range(k) if bounds[i] < bounds[i + 1]]
