"""Rewriting a damaged or unfinished ``.pcdc`` file into a clean, indexed one."""

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
    new file. ``src`` itself is never changed. Raises :class:`~pcdcodec.DecodeError` when
    ``src`` is not a pcdcodec recording and :class:`~pcdcodec.InputError` when ``dst`` exists
    and ``overwrite`` is false, or is the same file as ``src``.
    """
    from .._atomic import atomic_output, partial_path  # not loaded by `import pcdcodec`
    from .reader import Recording

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
            with Recording(tmp) as rec:
                count = len(rec)
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
                    sealer.note(topic, m.log_time)
                    if topic == fmt.TOPIC_COLOR:
                        sealer.packet(m.log_time, m.publish_time, m.log_time in keyframes, m.data)
                    elif topic == fmt.TOPIC_FRAME_DIGEST:
                        sealer.group()  # copied as written: checked by _complete
        if integrity:
            writer.add_metadata(fmt.SEAL_NAME, fmt.seal(fmt.SEAL_NAME, sealer.seal()))
        writer.finish()


#: A frame's own messages, left out when its color packet was never written.
_FRAME_TOPICS = (fmt.TOPIC_DEPTH, fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX)


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
