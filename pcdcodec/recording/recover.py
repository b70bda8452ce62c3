"""Rewriting a damaged or unfinished ``.pcdc`` file into a clean, indexed one.

Every chunk whose CRC holds is read, past damaged ones (:func:`~._scan.scan` with ``resync``).
A frame is kept when its checks hold: its depth (and pose) match its frame digest. Its color is
kept when every color packet it decodes from (from the keyframe before it) is there and matches
its group's digest; otherwise the frame is kept without color, its time listed in the
``pcdcodec.recovered`` record, so a reader gives its depth and ``color`` ``None``. What is left
out, and why, is returned (:class:`Recovered`).

A file of several cameras (format version 3) is recovered camera by camera: each camera keeps
the frames of its own that check out, and gets a seal of its own.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from ..errors import DecodeError, InputError, PcdcodecError
from . import _header as header
from . import _index as fmt

__all__ = ["Loss", "Recovered", "recover"]


@dataclass(frozen=True)
class Loss:
    """Frames ``recover`` left out, whole or in part, and why.

    ``stream`` is ``"frame"`` (the frame is left out: its depth, color and pose) or ``"color"``
    (the frame is kept with its depth and pose; its color is lost). ``frames`` are the frames'
    indices among the frames found in the damaged file (in time order) and ``timestamps`` their
    times in ns; ``camera`` names the camera of a rig (``None`` in a one-camera file).
    """

    camera: str | None
    stream: str
    frames: tuple[int, ...]
    timestamps: tuple[int, ...]
    reason: str

    def describe(self) -> str:
        """One line: which frames, what of them, why."""
        first, last = self.frames[0], self.frames[-1]
        which = f"frame {first}" if first == last else f"frames {first}-{last}"
        if len(self.frames) != last - first + 1:
            which = f"{len(self.frames)} frames from {first} to {last}"
        span = f"t={self.timestamps[0] / 1e9:.6f} s" + (
            f" to {self.timestamps[-1] / 1e9:.6f} s" if len(self.timestamps) > 1 else ""
        )
        what = "left out" if self.stream == "frame" else "kept without color (depth kept)"
        camera = f"camera {self.camera!r}: " if self.camera is not None else ""
        return f"{camera}{which} ({span}) {what}: {self.reason}"


class Recovered(int):
    """What :func:`recover` wrote: the number of frames (this int, of all cameras), and
    ``color_missing`` (of them, those kept without color), ``lost`` (:class:`Loss` entries:
    frames left out, frames kept without color) and ``damage`` (the damaged places passed
    over)."""

    color_missing: int
    lost: tuple[Loss, ...]
    damage: tuple[str, ...]

    def __new__(
        cls, frames: int, color_missing: int, lost: list[Loss], damage: list[str]
    ) -> Recovered:
        out = super().__new__(cls, frames)
        out.color_missing = color_missing
        out.lost = tuple(lost)
        out.damage = tuple(damage)
        return out

    def __reduce__(self) -> Any:
        return (type(self), (int(self), self.color_missing, list(self.lost), list(self.damage)))

    @property
    def frames(self) -> int:
        return int(self)

    @property
    def dropped(self) -> int:
        """Frames left out."""
        return sum(len(loss.frames) for loss in self.lost if loss.stream == "frame")

    def summary(self) -> list[str]:
        """Lines saying what was left out and why (empty when nothing was)."""
        lines = [loss.describe() for loss in self.lost]
        lines += [f"damage: {text}" for text in self.damage]
        return lines


def recover(
    src: str | os.PathLike[str], dst: str | os.PathLike[str], *, overwrite: bool = False
) -> Recovered:
    """Copy every frame of ``src`` that checks out into a new, indexed recording ``dst``.

    Use it on a file whose writer was killed (no summary), or that was cut or damaged: damaged
    chunks are passed over, and every frame whose depth (and pose) match its frame digest is
    kept. A frame whose color is lost (a color packet it decodes from was damaged) is kept
    with its depth, and reads with ``color`` ``None`` (``Recording.color_missing``); the
    color stream starts again at the next keyframe. Returns the number of frames of the new file
    (of all its cameras), an int that also says what was left out and why (:class:`Recovered`).
    ``src`` itself is never changed. Raises :class:`~pcdcodec.DecodeError` when ``src`` is not
    a pcdcodec recording, or its settings are lost, and :class:`~pcdcodec.InputError` when
    ``dst`` exists and ``overwrite`` is false, or is the same file as ``src``.
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
                lanes, damage = _copy(f, tmp, src_path)
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
    lost = [loss for lane in lanes for loss in lane.losses()]
    missing = sum(len(lane.color_missing) for lane in lanes)
    return Recovered(count, missing, lost, damage)


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


# -- what each camera keeps ------------------------------------------------------------------


@dataclass
class _Lane:
    """One camera of the file (the file itself for a one-camera file): its messages as found,
    and what of them is kept."""

    camera: str | None
    view: fmt.FileIndex
    integrity: int
    has_color: bool
    closed: bool  # the writer closed the file (its seal, or the data section's end, is there)
    seal: dict[str, str] | None
    keyframes: set[int] = field(default_factory=set)
    #: color packets in decode (file) order: (pts, chunk offset)
    packets: list[tuple[int, int]] = field(default_factory=list)
    #: per packet: why it cannot be used (``None``: it checks out)
    bad: list[str | None] = field(default_factory=list)
    #: packets before which the stream lost a packet: the chain of references breaks there
    breaks: dict[int, str] = field(default_factory=dict)
    depth: dict[int, bytes] = field(default_factory=dict)  # time -> digest of the data
    poses: dict[int, dict[str, bytes]] = field(default_factory=dict)
    records: dict[int, tuple[int, bytes, bytes, bytes]] = field(default_factory=dict)
    #: outcome: frame times kept, kept without color, packets kept; and per frame why
    kept: set[int] = field(default_factory=set)
    color_missing: set[int] = field(default_factory=set)
    kept_packets: set[int] = field(default_factory=set)
    kept_keyframes: set[int] = field(default_factory=set)
    why: dict[int, tuple[str, str]] = field(default_factory=dict)  # time -> (stream, reason)
    order: list[int] = field(default_factory=list)  # every frame time found, sorted

    def losses(self) -> list[Loss]:
        """The frames left out or kept without color, runs of one reason as one entry."""
        out: list[Loss] = []
        for k, t in enumerate(self.order):
            if t not in self.why:
                continue
            stream, reason = self.why[t]
            last = out[-1] if out else None
            if (
                last is not None
                and (last.stream, last.reason) == (stream, reason)
                and last.frames[-1] == k - 1
            ):
                out[-1] = Loss(
                    self.camera, stream, (*last.frames, k), (*last.timestamps, t), reason
                )
            else:
                out.append(Loss(self.camera, stream, (k,), (t,), reason))
        return out


def _copy(f: IO[bytes], tmp: Path, src_path: Path) -> tuple[list[_Lane], list[str]]:
    """Write every message that checks out of the open source ``f`` into ``tmp``, with a
    summary; the cameras' outcomes and the damage passed over."""
    name = repr(str(src_path))
    header.check_magic(f, src_path)
    try:
        index = fmt.scan(f, resync=True)
    except DecodeError:
        raise
    except Exception as exc:
        raise DecodeError(f"could not be read ({type(exc).__name__}: {exc})") from exc
    if not header.is_recording(index):
        raise header.not_a_recording(f, index, str(src_path))
    if index.loose_messages:
        raise DecodeError(
            f"{name} holds {index.loose_messages} message(s) outside chunks (an "
            "unchunked MCAP file), which carry no CRC of their own: nothing to recover from"
        )
    damage = [text.removeprefix("scan: ") for _, text in index.damaged_chunks]
    if index.truncated_at is not None:
        damage.append(
            f"the file is cut short: the record at byte offset {index.truncated_at} runs "
            "past its end"
        )
    if index.damaged_at is not None:
        damage.append(f"the file is damaged from byte offset {index.damaged_at}: {index.damage}")
    damage += _drop_damaged_seals(index)
    fmt.check_metadata(index, name)
    integrity = fmt.integrity_version(index, name)
    cameras = fmt.rig_cameras(index, name)
    views = (
        [(None, index)]
        if cameras is None
        else [(camera, fmt.camera_view(index, camera)) for camera in cameras]
    )
    ended = index.data_crc is not None
    lanes = []
    for camera, view in views:
        seal = view.metadata.get(fmt.SEAL_NAME) if integrity else None
        main = view.metadata.get(fmt.METADATA_NAME, {})
        lanes.append(
            _Lane(
                camera,
                view,
                integrity,
                bool(main.get("color_codec")),
                closed=seal is not None or (not integrity and ended),
                seal=seal,
                keyframes=set(view.times.get(fmt.TOPIC_KEYFRAMES, [])),
            )
        )
    lane_of = {cid: (lane, ch.topic) for lane in lanes for cid, ch in lane.view.channels.items()}
    offsets = sorted({o for topic in index.offsets.values() for o in topic})
    _read(f, index, offsets, lane_of, lanes)
    for lane in lanes:
        _decide(lane, index)
    damage += _write(f, tmp, index, offsets, lane_of, lanes, cameras)
    return lanes, damage


def _drop_damaged_seals(index: fmt.FileIndex) -> list[str]:
    """Leave out seal records that fail their digest (recover writes new ones): the packets
    after the last frame digest are then unchecked. What was left out, as damage lines."""
    out = []
    for record in list(index.metadata):
        if record != fmt.SEAL_NAME and not record.startswith(fmt.SEAL_NAME + "."):
            continue
        data = index.metadata[record]
        if data.get(fmt.DIGEST_KEY) != fmt.digest(record, data):
            del index.metadata[record]
            out.append(
                f"the seal record {record!r} at byte offset "
                f"{index.metadata_offsets.get(record)} is damaged: left out"
            )
    return out


def _messages(f: IO[bytes], index: fmt.FileIndex, offsets: list[int]) -> Any:
    """(offset, message) of every message in the chunks at ``offsets``, each (channel, time)
    once (a kept topic's messages may share a time), in file order."""
    from ._kept import kept_channel_ids  # (not loaded by `import pcdcodec`)

    seen: set[tuple[int, int]] = set()
    kept = set(kept_channel_ids(index))
    for offset in offsets:
        for m in fmt.read_chunk_messages(f, offset, what="recover", size=index.size):
            key = (m.channel_id, m.log_time)
            if key not in seen or m.channel_id in kept:
                seen.add(key)
                yield offset, m


def _read(
    f: IO[bytes],
    index: fmt.FileIndex,
    offsets: list[int],
    lane_of: dict[int, tuple[_Lane, str]],
    lanes: list[_Lane],
) -> None:
    """Read what every camera's frames are checked with: digests of the depth, pose and color
    packets (each color group checked against its frame digest as it closes)."""
    # Per camera, the color packets since its last frame digest: (packet number, pts, dts,
    # keyframe, data).
    groups: dict[int, list[tuple[int, int, int, bool, bytes]]] = {id(lane): [] for lane in lanes}
    for offset, m in _messages(f, index, offsets):
        found = lane_of.get(m.channel_id)
        if found is None:
            continue
        lane, topic = found
        t = int(m.log_time)
        if topic == fmt.TOPIC_COLOR:
            # (the data only where a digest will check it: a file without digests has none)
            data = bytes(m.data) if lane.integrity else b""
            packet = (len(lane.packets), t, int(m.publish_time), t in lane.keyframes, data)
            groups[id(lane)].append(packet)
            lane.packets.append((t, offset))
            lane.bad.append(None)
        elif topic == fmt.TOPIC_DEPTH:
            lane.depth[t] = fmt.data_digest(m.data)
        elif topic in (fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX):
            lane.poses.setdefault(t, {})[topic] = bytes(m.data)
        elif topic == fmt.TOPIC_FRAME_DIGEST:
            data = bytes(m.data)
            record = fmt.DIGEST_RECORD.unpack(data) if len(data) == fmt.DIGEST_RECORD.size else None
            if record is not None:
                lane.records[t] = record
            want = None if record is None else (record[0], record[1])
            _check_group(lane, groups[id(lane)], want, f"the frame digest at t={t} ns")
            groups[id(lane)] = []
    for lane in lanes:
        tail = groups[id(lane)]
        if not lane.integrity or not tail:
            continue
        if lane.seal is None:
            for j, *_ in tail:
                lane.bad[j] = _UNCHECKED
            continue
        try:
            count = int(lane.seal.get("tail_packets", ""))
            digest = bytes.fromhex(lane.seal.get("tail_digest", "").removeprefix("sha256:"))
            want = (count, digest)
        except ValueError:
            want = None
        _check_group(lane, tail, want, "the seal's digest of the last color packets")


def _check_group(
    lane: _Lane,
    group: list[tuple[int, int, int, bool, bytes]],
    want: tuple[int, bytes] | None,
    what: str,
) -> None:
    """Check the color packets ``group`` against their digest ``want`` (count, SHA-256). When
    the digest before them was lost, their group holds that one's packets too: the packets
    after the longest start that matches check out, those before it (unchecked) do not."""
    for start in range(len(group) + 1):
        sealer = fmt.Sealer()
        for _, pts, dts, keyframe, data in group[start:]:
            sealer.packet(pts, dts, keyframe, data)
        if want is not None and sealer.group() == want:
            if start:
                _bad_group(lane, [j for j, *_ in group[:start]], what)
            return
    _bad_group(lane, [j for j, *_ in group], what)


#: Why the color packets after the last frame digest of an unfinished file are not used.
_UNCHECKED = "the file ends before the frame digest of its color packet"


def _bad_group(lane: _Lane, group: list[int], what: str) -> None:
    """The color packets ``group`` (maybe none: all lost) fail their digest: none is used, and
    the stream breaks where they start."""
    first = group[0] if group else len(lane.packets)
    text = (
        f"the color packets from byte offset {lane.packets[first][1]} do not match {what}"
        if group
        else f"the color packets before {what} are lost"
    ) + " (a color packet or keyframe marker there is lost or damaged)"
    lane.breaks.setdefault(first, text)
    for j in group:
        lane.bad[j] = text


def _decide(lane: _Lane, index: fmt.FileIndex) -> None:
    """Which frames, and which color packets, ``lane`` keeps; why the others go."""
    if not lane.integrity and lane.has_color:
        # No digests: a damaged stretch between two packets may have held a packet.
        damaged = sorted(o for o, _ in index.damaged_chunks)
        if index.damaged_at is not None:
            damaged.append(index.damaged_at)
        previous = 0
        for j, (_, offset) in enumerate(lane.packets):
            hit = [d for d in damaged if previous < d < offset]
            if hit:
                lane.breaks.setdefault(
                    j, f"the color stream is damaged before it, at byte offset {hit[0]}"
                )
            previous = offset
    # A packet decodes when every packet from its keyframe on checks out.
    decodes: dict[int, str | None] = {}
    broken: str | None = "no keyframe before it in the file"
    for j, (pts, _) in enumerate(lane.packets):
        if j in lane.breaks:
            broken = f"it decodes from a color packet that is lost: {lane.breaks[j]}"
        if lane.bad[j] is not None:
            broken = f"it decodes from a color packet that is lost: {lane.bad[j]}"
            decodes[pts] = lane.bad[j]
            continue
        if pts in lane.keyframes:
            broken = None
        decodes[pts] = broken
        if broken is None:
            lane.kept_packets.add(j)
            if pts in lane.keyframes:
                lane.kept_keyframes.add(pts)
    # Every time a frame's message was found at: a frame whose depth and digest are both lost
    # is still reported, by its color packet or pose.
    frames = set(lane.depth) | set(lane.records) | set(lane.poses)
    frames |= {pts for pts, _ in lane.packets}
    lane.order = sorted(frames)
    last_record = max(lane.records, default=None)
    for t in lane.order:
        record = lane.records.get(t)
        reason = ""
        if lane.integrity and record is None:
            reason = (
                "the file ends before its frame digest (its writer stopped, or it was cut short)"
                if not lane.closed and (last_record is None or t > last_record)
                else "its frame digest message is lost (in a damaged chunk)"
            )
        elif t not in lane.depth:
            reason = "its depth message is lost (in a damaged chunk)"
        elif record is not None and lane.depth[t] != record[2]:
            reason = "its depth message does not match its frame digest"
        elif record is not None and _pose_digest(lane.poses.get(t, {})) != record[3]:
            reason = "its pose messages are lost or do not match its frame digest"
        if reason:
            lane.why[t] = ("frame", reason)
            continue
        lane.kept.add(t)
        if lane.has_color and t not in decodes:
            lane.color_missing.add(t)
            lane.why[t] = ("color", "its color packet is lost (in a damaged chunk)")
        elif lane.has_color and decodes[t] is not None:
            lane.color_missing.add(t)
            lane.why[t] = ("color", str(decodes[t]))
    if not lane.closed and lane.has_color:
        # At the end of an unfinished file, frames whose color never came were in flight.
        for t in reversed(lane.order):
            if t in lane.kept and t not in lane.color_missing:
                break
            if t in lane.color_missing and (t not in decodes or decodes[t] == _UNCHECKED):
                lane.kept.discard(t)
                lane.color_missing.discard(t)
                lane.why[t] = (
                    "frame",
                    "the file ends before its color packet (its writer stopped, or it was cut "
                    "short)",
                )


def _pose_digest(found: dict[str, bytes]) -> bytes:
    parts = [found[t] for t in (fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX) if t in found]
    return fmt.data_digest(*parts) if parts else fmt.NO_POSE


# -- the new file ------------------------------------------------------------------------------


def _write(
    f: IO[bytes],
    tmp: Path,
    index: fmt.FileIndex,
    offsets: list[int],
    lane_of: dict[int, tuple[_Lane, str]],
    lanes: list[_Lane],
    cameras: list[str] | None,
) -> list[str]:
    """Write what every camera keeps, each camera's frame digests made again for what it
    keeps, a ``pcdcodec.recovered`` record per camera with frames kept without color, and a
    seal per camera; the kept topics' messages from every chunk that holds (what of them was
    lost is returned)."""
    recovered = {
        fmt.RECOVERED_NAME if lane.camera is None else fmt.camera_recovered(lane.camera): lane
        for lane in lanes
    }
    seals = {fmt.SEAL_NAME, *(fmt.camera_seal(c) for c in cameras or [])}
    added = {
        record: fmt.seal(record, {fmt.COLOR_MISSING_KEY: json.dumps(sorted(lane.color_missing))})
        for record, lane in recovered.items()
        if lane.color_missing
    }
    with tmp.open("wb") as out:
        writer = header.start_mcap(out, "pcdcodec recover")
        for record, pairs in index.metadata.items():
            if record in seals or record in recovered:
                continue  # made again below, of what is kept
            if record == fmt.METADATA_NAME:
                pairs = _listing(pairs, set(recovered), set(added))
            writer.add_metadata(record, pairs)
        for record, pairs in added.items():
            writer.add_metadata(record, pairs)
        from ._kept_copy import KeptCopy  # (not loaded by `import pcdcodec`)

        kept = KeptCopy.of(index if cameras is None else None)
        kept.register(writer)
        channel = _channels(writer, kept.source(index), one_camera=cameras is None)
        sealers = {id(lane): fmt.Sealer() for lane in lanes}
        packet_index = {id(lane): 0 for lane in lanes}
        for _, m in _messages(f, index, offsets):
            if kept.take(writer, m):
                continue
            found = lane_of.get(m.channel_id)
            data: Any = m.data
            if found is not None:
                lane, topic = found
                t = int(m.log_time)
                sealer = sealers[id(lane)]
                if topic == fmt.TOPIC_COLOR:
                    j = packet_index[id(lane)]
                    packet_index[id(lane)] += 1
                    if j not in lane.kept_packets:
                        continue
                    sealer.packet(t, m.publish_time, t in lane.keyframes, data)
                elif topic == fmt.TOPIC_KEYFRAMES:
                    if t not in lane.kept_keyframes:
                        continue
                elif topic in _FRAME_TOPICS:
                    if t not in lane.kept:
                        continue
                elif topic == fmt.TOPIC_FRAME_DIGEST:
                    if t not in lane.kept:
                        continue
                    count, color = sealer.group()
                    _, _, depth, pose = lane.records[t]
                    data = fmt.DIGEST_RECORD.pack(count, color, depth, pose)
                sealer.note(topic, t, data)
            elif cameras is not None:
                continue  # a rig keeps its cameras' channels only
            writer.add_message(channel(m.channel_id), m.log_time, data, m.publish_time, m.sequence)
        kept_seal = kept.finish(writer)
        if any(lane.integrity for lane in lanes):
            for lane in lanes:
                record = fmt.SEAL_NAME if lane.camera is None else fmt.camera_seal(lane.camera)
                writer.add_metadata(record, fmt.seal(record, sealers[id(lane)].seal() | kept_seal))
        writer.finish()
    return kept.losses(lanes[0].seal if cameras is None else None)


#: A frame's own messages, left out with the frame.
_FRAME_TOPICS = (fmt.TOPIC_DEPTH, fmt.TOPIC_POSE, fmt.TOPIC_POSE_MATRIX, fmt.TOPIC_STAMPS)


def _listing(main: dict[str, str], recovered: set[str], added: set[str]) -> dict[str, str]:
    """The ``pcdcodec`` record listing the recovered records written (and no others)."""
    if fmt.DIGEST_KEY not in main:
        return main  # written before records were listed and sealed
    listed = fmt.parse_json(main.get(fmt.RECORDS_KEY, "[]"), "the settings' records")
    names = [n for n in listed if n not in recovered] if isinstance(listed, list) else []
    data = {k: v for k, v in main.items() if k != fmt.DIGEST_KEY}
    data[fmt.RECORDS_KEY] = json.dumps(names + sorted(added))
    return fmt.seal(fmt.METADATA_NAME, data)


def _channels(writer: Any, index: fmt.FileIndex, *, one_camera: bool) -> Any:
    """The new channel id of a channel of ``index``: a one-camera file's channels are all
    registered first, as written; a rig's with their first message, so a camera that keeps
    no frame (or a channel no message) leaves no channel without messages behind."""
    if one_camera:
        ids = header.copy_channels(writer, index)
        return ids.__getitem__
    schema_ids = {
        sid: writer.register_schema(schema, encoding, data)
        for sid, (schema, encoding, data) in index.schemas.items()
    }
    channel_ids: dict[int, int] = {}

    def channel(cid: int) -> int:
        if cid not in channel_ids:
            ch = index.channels[cid]
            schema = schema_ids.get(index.channel_schema.get(cid, 0), 0)
            channel_ids[cid] = writer.register_channel(ch.topic, ch.encoding, schema, ch.metadata)
        return channel_ids[cid]

    return channel
