"""What a ``.pcdc`` file holds, by name, and how it vouches for it.

The names of a recording's channels, encodings and metadata records (``docs/format.md``), and
its integrity records: the settings a recording is read with (camera, depth scale, codecs, user
metadata) live in MCAP metadata records, which have no CRC of their own; each one carries a
digest of its key/value pairs instead (:func:`seal`, :func:`check_metadata`). Frame digests and
the seal vouch for the messages (:class:`Sealer`). :func:`load` finds a file's messages
(:mod:`pcdcodec.recording._scan`) and trusts its summary only where the seal agrees.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import struct
import warnings
from collections.abc import Callable
from typing import IO, Any

from ..errors import DecodeError, IncompleteRecordingWarning, PcdcodecError
from ._scan import (
    MAGIC,
    ChannelInfo,
    FileIndex,
    SummaryError,
    file_size,
    from_summary,
    read_at,
    read_chunk_messages,
    scan,
)

#: Callers find a file's messages through this module too: :mod:`._scan`'s names are here.
__all__ = [
    "MAGIC",
    "ChannelInfo",
    "FileIndex",
    "file_size",
    "from_summary",
    "load",
    "read_at",
    "read_chunk_messages",
    "scan",
]

PROFILE = "pcdcodec"
#: The newest format version this pcdcodec reads and writes. Files that need nothing of a newer
#: version are written with the oldest one that holds them (see ``docs/format.md``).
FORMAT_VERSION = 4

TOPIC_COLOR = "/camera/color"
TOPIC_KEYFRAMES = "/camera/color/keyframes"
TOPIC_DEPTH = "/camera/depth"
TOPIC_CALIBRATION = "/camera/calibration"
TOPIC_COLOR_CALIBRATION = "/camera/color/calibration"  # a color camera apart from depth (v2)
TOPIC_EXTRINSICS = "/camera/extrinsics"  # where the color camera sits in the depth frame (v2)
TOPIC_POSE = "/camera/pose"  # camera-to-world pose per frame (FrameTransform)
TOPIC_POSE_MATRIX = "/camera/pose/matrix"  # the same pose, bit for bit: 16 float64 values
ENCODING_POSE_MATRIX = "pcdcodec.pose"  # 4 x 4 float64, row-major, little-endian, no schema

#: The latest time a recording holds (ns): ROS time, in the calibration and video messages,
#: has int32 seconds.
MAX_TIMESTAMP_NS = 2**31 * 1_000_000_000 - 1
#: Each image's own time, for frames whose color or depth was stamped apart from the frame's
#: time (TUM lists): :data:`STAMPS_RECORD`. Not one of the :data:`SEALED_TOPICS` (earlier
#: readers check those); the seal covers these messages with keys of their own.
TOPIC_STAMPS = "/camera/stamps"
ENCODING_STAMPS = "pcdcodec.stamps"
#: A ``/camera/stamps`` message: the color image's and the depth image's time (ns, int64).
STAMPS_RECORD = struct.Struct("<qq")
#: The seal's keys for the ``/camera/stamps`` messages (present only when there are some).
SEAL_STAMPS_KEYS = ("stamps", "stamps_digest")

ENCODING_DEPTH = "pcdcodec.depth"  # one encoded depth frame (docs/format.md), no schema
ENCODING_COLOR = "pcdcodec.color"  # one raw codec packet, for codecs without a standard schema
ENCODING_KEYFRAME = "pcdcodec.keyframe"  # an empty marker at each keyframe's pts
#: One message per frame, the frame's last: digests of the color packets written since the
#: previous one, of the frame's depth message and of its pose messages (:data:`DIGEST_RECORD`).
TOPIC_FRAME_DIGEST = "/camera/frame_digest"
ENCODING_FRAME_DIGEST = "pcdcodec.frame_digest"

METADATA_NAME = "pcdcodec"
USER_METADATA_NAME = "user"
#: In every metadata record a writer makes: the digest of the record's other pairs (:func:`seal`).
DIGEST_KEY = "pcdcodec.digest"
#: In the ``pcdcodec`` record: JSON list of the other metadata records written with it.
RECORDS_KEY = "metadata_records"
#: In the ``pcdcodec`` record of files with color digests and a seal: their version, ``1``.
INTEGRITY_KEY = "integrity"
INTEGRITY_VERSION = 1
#: The metadata record written on close: what the file holds (:meth:`Sealer.seal`).
SEAL_NAME = "pcdcodec.seal"
#: The topics whose messages the seal counts and lists (other channels may come and go).
SEALED_TOPICS = (
    TOPIC_COLOR,
    TOPIC_KEYFRAMES,
    TOPIC_FRAME_DIGEST,
    TOPIC_DEPTH,
    TOPIC_CALIBRATION,
    TOPIC_COLOR_CALIBRATION,
    TOPIC_EXTRINSICS,
    TOPIC_POSE,
    TOPIC_POSE_MATRIX,
)


#: The metadata record ``pcdcodec recover`` writes when it kept frames whose color was lost:
#: listed in ``metadata_records`` and sealed like the others.
RECOVERED_NAME = "pcdcodec.recovered"
#: In the recovered record: JSON list of the times (ns) of the frames kept without their color.
COLOR_MISSING_KEY = "color_missing"


def color_missing(index: FileIndex, what: str) -> frozenset[int]:
    """The times (ns) of the frames ``recover`` kept without color (its record, checked)."""
    record = index.metadata.get(RECOVERED_NAME)
    if record is None or COLOR_MISSING_KEY not in record:
        return frozenset()
    times = parse_json(record[COLOR_MISSING_KEY], f"{what}: {RECOVERED_NAME!r}")
    if not isinstance(times, list) or not all(
        isinstance(t, int) and not isinstance(t, bool) and 0 <= t < 1 << 64 for t in times
    ):
        raise DecodeError(
            f"{what}: {RECOVERED_NAME!r} {COLOR_MISSING_KEY!r} is not a list of frame times (ns)"
        )
    return frozenset(times)


# -- several cameras in one file (format version 3) -------------------------------------------

#: The format version of recordings with several cameras: each camera's messages and records
#: are those of a one-camera file, under the camera's own namespace and record names.
RIG_VERSION = 3
#: In the ``pcdcodec`` record of a version 3 file: JSON list of the camera names, in order.
CAMERAS_KEY = "cameras"
#: In the ``pcdcodec`` record of a version 3 file: the frame the cameras' poses are given in.
RIG_FRAME_KEY = "rig_frame_id"
#: In a camera's record: JSON 4 x 4 rigid transform from its depth camera frame to the rig frame.
RIG_POSE_KEY = "rig_pose"
#: A one-camera file's topics all start with this; a camera of a rig uses ``/<name>`` instead.
ONE_CAMERA_NAMESPACE = "/camera"
#: Camera names: what ROS takes as a namespace, and what a folder or record name can hold.
CAMERA_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
#: A one-camera file's topics: the sealed ones and the stamps.
_LANE_TOPICS = (*SEALED_TOPICS, TOPIC_STAMPS)


def parse_json(text: str, what: str) -> Any:
    """The JSON value of a record's field; :class:`DecodeError` naming ``what`` for text that
    is not JSON, nested too deep included."""
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise DecodeError(f"{what} is not valid JSON ({type(exc).__name__})") from None


def camera_record(name: str) -> str:
    """The metadata record of camera ``name`` of a rig."""
    return f"{METADATA_NAME}.camera.{name}"


def camera_seal(name: str) -> str:
    """The seal record of camera ``name`` of a rig."""
    return f"{SEAL_NAME}.{name}"


def camera_recovered(name: str) -> str:
    """The recovered record (:data:`RECOVERED_NAME`) of camera ``name`` of a rig."""
    return f"{RECOVERED_NAME}.{name}"


def camera_topic(topic: str, name: str) -> str:
    """Where camera ``name`` of a rig keeps what a one-camera file keeps on ``topic``."""
    return "/" + name + topic[len(ONE_CAMERA_NAMESPACE) :]


def rig_cameras(index: FileIndex, what: str) -> list[str] | None:
    """The camera names of a version 3 file, checked; ``None`` for a one-camera file."""
    main = index.metadata.get(METADATA_NAME)
    if main is None or CAMERAS_KEY not in main:
        return None
    try:
        names = parse_json(main[CAMERAS_KEY], f"{what}: {CAMERAS_KEY!r}")
    except DecodeError:
        names = None
    if (
        not isinstance(names, list)
        or not names
        or not all(isinstance(n, str) and CAMERA_NAME.fullmatch(n) for n in names)
        or len(set(names)) != len(names)
    ):
        text = main[CAMERAS_KEY]
        shown = repr(text) if len(text) <= 80 else repr(text[:80]) + f"... ({len(text)} chars)"
        raise DecodeError(
            f"{what}: {CAMERAS_KEY!r} is {shown}, expected a JSON list of distinct camera names"
        )
    return names


def camera_rig_pose(index: FileIndex, name: str, what: str) -> Any:
    """Camera ``name``'s pose on the rig (4 × 4 float64), from its record, checked."""
    from ..geometry.transform import as_rigid

    record = index.metadata.get(camera_record(name))
    if record is None:
        raise DecodeError(f"{what}: camera {name!r} has no record")
    try:
        return as_rigid(parse_json(record[RIG_POSE_KEY], f"{name}.rig_pose"), "rig_pose")
    except (KeyError, ValueError, PcdcodecError) as exc:
        raise DecodeError(f"{what}: camera {name!r} has no valid rig pose ({exc})") from None


def camera_view(index: FileIndex, name: str) -> FileIndex:
    """Camera ``name`` of a rig's file seen as a one-camera file: its channels under the
    one-camera topics, its record as the ``pcdcodec`` record and its seal as the seal.

    The records are sealed again under their one-camera names: call this only on an index whose
    digests were checked (:func:`check_metadata` on the whole file).
    """
    topics = {camera_topic(t, name): t for t in _LANE_TOPICS}
    channels = {
        cid: dataclasses.replace(info, topic=topics[info.topic])
        for cid, info in index.channels.items()
        if info.topic in topics
    }
    renamed = {
        camera_record(name): METADATA_NAME,
        camera_seal(name): SEAL_NAME,
        camera_recovered(name): RECOVERED_NAME,
    }
    if USER_METADATA_NAME in index.metadata:
        renamed[USER_METADATA_NAME] = USER_METADATA_NAME
    listed = [
        seen
        for real, seen in renamed.items()
        if seen in (USER_METADATA_NAME, RECOVERED_NAME) and real in index.metadata
    ]
    metadata: dict[str, dict[str, str]] = {}
    offsets: dict[str, int] = {}
    for real, seen in renamed.items():
        if real in index.metadata:
            data = dict(index.metadata[real])
            if seen == METADATA_NAME:
                data[RECORDS_KEY] = json.dumps(listed)
            metadata[seen] = seal(seen, data) if DIGEST_KEY in data else data
            if real in index.metadata_offsets:
                offsets[seen] = index.metadata_offsets[real]
    return dataclasses.replace(
        index,
        channels=channels,
        channel_schema={c: s for c, s in index.channel_schema.items() if c in channels},
        metadata=metadata,
        metadata_offsets=offsets,
        times={topics[t]: v for t, v in index.times.items() if t in topics},
        offsets={topics[t]: v for t, v in index.offsets.items() if t in topics},
        damaged_chunks=list(index.damaged_chunks),
        duplicates={topics[t]: n for t, n in index.duplicates.items() if t in topics},
    )


def ends_early(index: FileIndex) -> str | None:
    """Why the file of ``index`` ends before its writer closed it, or ``None`` when it was
    closed: it has its summary, the end of its data section, or a seal (written on closing)."""
    if index.indexed or index.data_crc is not None:
        return None
    if any(name == SEAL_NAME or name.startswith(SEAL_NAME + ".") for name in index.metadata):
        return None
    if index.truncated_at is not None:
        return (
            f"it is cut short: the record at byte offset {index.truncated_at} runs past its "
            f"end, at byte {index.size}"
        )
    return (
        "it ends without the records a writer adds on closing: its writer was stopped, or "
        "it was cut short"
    )


def warn_if_incomplete(index: FileIndex, name: str, frames: Callable[[], str]) -> None:
    """Warn (:class:`~pcdcodec.errors.IncompleteRecordingWarning`) when the file ``name`` of
    ``index`` :func:`ends_early`, saying which ``frames()`` can be read and what to do."""
    reason = ends_early(index)
    if reason is not None:
        warnings.warn(
            f"{name!r} is incomplete ({reason}); {frames()} can be read. `pcdcodec recover "
            f"{name} -o OUT` copies them into a closed recording",
            IncompleteRecordingWarning,
            stacklevel=4,
        )


def load(f: IO[bytes]) -> FileIndex:
    """The index of a recording: from its summary when that is intact, else from a scan."""
    problem: str | None = None
    try:
        index = from_summary(f)
    except SummaryError as exc:
        index, problem = None, str(exc)
    if index is not None:
        # A summary that disagrees with the seal (written last, in the data section) is not
        # used either: the scan then finds what the file really holds.
        try:
            disagree = seal_problems(index, "the summary")
        except DecodeError as exc:
            disagree = [str(exc)]
        if not disagree:
            return index
        problem = "it disagrees with the file's seal (" + "; ".join(disagree) + ")"
    index = scan(f)
    if problem is None and index.data_crc is not None:
        problem = "the data section ends, but no intact summary and footer follow it"
    index.summary_problem = problem
    return index


# -- the file's own settings --------------------------------------------------------------------


def digest(name: str, data: dict[str, str]) -> str:
    """The digest of a metadata record: SHA-256 of its name and sorted pairs, as JSON."""
    pairs = sorted([k, v] for k, v in data.items() if k != DIGEST_KEY)
    text = json.dumps([name, pairs], separators=(",", ":"))
    return "sha256:" + hashlib.sha256(text.encode("ascii")).hexdigest()


def seal(name: str, data: dict[str, str]) -> dict[str, str]:
    """``data`` with its digest added, as a writer stores every metadata record."""
    return {**data, DIGEST_KEY: digest(name, data)}


def check_metadata(index: FileIndex, what: str) -> None:
    """Check the digest of every metadata record of a recording that was written with them.

    Files whose ``pcdcodec`` record has no digest were written before digests existed and are
    read as they are. Raises :class:`DecodeError` naming the record and its byte offset.
    """
    main = index.metadata.get(METADATA_NAME)
    if main is None or DIGEST_KEY not in main:
        return
    for name, data in index.metadata.items():
        offset = index.metadata_offsets.get(name)
        if DIGEST_KEY not in data:
            if name == METADATA_NAME:
                continue
            listed = name in _listed(main, what)
            if listed:
                raise DecodeError(
                    f"{what}: metadata record {name!r} at byte offset {offset} has no digest"
                )
            continue  # a record some other tool added: pcdcodec does not read it
        if data[DIGEST_KEY] != digest(name, data):
            raise DecodeError(
                f"{what}: metadata record {name!r} at byte offset {offset} does not match its "
                "digest: the recording's settings were changed or damaged"
            )
    missing = [name for name in _listed(main, what) if name not in index.metadata]
    if missing:
        raise DecodeError(f"{what}: metadata record(s) {missing} are missing")


def _listed(main: dict[str, str], what: str) -> list[str]:
    try:
        names = parse_json(main.get(RECORDS_KEY, "[]"), f"{what}: {RECORDS_KEY!r}")
    except DecodeError:
        names = None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise DecodeError(f"{what}: {RECORDS_KEY!r} is not a list of record names")
    return names


# -- color digests and the seal ----------------------------------------------------------------

#: What a color packet adds to its group's digest: pts, dts (as stored), keyframe flag, length.
_PACKET_FIELDS = struct.Struct("<QQBQ")
_STAMP_FIELDS = struct.Struct("<QQ")
#: A ``/camera/frame_digest`` message: the number of color packets in the frame's group and
#: their SHA-256, the SHA-256 of the depth message's data, and the SHA-256 of the pose and pose
#: matrix messages' data (32 zero bytes for a frame without a pose).
DIGEST_RECORD = struct.Struct("<I32s32s32s")
NO_POSE = bytes(32)


def data_digest(*parts: bytes | memoryview) -> bytes:
    """SHA-256 of the message data ``parts`` one after another."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    return h.digest()


class Sealer:
    """Follows the messages of a recording in file order and makes its integrity records.

    A writer calls :meth:`note` for every message it writes and :meth:`packet` for every color
    packet; :meth:`group` closes the group of packets of one frame (for its digest message) and
    :meth:`seal` makes the seal record. A reader uses the same methods to recompute them.
    """

    def __init__(self) -> None:
        self._structure = hashlib.sha256()
        self.counts: dict[str, int] = {}
        self.first: int | None = None
        self.last: int | None = None
        self._group = hashlib.sha256()
        self._group_count = 0
        self._stamps = hashlib.sha256()
        self._stamp_count = 0

    def note(self, topic: str, log_time: int, data: bytes | memoryview = b"") -> None:
        """A message on ``topic`` at ``log_time`` (ns), the next one in the file; ``data`` is
        its data (used for ``/camera/stamps``, whose messages the seal digests)."""
        if topic == TOPIC_STAMPS:
            self._stamps.update(_STAMP_FIELDS.pack(log_time, len(data)))
            self._stamps.update(data)
            self._stamp_count += 1
            return
        if topic not in SEALED_TOPICS:
            return
        self._structure.update(f"{topic} {log_time}\n".encode())
        self.counts[topic] = self.counts.get(topic, 0) + 1
        if topic == TOPIC_DEPTH:
            self.first = log_time if self.first is None else self.first
            self.last = log_time

    def packet(self, pts: int, dts: int, keyframe: bool, data: bytes | memoryview) -> None:
        """A color packet: its message's log time, publish time and data, as stored."""
        self._group.update(_PACKET_FIELDS.pack(pts, dts, int(keyframe), len(data)))
        self._group.update(data)
        self._group_count += 1

    def group(self) -> tuple[int, bytes]:
        """The number and SHA-256 of the packets since the last call; starts a new group."""
        out = self._group_count, self._group.digest()
        self._group, self._group_count = hashlib.sha256(), 0
        return out

    def frame_record(self, depth: bytes | memoryview, pose: bytes = NO_POSE) -> bytes:
        """The data of a frame's digest message: :meth:`group`, the depth message's data and
        the digest of its pose messages' data (:func:`data_digest`)."""
        count, color = self.group()
        return DIGEST_RECORD.pack(count, color, data_digest(depth), pose)

    def seal(self) -> dict[str, str]:
        """The seal record (before its own digest is added by :func:`seal`)."""
        count, digest_ = self.group()
        out = {
            **self.summary(),
            "tail_packets": str(count),
            "tail_digest": "sha256:" + digest_.hex(),
        }
        if self._stamp_count:
            out.update(zip(SEAL_STAMPS_KEYS, self.stamps_seal(), strict=True))
        return out

    def stamps_seal(self) -> tuple[str, str]:
        """The seal's ``stamps`` and ``stamps_digest``: the number of ``/camera/stamps``
        messages noted and the SHA-256 of their times and data, in file order."""
        return str(self._stamp_count), "sha256:" + self._stamps.hexdigest()

    def summary(self) -> dict[str, str]:
        """The part of the seal that an index alone can be checked against."""
        return {
            "frames": str(self.counts.get(TOPIC_DEPTH, 0)),
            "messages": json.dumps(dict(sorted(self.counts.items())), separators=(",", ":")),
            "first_timestamp": "" if self.first is None else str(self.first),
            "last_timestamp": "" if self.last is None else str(self.last),
            "structure": "sha256:" + self._structure.hexdigest(),
        }


def structure_of(index: FileIndex) -> Sealer:
    """A :class:`Sealer` that has noted the messages of ``index`` in file order."""
    entries = [
        (offset, k, topic, t)
        for topic in SEALED_TOPICS
        for k, (t, offset) in enumerate(
            zip(index.times.get(topic, []), index.offsets.get(topic, []), strict=True)
        )
    ]
    # One message per chunk in files pcdcodec writes; within a chunk, the index keeps order.
    entries.sort(key=lambda e: (e[0], e[1]))
    sealer = Sealer()
    for _, _, topic, t in entries:
        sealer.note(topic, t)
    return sealer


def integrity_version(index: FileIndex, what: str) -> int:
    """The ``integrity`` of the file's ``pcdcodec`` record, 0 for files written without it."""
    text = index.metadata.get(METADATA_NAME, {}).get(INTEGRITY_KEY)
    if text is None:
        return 0
    try:
        version = int(text)
        if version < 1:
            raise ValueError
    except ValueError:
        raise DecodeError(
            f"{what}: {INTEGRITY_KEY!r} is {text!r}, expected a positive int"
        ) from None
    return version


def seal_problems(index: FileIndex, what: str, *, record: str = SEAL_NAME) -> list[str]:
    """How the messages of ``index`` differ from the file's seal (empty when they agree).

    Raises :class:`DecodeError` when a file written with integrity records lacks a seal
    although it was closed (it has a usable summary, or its data section ends), or its seal
    has no digest. A file without a seal that was not closed (its writer died) has none.
    ``record`` is the seal record's name in the file, for the messages: a rig camera's
    :func:`camera_view` has its seal (:func:`camera_seal`) under the one-camera name.
    """
    if not integrity_version(index, what):
        return []
    names = rig_cameras(index, what)
    if names is not None:
        return [
            f"camera {name!r}: {problem}"
            for name in names
            for problem in seal_problems(camera_view(index, name), what, record=camera_seal(name))
        ]
    seal_ = index.metadata.get(SEAL_NAME)
    if seal_ is None:
        if index.indexed or index.data_crc is not None:
            raise DecodeError(
                f"{what}: the file was closed, but its seal record {record!r} is missing"
            )
        return []
    if DIGEST_KEY not in seal_:
        raise DecodeError(f"{what}: the seal record {record!r} has no digest")
    found = structure_of(index).summary()
    labels = {
        "frames": "frames",
        "messages": "messages per channel",
        "first_timestamp": "first frame time (ns)",
        "last_timestamp": "last frame time (ns)",
        "structure": "",
    }
    return [
        f"{label}: sealed {seal_.get(key)!r}, found {found[key]!r}"
        if key != "structure"
        else "the messages are not those sealed, or not in the sealed order"
        for key, label in labels.items()
        if seal_.get(key) != found[key]
    ]
