"""Joining recordings written one after another (time segments of one input) into one file.

Each part must come from the same camera and codecs, and each part's color stream must start
with a keyframe (a new encoder per part does that), so the joined stream decodes straight
through. The join copies MCAP messages, it never decodes: it is as fast as the disk.

Parts of several cameras (format version 3) are joined camera by camera in one pass: every
part must have the same cameras with the same settings, and each camera's messages, sequence
numbers, frame digests and seal continue across the parts as a one-camera file's do.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .._atomic import atomic_output
from ..errors import DecodeError, InputError
from . import _header as header
from . import _index as fmt
from ._kept import stored_topics_of
from ._kept_copy import KeptCopy, union_of, without_kept

__all__ = ["join"]

#: channel metadata that must agree between parts (the color codec's extradata among them)
_SAME = (fmt.TOPIC_COLOR, fmt.TOPIC_DEPTH, fmt.TOPIC_KEYFRAMES, fmt.TOPIC_CALIBRATION)


def _load(path: Path) -> fmt.FileIndex:
    with path.open("rb") as f:
        header.check_magic(f, path)
        try:
            index = fmt.from_summary(f)
        except Exception as exc:
            raise DecodeError(f"{str(path)!r} has a damaged index ({exc})") from exc
    if index is None:
        raise DecodeError(
            f"{str(path)!r} was not closed by its writer (no index); `pcdcodec recover` it first"
        )
    if not header.is_recording(index):
        raise DecodeError(f"{str(path)!r} is not a pcdcodec recording")
    fmt.check_metadata(index, repr(str(path)))
    problems = fmt.seal_problems(index, repr(str(path)))
    if problems:
        raise DecodeError(f"{str(path)!r} does not hold what was sealed: {'; '.join(problems)}")
    return index


def _settings(index: fmt.FileIndex, *, compared: bool = False) -> dict[str, dict[str, str]]:
    """The metadata records of a part (each part has its own seals); ``compared``: as they
    must agree between parts, whose format versions may differ where only some keep topics."""
    out = {
        name: data
        for name, data in index.metadata.items()
        if name != fmt.SEAL_NAME and not name.startswith(fmt.SEAL_NAME + ".")
    }
    if compared and fmt.METADATA_NAME in out:
        drop = ("format_version", fmt.DIGEST_KEY)
        out[fmt.METADATA_NAME] = {k: v for k, v in out[fmt.METADATA_NAME].items() if k not in drop}
    return out


def _lanes(index: fmt.FileIndex, name: str) -> dict[str | None, fmt.FileIndex]:
    """Each camera of a file seen as a one-camera file (``None``: the one camera of a
    one-camera file, the file itself)."""
    cameras = fmt.rig_cameras(index, repr(name))
    if cameras is None:
        return {None: index}
    for camera in cameras:
        fmt.camera_rig_pose(index, camera, repr(name))  # a part that cannot be read: refused
    return {camera: fmt.camera_view(index, camera) for camera in cameras}


def _check_same(first: fmt.FileIndex, other: fmt.FileIndex, name: str, first_name: str) -> None:
    ours, theirs = fmt.rig_cameras(first, repr(first_name)), fmt.rig_cameras(other, repr(name))
    if ours != theirs:

        def holds(cameras: list[str] | None) -> str:
            return "one camera" if cameras is None else f"the cameras {cameras}"

        raise InputError(
            f"{name!r} cannot follow {first_name!r}: it holds {holds(theirs)}, "
            f"{first_name!r} {holds(ours)}; every part must hold the same cameras"
        )
    if ours is not None:
        for cam in ours:
            a = first.metadata.get(fmt.camera_record(cam), {})
            b = other.metadata.get(fmt.camera_record(cam), {})
            fields = sorted(
                k for k in set(a) | set(b) if k != fmt.DIGEST_KEY and a.get(k) != b.get(k)
            )
            if fields:
                raise InputError(
                    f"{name!r} cannot follow {first_name!r}: camera {cam!r} has other "
                    f"settings ({', '.join(fields)}); every part must record each camera alike"
                )
    ours_, theirs_ = _settings(first, compared=True), _settings(other, compared=True)
    if ours_ != theirs_:
        keys = sorted(k for k in set(ours_) | set(theirs_) if ours_.get(k) != theirs_.get(k))
        raise InputError(
            f"{name!r} cannot follow {first_name!r}: its recording metadata differs ({keys})"
        )


def _check_channels(
    first: fmt.FileIndex, other: fmt.FileIndex, name: str, first_name: str, camera: str | None
) -> None:
    of = "" if camera is None else f" camera {camera!r}:"
    for topic in _SAME:
        a, b = first.channel(topic), other.channel(topic)
        if (a is None) != (b is None):
            raise InputError(f"{name!r} cannot follow {first_name!r}:{of} only one has {topic}")
        if a is not None and b is not None and (a.metadata, a.encoding) != (b.metadata, b.encoding):
            what = "extradata" if topic == fmt.TOPIC_COLOR else "channel metadata"
            diff = sorted(
                k
                for k in set(a.metadata) | set(b.metadata)
                if a.metadata.get(k) != b.metadata.get(k)
            )
            raise InputError(
                f"{name!r} cannot follow {first_name!r}:{of} the {topic} {what} differs ({diff}); "
                "the parts were written with different codec settings"
            )


class _Lane:
    """One camera's messages being joined: its sequence numbers so far and its seal."""

    def __init__(self) -> None:
        self.base = {fmt.TOPIC_COLOR: 0, fmt.TOPIC_DEPTH: 0, fmt.TOPIC_FRAME_DIGEST: 0}
        self.sealer = fmt.Sealer()
        self.check = fmt.Sealer()  # the part being copied, against its own digests
        self.keyframes: set[int] = set()
        self.last_time: int | None = None
        #: the messages written once per camera (calibration) that the joined file has
        self.once: set[str] = set()
        #: the depth and pose messages of the part's frames whose digest message is to come
        self.pending: dict[int, dict[str, bytes]] = {}


def join(
    parts: Sequence[str | os.PathLike[str]],
    dst: str | os.PathLike[str],
    *,
    overwrite: bool = False,
) -> int:
    """Write the frames of ``parts`` (closed recordings, in time order) into one recording.

    The result reads like a file from one writer: one metadata record, one set of channels,
    continuous message sequence numbers, the camera calibration once, keyframes where each
    part started. Parts of several cameras (all with the same cameras and settings) give a
    recording of those cameras, each camera's frames in time order across the parts. It is
    written beside ``dst`` and renamed at the end, so ``dst`` never holds a half-written file.
    Returns the number of frames written (all cameras).

    Raises :class:`~pcdcodec.InputError` when the parts differ in cameras, codecs or codec
    extradata, when a camera's timestamps overlap between parts, or when ``dst`` exists and
    ``overwrite`` is false; :class:`~pcdcodec.DecodeError` for a part that is damaged or not
    a recording.
    """
    paths = [Path(p) for p in parts]
    if not paths:
        raise InputError("join needs at least one recording")
    dst_path = Path(dst)
    if dst_path.exists() and not overwrite:
        raise InputError(f"{str(dst_path)!r} already exists; pass overwrite=True to replace it")
    if any(dst_path.exists() and dst_path.resolve() == p.resolve() for p in paths):
        raise InputError("join writes a new file: the destination must differ from the parts")
    indexes = [_load(p) for p in paths]
    first = indexes[0]
    lanes = {camera: _Lane() for camera in _lanes(first, str(paths[0]))}
    # Per camera, the last part that recorded it: each part's channels must match it (a camera
    # of a rig may have no frames, and so no channels, in some parts).
    recorded: dict[str | None, tuple[fmt.FileIndex, str]] = {}
    for path, index in zip(paths, indexes, strict=True):
        _check_same(first, index, str(path), str(paths[0]))
        for camera, view in _lanes(index, str(path)).items():
            if camera is None or view.channel(fmt.TOPIC_DEPTH) is not None:
                if camera in recorded:
                    before, before_name = recorded[camera]
                    _check_channels(before, view, str(path), before_name, camera)
                recorded[camera] = (view, str(path))
            lane = lanes[camera]
            times = view.times.get(fmt.TOPIC_DEPTH, [])
            if times and lane.last_time is not None and min(times) <= lane.last_time:
                of = "" if camera is None else f"camera {camera!r} of "
                raise InputError(
                    f"{of}{str(path)!r} starts at {min(times)} ns, not after the previous "
                    f"part's last frame ({lane.last_time} ns): parts must be given in time "
                    "order without overlap"
                )
            if times:
                lane.last_time = max(times)

    # Parts keep the union of their kept topics; the settings are those of a part that keeps
    # topics (format version 4) where one does.
    kept = KeptCopy(union_of(indexes, [str(p) for p in paths]))
    main = next((index for index in indexes if stored_topics_of(index)), first)
    frames = 0
    with atomic_output(dst_path) as tmp:  # noqa: SIM117 - the file closes before the rename
        with tmp.open("wb") as out:
            writer = header.start_mcap(out, header.library_of(paths[0]))
            for name, data in _settings(main).items():
                writer.add_metadata(name, data)
            # Each channel as the first part that has it registered it: a camera of a rig may
            # start recording in a later part.
            topic_ids: dict[str, int] = {}
            schemas: dict[tuple[str, str, bytes], int] = {}
            for index in indexes:
                _register(writer, without_kept(index), topic_ids, schemas)
            kept.register(writer)
            integrity = fmt.integrity_version(first, repr(str(paths[0])))
            for path, index in zip(paths, indexes, strict=True):
                frames += _copy_part(writer, path, index, lanes, topic_ids, kept)
            kept_seal = kept.finish(writer)
            if integrity:
                for camera, lane in lanes.items():
                    seal_name = fmt.SEAL_NAME if camera is None else fmt.camera_seal(camera)
                    sealed = lane.sealer.seal() | (kept_seal if camera is None else {})
                    writer.add_metadata(seal_name, fmt.seal(seal_name, sealed))
            writer.finish()
            out.flush()
            os.fsync(out.fileno())
    return frames


#: What a camera writes once, at its first frame: the joined file keeps the first part's.
_ONCE = (fmt.TOPIC_CALIBRATION, fmt.TOPIC_COLOR_CALIBRATION, fmt.TOPIC_EXTRINSICS)


def _copy_part(
    writer: Any,
    path: Path,
    index: fmt.FileIndex,
    lanes: dict[str | None, _Lane],
    topic_ids: dict[str, int],
    kept: KeptCopy,
) -> int:
    """Copy the part at ``path`` into ``writer``; returns its frames. Its kept messages go
    into ``kept``'s chunks, checked against the part's seal.

    Sequence numbers continue across parts: the color packets (and the keyframe markers,
    which share their packet's number), the depth frames and the frame digests count apart.
    Each part's color digests are checked as its packets are copied; the joined file gets its
    own (a part's last packets join the next part's first frame's)."""
    views = _lanes(index, str(path))
    # channel id -> (camera, the topic a one-camera file has it on, the topic in the file)
    channel_topic = {
        cid: (camera, ch.topic, index.channels[cid].topic)
        for camera, view in views.items()
        for cid, ch in view.channels.items()
    }
    for camera, view in views.items():
        lanes[camera].check = fmt.Sealer()
        lanes[camera].keyframes = set(view.times.get(fmt.TOPIC_KEYFRAMES, []))
    offsets = sorted({o for topic in index.offsets.values() for o in topic})
    kept.source(index)
    with path.open("rb") as f:
        size = fmt.file_size(f)
        for offset in offsets:
            for m in fmt.read_chunk_messages(f, offset, what=repr(str(path)), size=size):
                if kept.take(writer, m):
                    continue
                found = channel_topic.get(m.channel_id)
                if found is None:
                    continue
                camera, topic, real = found
                lane = lanes[camera]
                if topic in _ONCE:
                    if topic in lane.once:
                        continue
                    lane.once.add(topic)
                counter = fmt.TOPIC_COLOR if topic == fmt.TOPIC_KEYFRAMES else topic
                sequence = m.sequence + lane.base.get(counter, 0)
                payload = m.data
                if topic == fmt.TOPIC_COLOR:
                    key = m.log_time in lane.keyframes
                    lane.check.packet(m.log_time, m.publish_time, key, m.data)
                    lane.sealer.packet(m.log_time, m.publish_time, key, m.data)
                elif topic in _DIGESTED:
                    lane.pending.setdefault(m.log_time, {})[topic] = bytes(m.data)
                elif topic == fmt.TOPIC_FRAME_DIGEST:
                    frame = lane.pending.pop(m.log_time, {})
                    payload = _rejoin(m.data, lane, frame, _where(path, camera, m.log_time, offset))
                writer.add_message(topic_ids[real], m.log_time, payload, m.publish_time, sequence)
                lane.sealer.note(topic, m.log_time, m.data)
    kept.check_sealed(index.metadata.get(fmt.SEAL_NAME), repr(str(path)))
    frames = 0
    for camera, view in views.items():
        lane = lanes[camera]
        if lane.pending and fmt.TOPIC_FRAME_DIGEST in view.times:
            t = min(lane.pending)
            raise DecodeError(f"{_where(path, camera, t, None)}: the frame has no digest message")
        lane.pending.clear()
        seal = view.metadata.get(fmt.SEAL_NAME)
        tail = lane.check.seal()
        ends = ("tail_packets", "tail_digest")
        if seal is not None and any(seal.get(k) != tail[k] for k in ends):
            of = "" if camera is None else f" camera {camera!r}:"
            raise DecodeError(
                f"{str(path)!r}:{of} its last color packets do not match their digest in the seal"
            )
        for topic in lane.base:
            lane.base[topic] += len(view.times.get(topic, []))
        frames += len(view.times.get(fmt.TOPIC_DEPTH, []))
    return frames


def _register(
    writer: Any,
    index: fmt.FileIndex,
    topic_ids: dict[str, int],
    schemas: dict[tuple[str, str, bytes], int],
) -> None:
    """Register the channels of ``index`` that ``writer`` lacks (and their schemas)."""
    for cid, ch in index.channels.items():
        if ch.topic in topic_ids:
            continue
        sid = 0
        schema = index.schemas.get(index.channel_schema.get(cid, 0))
        if schema is not None:
            if schema not in schemas:
                schemas[schema] = writer.register_schema(*schema)
            sid = schemas[schema]
        topic_ids[ch.topic] = writer.register_channel(ch.topic, ch.encoding, sid, ch.metadata)


#: The messages of a frame that its digest message vouches for (in the digest's order).
_DIGESTED = (fmt.TOPIC_DEPTH, fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX)


def _where(path: Path, camera: str | None, t: int, offset: int | None) -> str:
    of = "" if camera is None else f" camera {camera!r}"
    at = "" if offset is None else f" (its digest at byte offset {offset})"
    return f"{str(path)!r}:{of} frame at t={t} ns{at}"


def _rejoin(data: bytes, lane: _Lane, frame: dict[str, bytes], where: str) -> bytes:
    """A part's frame digest message as the joined file needs it: the part's color group,
    depth and pose messages checked against it, as reading the part would, and the color
    group replaced by the joined file's (which may begin in the part before); the depth and
    pose digests are kept as written. ``where`` names the part and the frame."""
    if len(data) != fmt.DIGEST_RECORD.size:
        raise DecodeError(f"{where}: the frame digest message is damaged")
    count, color, depth, pose = fmt.DIGEST_RECORD.unpack(data)
    if lane.check.group() != (count, color):
        raise DecodeError(
            f"{where}: the color packets before it do not match their digest; "
            "`pcdcodec verify` the part"
        )
    if fmt.TOPIC_DEPTH not in frame or fmt.data_digest(frame[fmt.TOPIC_DEPTH]) != depth:
        raise DecodeError(
            f"{where}: the depth message does not match the frame's digest (it was changed, "
            "or belongs to another frame); `pcdcodec verify` the part"
        )
    poses = [frame[t] for t in (fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX) if t in frame]
    if (fmt.data_digest(*poses) if poses else fmt.NO_POSE) != pose:
        raise DecodeError(
            f"{where}: the pose messages do not match the frame's digest (they were changed, "
            "added or removed); `pcdcodec verify` the part"
        )
    return fmt.DIGEST_RECORD.pack(*lane.sealer.group(), depth, pose)
