"""Rewriting a damaged or unfinished ``.pcdc`` file into a clean, indexed one.

A file of several cameras (format version 3) is recovered camera by camera: each camera keeps
the frames of its own that check out (its frame digests, as a one-camera file's), so a camera
whose last frames were lost does not cost the others theirs, and each gets a seal of its own.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

from ..errors import DecodeError, InputError, PcdcodecError
from . import _header as header
from . import _index as fmt

__all__ = ["recover"]


def recover(
    src: str | os.PathLike[str], dst: str | os.PathLike[str], *, overwrite: bool = False
) -> int:
    """Copy every complete message of ``src`` into a new, indexed recording ``dst``.

    Use it on a file whose writer was killed (no summary) or whose tail is cut or damaged:
    everything up to the first damaged record is kept. Returns the number of frames of the
    new file (of all its cameras, for a file of several cameras: each keeps the frames of its
    own that check out). ``src`` itself is never changed. Raises :class:`~pcdcodec.DecodeError` when
    ``src`` is not a pcdcodec recording and :class:`~pcdcodec.InputError` when ``dst`` exists
    and ``overwrite`` is false, or is the same file as ``src``.
    """
    from .._atomic import atomic_output, partial_path  # not loaded by `import pcdcodec`

    src_path, dst_path = Path(src), Path(dst)
    if not src_path.is_file():
        raise InputError(f"recording {str(src_path)!r} does not exist")
    if dst_path.exists() and dst_path.resolve() == src_path.resolve():
        raise InputError("recover writes a new file: the destination must differ from the source")
    if dst_path.exists() and not overwrite:
        raise InputError(f"{str(dst_path)!r} already exists; pass overwrite=True to replace it")
    tmp = partial_path(dst_path)
    try:
        with atomic_output(dst_path) as tmp:
            with src_path.open("rb") as f:
                _copy(f, tmp, src_path)
            count = _frames(tmp)
    except PcdcodecError as exc:
        # Name the files the caller gave, never the temporary one.
        text = (
            str(exc).replace(repr(str(tmp)), repr(str(dst_path))).replace(str(tmp), str(dst_path))
        )
        if str(src_path) not in text:
            text = f"{str(src_path)!r}: {text}"
        raise type(exc)(text) from exc
    except OSError as exc:
        raise InputError(
            f"recovering {str(src_path)!r} into {str(dst_path)!r} failed: {exc.strerror or exc}"
        ) from exc
    return count


def _copy(f: IO[bytes], tmp: Path, src_path: Path) -> None:
    """Write every complete message of the open source ``f`` into ``tmp``, with a summary."""
    header.check_magic(f, src_path)
    try:
        index = fmt.scan(f)
    except DecodeError:
        raise
    except Exception as exc:
        raise DecodeError(f"could not be read ({type(exc).__name__}: {exc})") from exc
    if not header.is_recording(index):
        raise DecodeError(f"{str(src_path)!r} is not a pcdcodec recording")
    if index.loose_messages:
        raise DecodeError(
            f"{str(src_path)!r} holds {index.loose_messages} message(s) outside chunks (an "
            "unchunked MCAP file), which carry no CRC of their own: nothing to recover from"
        )
    fmt.check_metadata(index, repr(str(src_path)))
    integrity = fmt.integrity_version(index, repr(str(src_path)))
    cameras = fmt.rig_cameras(index, repr(str(src_path)))
    if cameras is not None:
        _copy_rig(f, tmp, index, cameras, integrity)
        return
    offsets = sorted({o for topic in index.offsets.values() for o in topic})
    in_flight: set[int] = set()
    if integrity:
        offsets = offsets[: _complete(f, index, offsets)]
        in_flight = _in_flight(index, set(offsets))
    with tmp.open("wb") as out:
        writer = header.start_mcap(out, "pcdcodec recover")
        for name, data in index.metadata.items():
            writer.add_metadata(name, data)
        channel_ids = header.copy_channels(writer, index)
        seen: set[tuple[int, int]] = set()
        sealer = fmt.Sealer()
        keyframes = set(index.times.get(fmt.TOPIC_KEYFRAMES, []))
        for offset in offsets:
            for m in fmt.read_chunk_messages(f, offset, what="recover", size=index.size):
                key = (m.channel_id, m.log_time)
                if m.channel_id in channel_ids and key not in seen:
                    seen.add(key)
                    topic = index.channels[m.channel_id].topic
                    if m.log_time in in_flight and topic in _FRAME_TOPICS:
                        continue
                    writer.add_message(
                        channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence
                    )
                    sealer.note(topic, m.log_time, m.data)
                    if topic == fmt.TOPIC_COLOR:
                        sealer.packet(m.log_time, m.publish_time, m.log_time in keyframes, m.data)
                    elif topic == fmt.TOPIC_FRAME_DIGEST:
                        sealer.group()  # copied as written: checked by _complete
        if integrity:
            writer.add_metadata(fmt.SEAL_NAME, fmt.seal(fmt.SEAL_NAME, sealer.seal()))
        writer.finish()


def _frames(path: Path) -> int:
    """The frames of the recording at ``path`` (all cameras), read as a reader does."""
    from .reader import Recording, SeveralCamerasError

    try:
        with Recording(path) as rec:
            return len(rec)
    except SeveralCamerasError as several:
        from .rig_reader import RigRecording

        with RigRecording(path, index=several.index) as rig:
            return sum(len(rig.frames(name)) for name in rig.camera_names)


def _copy_rig(
    f: IO[bytes], tmp: Path, index: fmt.FileIndex, cameras: list[str], integrity: int
) -> None:
    """:func:`_copy` of a file of several cameras: each camera's complete frames, and a seal
    per camera."""
    kept: dict[str, set[int]] = {}  # per camera, the chunks it keeps
    in_flight: dict[str, set[int]] = {}  # per camera, frames an encoder still held back
    keyframes: dict[str, set[int]] = {}
    lane_of: dict[int, tuple[str, str]] = {}  # channel id -> (camera, one-camera topic)
    for name in cameras:
        view = fmt.camera_view(index, name)
        offsets = sorted({o for topic in view.offsets.values() for o in topic})
        if integrity:
            offsets = offsets[: _complete(f, view, offsets)]
        kept[name] = set(offsets)
        in_flight[name] = _in_flight(view, kept[name]) if integrity else set()
        keyframes[name] = set(view.times.get(fmt.TOPIC_KEYFRAMES, []))
        lane_of.update({cid: (name, ch.topic) for cid, ch in view.channels.items()})
    seals = {fmt.SEAL_NAME, *(fmt.camera_seal(name) for name in cameras)}
    with tmp.open("wb") as out:
        writer = header.start_mcap(out, "pcdcodec recover")
        for record, data in index.metadata.items():
            if record not in seals:  # each camera gets a new seal, of what was kept
                writer.add_metadata(record, data)
        # A channel is registered with its first message: a camera that keeps no frame (or
        # channel no message) leaves no channel without messages behind.
        schema_ids = {
            sid: writer.register_schema(schema, encoding, data)
            for sid, (schema, encoding, data) in index.schemas.items()
        }
        channel_ids: dict[int, int] = {}

        def channel(cid: int) -> int:
            if cid not in channel_ids:
                ch = index.channels[cid]
                schema = schema_ids.get(index.channel_schema.get(cid, 0), 0)
                channel_ids[cid] = writer.register_channel(
                    ch.topic, ch.encoding, schema, ch.metadata
                )
            return channel_ids[cid]

        sealers = {name: fmt.Sealer() for name in cameras}
        seen: set[tuple[int, int]] = set()
        for offset in sorted(set().union(*kept.values())):
            for m in fmt.read_chunk_messages(f, offset, what="recover", size=index.size):
                key = (m.channel_id, m.log_time)
                lane = lane_of.get(m.channel_id)
                if lane is None or key in seen:
                    continue
                name, topic = lane
                if offset not in kept[name]:
                    continue
                if m.log_time in in_flight[name] and topic in _FRAME_TOPICS:
                    continue
                seen.add(key)
                writer.add_message(
                    channel(m.channel_id), m.log_time, m.data, m.publish_time, m.sequence
                )
                sealer = sealers[name]
                sealer.note(topic, m.log_time, m.data)
                if topic == fmt.TOPIC_COLOR:
                    sealer.packet(m.log_time, m.publish_time, m.log_time in keyframes[name], m.data)
                elif topic == fmt.TOPIC_FRAME_DIGEST:
                    sealer.group()  # copied as written: checked by _complete
        if integrity:
            for name, sealer in sealers.items():
                record = fmt.camera_seal(name)
                writer.add_metadata(record, fmt.seal(record, sealer.seal()))
        writer.finish()


#: A frame's own messages, left out when its color packet was never written.
_FRAME_TOPICS = (fmt.TOPIC_DEPTH, fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX, fmt.TOPIC_STAMPS)


def _in_flight(index: fmt.FileIndex, kept: set[int]) -> set[int]:
    """The times of the frames at the end of the chunks ``kept`` whose color packet is not
    among them: frames an encoder still held back (a lookahead) when the writer stopped."""
    if index.channel(fmt.TOPIC_COLOR) is None:
        return set()
    pts = {
        t
        for t, o in zip(
            index.times.get(fmt.TOPIC_COLOR, []),
            index.offsets.get(fmt.TOPIC_COLOR, []),
            strict=True,
        )
        if o in kept
    }
    depth = sorted(
        (o, t)
        for t, o in zip(
            index.times.get(fmt.TOPIC_DEPTH, []),
            index.offsets.get(fmt.TOPIC_DEPTH, []),
            strict=True,
        )
        if o in kept
    )
    times = [t for _, t in depth]
    good = [i for i, t in enumerate(times) if t in pts]
    return set(times[good[-1] + 1 :] if good else times)


def _complete(f: IO[bytes], index: fmt.FileIndex, offsets: list[int]) -> int:
    """How many of the chunks at ``offsets`` (in file order) hold complete frames.

    In a file with frame digests, a frame is complete once its digest message is written and
    matches the color packets before it and the frame's depth; the chunks up to the last such
    message are kept (the packets after it too when the file's seal vouches for them). A frame
    that does not match its digest ends what is kept, like a damaged record.
    """
    depth: dict[int, bytes] = {}
    keyframes = set(index.times.get(fmt.TOPIC_KEYFRAMES, []))
    sealer = fmt.Sealer()
    seen: set[tuple[int, int]] = set()
    kept = 0
    for k, offset in enumerate(offsets):
        for m in fmt.read_chunk_messages(f, offset, what="recover", size=index.size):
            info = index.channels.get(m.channel_id)
            if info is None or (m.channel_id, m.log_time) in seen:
                continue
            seen.add((m.channel_id, m.log_time))
            if info.topic == fmt.TOPIC_COLOR:
                sealer.packet(m.log_time, m.publish_time, m.log_time in keyframes, m.data)
            elif info.topic == fmt.TOPIC_DEPTH:
                depth[m.log_time] = fmt.data_digest(m.data)
            elif info.topic == fmt.TOPIC_FRAME_DIGEST:
                data = bytes(m.data)
                if len(data) != fmt.DIGEST_RECORD.size:
                    return kept
                count, color, depth_digest, _ = fmt.DIGEST_RECORD.unpack(data)
                if sealer.group() != (count, color) or depth.pop(m.log_time, None) != depth_digest:
                    return kept
                kept = k + 1
    seal = index.metadata.get(fmt.SEAL_NAME)
    tail = sealer.seal()
    if seal is not None and all(
        seal.get(key) == tail[key] for key in ("tail_packets", "tail_digest")
    ):
        return len(offsets)
    return kept
