"""Checking a whole recording: what :meth:`pcdcodec.Recording.verify` finds besides decoding.

A file is read from start to end without its summary, and what that finds (channels, messages,
their times, the data section's CRC, the metadata, the seal, the calibration) is compared with
the index the frames are read through (``docs/format.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

from ..errors import PcdcodecError
from ..geometry.camera import CameraIntrinsics
from . import _header as header
from . import _index as fmt
from ._kept import check_kept, kept_offsets

__all__ = ["VerifyReport", "index_problems", "structure_problems"]


@dataclass
class VerifyReport:
    """What :meth:`Recording.verify` found: per-frame problems, empty when all is well."""

    frames: int
    errors: list[str]
    indexed: bool
    truncated_at: int | None
    #: Kept messages read per topic (each chunk's CRC checked; ``docs/format.md``).
    kept: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.errors


def index_problems(index: fmt.FileIndex) -> list[str]:
    """What finding the messages of a file met: its end cut short, an unusable summary."""
    errors: list[str] = []
    if index.truncated_at is not None:
        errors.append(f"the file is cut short: records end at byte offset {index.truncated_at}")
    if index.summary_problem:
        errors.append(
            f"the summary (index) is unusable: {index.summary_problem}; the frames were "
            "found by reading the whole file"
        )
    return errors


def structure_problems(
    f: IO[bytes],
    index: fmt.FileIndex,
    *,
    integrity: int,
    has_color: bool,
    intrinsics: CameraIntrinsics,
    camera: str | None = None,
    elsewhere: frozenset[int] = frozenset(),
    color_missing: frozenset[int] = frozenset(),
) -> list[str]:
    """Problems found by reading every record of ``f``, compared with the ``index`` the frames
    use (of a file written with ``integrity`` records, with color or not, of a camera with
    ``intrinsics``; ``camera``: of that camera of a rig, whose ``index`` is its
    :func:`~pcdcodec.recording._index.camera_view`, and ``elsewhere`` the chunks of the other
    cameras, whose damage is theirs; ``color_missing``: the times of frames ``recover`` kept
    without color). The caller holds whatever lock guards ``f``."""
    try:
        scanned = fmt.scan(f, skip_damaged_chunks=True)
        if camera is not None:
            fmt.check_metadata(scanned, "reading the whole file")
            scanned = fmt.camera_view(scanned, camera)
    except PcdcodecError as exc:
        return [f"reading the whole file failed: {exc}"]
    errors: list[str] = []
    # Damaged chunks of frames are reported when those frames are decoded, and those of kept
    # topics when they are read (with the topics they hold).
    used = {o for topic in (fmt.TOPIC_DEPTH, fmt.TOPIC_COLOR) for o in index.offsets.get(topic, [])}
    used |= set(kept_offsets(index))
    skipped = {offset for offset, _ in scanned.damaged_chunks}
    errors.extend(
        text
        for offset, text in scanned.damaged_chunks
        if offset not in used and offset not in elsewhere
    )
    if scanned.damaged_at is not None:
        errors.append(f"damaged record at byte offset {scanned.damaged_at}: {scanned.damage}")
    for topic, count in sorted(scanned.duplicates.items()):
        real = topic if camera is None else fmt.camera_topic(topic, camera)
        errors.append(f"{count} message(s) on {real!r} are stored twice")
    crc = scanned.data_crc
    if crc is not None and crc[0] not in (0, crc[1]) and not scanned.damaged_chunks:
        stored, computed = crc
        errors.append(
            f"the data section fails its CRC ({stored:#010x} stored, {computed:#010x} "
            "computed): bytes outside the chunks were changed"
        )
    if index.indexed and scanned.data_crc is None and scanned.damaged_at is None:
        errors.append("the data section has no end record, although the file has a summary")
    if index.indexed:
        if scanned.metadata != index.metadata:
            errors.append("the metadata records differ from those the summary points to")
        for topic in sorted(set(index.times) | set(scanned.times)):
            listed = [
                (t, o)
                for t, o in zip(
                    index.times.get(topic, []), index.offsets.get(topic, []), strict=True
                )
                if o not in skipped
            ]
            if listed != list(
                zip(scanned.times.get(topic, []), scanned.offsets.get(topic, []), strict=True)
            ):
                errors.append(
                    f"channel {topic!r}: the index lists {len(index.times.get(topic, []))} "
                    f"messages, the file holds {len(scanned.times.get(topic, []))} (or at "
                    "other times or offsets)"
                )
        described = {
            (c.topic, c.encoding, tuple(sorted(c.metadata.items())))
            for c in index.channels.values()
        }
        found = {
            (c.topic, c.encoding, tuple(sorted(c.metadata.items())))
            for c in scanned.channels.values()
        }
        if described != found:
            errors.append("the channels in the summary differ from those in the chunks")
    depth = np.asarray(sorted(scanned.times.get(fmt.TOPIC_DEPTH, [])), dtype=np.int64)
    if np.any(np.diff(depth) <= 0):
        errors.append("depth messages share timestamps")
    if integrity and not scanned.damaged_chunks:  # (those are reported already)
        try:
            problems = fmt.seal_problems(scanned, "reading the whole file")
        except PcdcodecError as exc:
            problems = [str(exc)]
        errors.extend(f"the file does not hold what was sealed: {p}" for p in problems)
    if has_color:
        pts = set(scanned.times.get(fmt.TOPIC_COLOR, []))
        orphans = [int(t) for t in depth.tolist() if t not in pts and t not in color_missing]
        # At the end of an unfinished file they were in flight; a closed file has none.
        if orphans and (index.indexed or orphans != depth.tolist()[-len(orphans) :]):
            errors.append(
                f"{len(orphans)} depth message(s) have no color packet, the first at "
                f"t={orphans[0]} ns"
            )
    errors.extend(header.calibration_problems(f, scanned, intrinsics))
    return errors


def verify_recording(rec: Any) -> VerifyReport:
    """:meth:`pcdcodec.Recording.verify` of ``rec``."""
    errors: list[str] = []
    index = rec.index
    errors.extend(index_problems(index))
    with rec._lock:
        errors.extend(
            structure_problems(
                rec._file,
                index,
                integrity=rec.integrity,
                has_color=rec.color_codec is not None,
                intrinsics=rec.intrinsics,
                camera=rec.camera,
                elsewhere=rec.other_chunks,
                color_missing=rec._color_missing,
            )
        )
    if rec.integrity and rec.color_codec is not None:
        # Every group, also those no frame's color comes from (the end of the stream).
        groups = len(rec._digest_offsets) + (rec._seal is not None)
        with rec._lock:
            for g in range(groups):
                try:
                    problem = rec._group_problem(g)
                except PcdcodecError as exc:
                    problem = str(exc)
                if problem:
                    errors.append(problem)
    with rec._lock:
        problems, kept = check_kept(rec._file, index, repr(str(rec.path)))
    errors.extend(problems)
    for i in range(len(rec)):
        try:
            rec.frame(i)
        except PcdcodecError as exc:
            if str(exc) not in errors:  # one of the whole file (its stamps) is said once
                errors.append(str(exc))
            with rec._lock:
                rec._stream.reset()
    return VerifyReport(len(rec), errors, index.indexed, index.truncated_at, kept)
