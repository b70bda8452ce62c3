"""Joining recordings written one after another (time segments of one input) into one file.

Each part must come from the same camera and codecs, and each part's color stream must start
with a keyframe (a new encoder per part does that), so the joined stream decodes straight
through. The join copies MCAP messages, it never decodes: it is as fast as the disk.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from .._atomic import atomic_output
from ..errors import DecodeError, InputError
from . import _header as header
from . import _index as fmt

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


def _settings(index: fmt.FileIndex) -> dict[str, dict[str, str]]:
    """The metadata records that must agree between parts (each part has its own seal)."""
    return {name: data for name, data in index.metadata.items() if name != fmt.SEAL_NAME}


def _check_same(first: fmt.FileIndex, other: fmt.FileIndex, name: str, first_name: str) -> None:
    if _settings(other) != _settings(first):
        keys = sorted(
            k
            for k in set(_settings(first)) | set(_settings(other))
            if first.metadata.get(k) != other.metadata.get(k)
        )
        raise InputError(
            f"{name!r} cannot follow {first_name!r}: its recording metadata differs ({keys})"
        )
    for topic in _SAME:
        a, b = first.channel(topic), other.channel(topic)
        if (a is None) != (b is None):
            raise InputError(f"{name!r} cannot follow {first_name!r}: only one has {topic}")
        if a is not None and b is not None and (a.metadata, a.encoding) != (b.metadata, b.encoding):
            what = "extradata" if topic == fmt.TOPIC_COLOR else "channel metadata"
            diff = sorted(
                k
                for k in set(a.metadata) | set(b.metadata)
                if a.metadata.get(k) != b.metadata.get(k)
            )
            raise InputError(
                f"{name!r} cannot follow {first_name!r}: the {topic} {what} differs ({diff}); "
                "the parts were written with different codec settings"
            )


def join(
    parts: Sequence[str | os.PathLike[str]],
    dst: str | os.PathLike[str],
    *,
    overwrite: bool = False,
) -> int:
    """Write the frames of ``parts`` (closed recordings, in time order) into one recording.

    The result reads like a file from one writer: one metadata record, one set of channels,
    continuous message sequence numbers, the camera calibration once, keyframes where each
    part started. It is written beside ``dst`` and renamed at the end, so ``dst`` never holds
    a half-written file. Returns the number of frames written.

    Raises :class:`~pcdcodec.InputError` when the parts differ in camera, codecs or codec
    extradata, when their timestamps overlap, or when ``dst`` exists and ``overwrite`` is
    false; :class:`~pcdcodec.DecodeError` for a part that is damaged or not a recording.
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
    last_time: int | None = None
    for path, index in zip(paths, indexes, strict=True):
        _check_same(first, index, str(path), str(paths[0]))
        times = index.times.get(fmt.TOPIC_DEPTH, [])
        if times and last_time is not None and min(times) <= last_time:
            raise InputError(
                f"{str(path)!r} starts at {min(times)} ns, not after the previous part's last "
                f"frame ({last_time} ns): parts must be given in time order without overlap"
            )
        if times:
            last_time = max(times)

    frames = 0
    with atomic_output(dst_path) as tmp:  # noqa: SIM117 - the file closes before the rename
        with tmp.open("wb") as out:
            writer = header.start_mcap(out, header.library_of(paths[0]))
            for name, data in _settings(first).items():
                writer.add_metadata(name, data)
            ids = header.copy_channels(writer, first)
            topic_ids = {ch.topic: ids[cid] for cid, ch in first.channels.items()}
            # Sequence numbers continue across parts: the color packets (and the keyframe
            # markers, which share their packet's number), the depth frames and the frame
            # digests count apart.
            base = {fmt.TOPIC_COLOR: 0, fmt.TOPIC_DEPTH: 0, fmt.TOPIC_FRAME_DIGEST: 0}
            # Each part's color digests are checked as its packets are copied; the joined
            # file gets its own (a part's last packets join the next part's first frame's).
            integrity = fmt.integrity_version(first, repr(str(paths[0])))
            sealer = fmt.Sealer()
            for n, (path, index) in enumerate(zip(paths, indexes, strict=True)):
                channel_topic = {cid: ch.topic for cid, ch in index.channels.items()}
                offsets = sorted({o for topic in index.offsets.values() for o in topic})
                keyframes = set(index.times.get(fmt.TOPIC_KEYFRAMES, []))
                check = fmt.Sealer()
                with path.open("rb") as f:
                    size = fmt.file_size(f)
                    for offset in offsets:
                        for m in fmt.read_chunk_messages(f, offset, what=path.name, size=size):
                            topic = channel_topic.get(m.channel_id)
                            if topic is None or (topic == fmt.TOPIC_CALIBRATION and n > 0):
                                continue
                            counter = fmt.TOPIC_COLOR if topic == fmt.TOPIC_KEYFRAMES else topic
                            sequence = m.sequence + base.get(counter, 0)
                            payload = m.data
                            if topic == fmt.TOPIC_COLOR:
                                key = m.log_time in keyframes
                                check.packet(m.log_time, m.publish_time, key, m.data)
                                sealer.packet(m.log_time, m.publish_time, key, m.data)
                            elif topic == fmt.TOPIC_FRAME_DIGEST:
                                payload = _rejoin(m.data, check, sealer, path, offset)
                            writer.add_message(
                                topic_ids[topic], m.log_time, payload, m.publish_time, sequence
                            )
                            sealer.note(topic, m.log_time)
                seal = index.metadata.get(fmt.SEAL_NAME)
                tail = check.seal()
                if seal is not None and any(
                    seal.get(k) != tail[k] for k in ("tail_packets", "tail_digest")
                ):
                    raise DecodeError(
                        f"{str(path)!r}: its last color packets do not match their digest in "
                        "the seal"
                    )
                for topic in base:
                    base[topic] += len(index.times.get(topic, []))
                frames += len(index.times.get(fmt.TOPIC_DEPTH, []))
            if integrity:
                writer.add_metadata(fmt.SEAL_NAME, fmt.seal(fmt.SEAL_NAME, sealer.seal()))
            writer.finish()
            out.flush()
            os.fsync(out.fileno())
    return frames


def _rejoin(data: bytes, check: fmt.Sealer, sealer: fmt.Sealer, path: Path, offset: int) -> bytes:
    """A part's frame digest message as the joined file needs it: the part's color group
    checked, and replaced by the joined file's group (which may begin in the part before);
    the depth and pose digests are kept as written."""
    if len(data) != fmt.DIGEST_RECORD.size:
        raise DecodeError(f"{str(path)!r}: the frame digest at byte offset {offset} is damaged")
    count, color, depth, pose = fmt.DIGEST_RECORD.unpack(data)
    if check.group() != (count, color):
        raise DecodeError(
            f"{str(path)!r}: the color packets before byte offset {offset} do not match their "
            "digest there"
        )
    return fmt.DIGEST_RECORD.pack(*sealer.group(), depth, pose)
