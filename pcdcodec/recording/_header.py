"""The records that describe a recording, each defined once, its writing and its parsing side by
side: the MCAP header, the settings record (camera, depth scale, codecs), the user's metadata, the
color and depth channels' metadata, the calibration messages and the transforms (extrinsics and
poses).

The writer makes them, the reader parses and checks them, and ``join`` and ``recover`` copy them
(``docs/format.md`` describes each). Where the topics and the digests of these records live is
:mod:`pcdcodec.recording._index`.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from .._version import __version__
from ..errors import DecodeError, InputError, InputTypeError, PcdcodecError
from ..geometry.camera import CameraIntrinsics, as_intrinsics
from ..geometry.transform import as_rigid, matrix_to_quaternion, quaternion_to_matrix
from ..ros.foxglove import CameraCalibration, FrameTransform
from . import _index as fmt

#: The library a writer names in the MCAP header and in the settings record.
LIBRARY = f"pcdcodec {__version__}"


def writer_camera(value: Any) -> CameraIntrinsics:
    """The camera a writer is given (any form :func:`~pcdcodec.geometry.camera.as_intrinsics`
    takes); a writer cannot do without one."""
    if value is None:
        raise InputError(
            "intrinsics are required to write a recording: pass "
            "intrinsics=pcdcodec.CameraIntrinsics(width, height, fx, fy, cx, cy)"
        )
    return as_intrinsics(value)


# -- the MCAP header ----------------------------------------------------------------------------


def start_mcap(file: IO[bytes], library: str = LIBRARY) -> Any:
    """An MCAP writer on ``file`` with the header every pcdcodec file starts with written.

    One chunk per message: each is on disk (with its CRC) as soon as it is written, and MCAP's
    chunk index then gives every message's time and offset directly.
    """
    from mcap.writer import CompressionType, Writer

    mcap = Writer(file, chunk_size=0, compression=CompressionType.NONE, enable_data_crcs=True)
    # The writer keeps every chunk's index entry for the summary, as an object of about 600
    # bytes: with a chunk per message, 2-3 KB per frame, growing with the recording. Packed,
    # they take 72 bytes each (the same summary is written).
    if isinstance(getattr(mcap, _CHUNK_INDEXES, None), list) and not getattr(mcap, _CHUNK_INDEXES):
        setattr(mcap, _CHUNK_INDEXES, PackedChunkIndexes())
    mcap.start(profile=fmt.PROFILE, library=library)
    return mcap


#: Where mcap's Writer keeps its chunk index entries until it writes the summary.
_CHUNK_INDEXES = "_Writer__chunk_indices"


class PackedChunkIndexes:
    """The chunk index entries of an MCAP writer, kept as packed integers.

    Takes what the writer appends and gives back equal ``ChunkIndex`` records, in order, when it
    writes the summary. Entries of one channel, uncompressed (all that pcdcodec writes), take 9
    integers; any other entry is kept as it is.
    """

    def __init__(self) -> None:
        from array import array

        self._rows = array("Q")
        self._others: dict[int, Any] = {}  # position -> an entry kept whole
        self._count = 0

    def append(self, entry: Any) -> None:
        offsets = entry.message_index_offsets
        if entry.compression == "" and len(offsets) == 1:
            ((channel, where),) = offsets.items()
            self._rows.extend(
                (
                    entry.message_start_time,
                    entry.message_end_time,
                    entry.chunk_start_offset,
                    entry.chunk_length,
                    channel,
                    where,
                    entry.message_index_length,
                    entry.compressed_size,
                    entry.uncompressed_size,
                )
            )
        else:
            self._others[self._count] = entry
        self._count += 1

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Any:
        from mcap.records import ChunkIndex

        rows = self._rows
        k = 0
        for position in range(self._count):
            other = self._others.get(position)
            if other is not None:
                yield other
                continue
            start, end, offset, length, channel, where, index_length, size, raw = rows[k : k + 9]
            k += 9
            yield ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=offset,
                chunk_length=length,
                message_index_offsets={channel: where},
                message_index_length=index_length,
                compression="",
                compressed_size=size,
                uncompressed_size=raw,
            )

    @property
    def nbytes(self) -> int:
        """Bytes the packed entries take."""
        return self._rows.itemsize * len(self._rows)


def library_of(path: Path) -> str:
    """The library named in the MCAP header of the file at ``path``."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return str(make_reader(f).get_header().library)


def check_magic(f: IO[bytes], path: str | Path) -> None:
    """Raise :class:`DecodeError` unless ``f`` starts as an MCAP file; leaves ``f`` at 0."""
    head = f.read(8)
    if head != fmt.MAGIC:
        raise DecodeError(f"{str(path)!r} is not a pcdcodec recording (not an MCAP file)")
    f.seek(0)


def is_recording(index: fmt.FileIndex) -> bool:
    """Whether an MCAP file's header and records make it a pcdcodec recording."""
    return index.profile == fmt.PROFILE and fmt.METADATA_NAME in index.metadata


def not_a_recording(f: IO[bytes], index: fmt.FileIndex, name: str) -> DecodeError:
    """The error for an MCAP file in which no recording's settings were found: a pcdcodec
    recording cut short or damaged before its settings record, when its first bytes (the MCAP
    header's profile) show it is one, else an MCAP file of another kind."""
    if index.profile != fmt.PROFILE:
        # A file cut inside its header record: the profile's first bytes, where they are.
        f.seek(0)
        head = f.read(_PROFILE_AT + len(fmt.PROFILE))
        f.seek(0)
        seen = head[_PROFILE_AT:]
        if index.profile or not seen or not fmt.PROFILE.encode().startswith(seen):
            return DecodeError(
                f"{name!r} is an MCAP file but not a pcdcodec recording "
                f"(profile {index.profile!r}, no {fmt.METADATA_NAME!r} metadata)"
            )
    where = (
        f"cut short at byte {index.size}"
        if index.truncated_at is not None
        else "damaged"
        + (f" at byte offset {index.damaged_at}" if index.damaged_at is not None else "")
    )
    return DecodeError(
        f"{name!r} is a pcdcodec recording {where}, before its settings record "
        f"({fmt.METADATA_NAME!r}) was written whole: nothing can be recovered from it, "
        "as the camera, depth scale and codecs are lost"
    )


#: Where the MCAP header's profile string starts: magic, opcode, length, the string's length.
_PROFILE_AT = 8 + 1 + 8 + 4


def copy_channels(writer: Any, index: fmt.FileIndex) -> dict[int, int]:
    """Register the schemas and channels of ``index`` with ``writer``, in their order; the
    channel ids of ``index`` -> those of ``writer``."""
    schema_ids = {
        sid: writer.register_schema(name, encoding, data)
        for sid, (name, encoding, data) in index.schemas.items()
    }
    return {
        cid: writer.register_channel(
            ch.topic, ch.encoding, schema_ids.get(index.channel_schema.get(cid, 0), 0), ch.metadata
        )
        for cid, ch in index.channels.items()
    }


# -- the settings record ------------------------------------------------------------------------


@dataclass(frozen=True)
class Settings:
    """The ``pcdcodec`` metadata record: what a recording is read with."""

    format_version: int
    intrinsics: CameraIntrinsics
    depth_scale: float
    fps: float
    #: the codecs' stored configs (:meth:`~pcdcodec.Codec.stored_config`); no color: ``None``
    depth_codec: dict[str, Any]
    color_codec: dict[str, Any] | None
    frame_id: str = "camera"
    #: a color camera apart from the depth camera (format version 2), else ``None``
    color_intrinsics: CameraIntrinsics | None = None
    depth_to_color: npt.NDArray[np.float64] | None = None

    @staticmethod
    def version_for(intrinsics: CameraIntrinsics, two_cameras: bool) -> int:
        """Version 2 only where a version 1 reader would give wrong clouds: a color camera
        apart from depth, or lens distortion. Everything else stays readable by version 1."""
        return 2 if two_cameras or intrinsics.has_distortion else 1

    @property
    def color_shape(self) -> tuple[int, int]:
        """``(height, width)`` of the color images: the color camera's, else the depth's."""
        return (self.color_intrinsics or self.intrinsics).shape

    def record(self) -> dict[str, str]:
        """The record as written (before :func:`records` lists the others and seals it)."""
        cameras: dict[str, str] = {}
        if self.color_intrinsics is not None and self.depth_to_color is not None:
            cameras = {
                "color_intrinsics": json.dumps(self.color_intrinsics.to_dict()),
                "depth_to_color": json.dumps(self.depth_to_color.tolist()),
            }
        return {
            "format_version": str(self.format_version),
            "library": LIBRARY,
            "intrinsics": json.dumps(self.intrinsics.to_dict()),
            "depth_scale": repr(self.depth_scale),
            "fps": repr(self.fps),
            "depth_codec": json.dumps(self.depth_codec),
            "color_codec": json.dumps(self.color_codec) if self.color_codec else "",
            "frame_id": self.frame_id,
            fmt.INTEGRITY_KEY: str(fmt.INTEGRITY_VERSION),
            **cameras,
        }

    @classmethod
    def parse(cls, meta: dict[str, str], name: str, where: str) -> Settings:
        """The record ``meta`` of the file ``name`` (found at ``where``), checked.

        Raises :class:`DecodeError` for a record that is damaged or of a newer version.
        """
        try:
            version = int(meta["format_version"])
            if version < 1:
                raise ValueError(f"format_version {version} is not a version")
        except (KeyError, ValueError):
            raise DecodeError(f"{where} has no valid format_version") from None
        if version > fmt.FORMAT_VERSION:
            raise DecodeError(
                f"{name!r} is format version {version}, newer than this pcdcodec reads "
                f"(version {fmt.FORMAT_VERSION}); upgrade pcdcodec to read it"
            )
        color_intrinsics: CameraIntrinsics | None = None
        depth_to_color: npt.NDArray[np.float64] | None = None
        if meta.get("color_intrinsics"):
            try:
                color_intrinsics = CameraIntrinsics.from_dict(json.loads(meta["color_intrinsics"]))
                depth_to_color = as_rigid(json.loads(meta["depth_to_color"]), "depth_to_color")
            except Exception as exc:  # damaged text of any kind, JSON nested too deep included
                raise DecodeError(
                    f"{name!r} has a damaged color camera record ({type(exc).__name__}: {exc})"
                ) from None
        try:
            intrinsics = CameraIntrinsics.from_dict(json.loads(meta["intrinsics"]))
            depth_scale = float(meta["depth_scale"])
            fps = float(meta.get("fps", "30"))
            if not (np.isfinite(depth_scale) and depth_scale > 0):
                raise ValueError(f"depth_scale {depth_scale} is not positive and finite")
            if not (np.isfinite(fps) and fps > 0):
                raise ValueError(f"fps {fps} is not positive and finite")
            depth_config = json.loads(meta["depth_codec"])
            color_config = json.loads(meta["color_codec"]) if meta.get("color_codec") else None
        except Exception as exc:
            raise DecodeError(
                f"{where} is not valid ({type(exc).__name__}: {exc}); expected the intrinsics, "
                "depth_scale, fps and codec configs a pcdcodec writer stores"
            ) from exc
        return cls(
            version,
            intrinsics,
            depth_scale,
            fps,
            depth_config,
            color_config,
            meta.get("frame_id", "camera"),
            color_intrinsics,
            depth_to_color,
        )


def records(settings: Settings, user: dict[str, str]) -> dict[str, dict[str, str]]:
    """Every metadata record a writer makes, by name, each sealed with its digest; the main
    record lists the others, so a reader notices any of them changed or missing."""
    out: dict[str, dict[str, str]] = {fmt.METADATA_NAME: settings.record()}
    if user:
        out[fmt.USER_METADATA_NAME] = user
    out[fmt.METADATA_NAME][fmt.RECORDS_KEY] = json.dumps(
        [name for name in out if name != fmt.METADATA_NAME]
    )
    return {name: fmt.seal(name, data) for name, data in out.items()}


# -- the user's metadata ------------------------------------------------------------------------


def user_metadata(metadata: Any) -> dict[str, str]:
    """User metadata as MCAP's str -> str map: strings kept, other values as JSON."""
    if metadata is None:
        return {}
    if not isinstance(metadata, dict):
        raise InputTypeError(f"metadata must be a dict, got {type(metadata).__name__}")
    out: dict[str, str] = {}
    for key, value in metadata.items():
        if not isinstance(key, str):
            raise InputTypeError(f"metadata key {key!r} must be a str, got {type(key).__name__}")
        if isinstance(value, str):
            out[key] = value
            continue
        try:
            out[key] = json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"metadata[{key!r}] = {value!r} is not a str and cannot be stored as JSON ({exc})"
            ) from None
    if fmt.DIGEST_KEY in out:
        raise InputError(f"metadata key {fmt.DIGEST_KEY!r} is reserved for the file's digest")
    return out


def read_user_metadata(index: fmt.FileIndex) -> dict[str, str]:
    """The user's metadata of a recording, as written."""
    user = index.metadata.get(fmt.USER_METADATA_NAME, {})
    return {k: v for k, v in user.items() if k != fmt.DIGEST_KEY}


# -- the channels' metadata ---------------------------------------------------------------------


def color_channel(
    width: int,
    height: int,
    config: dict[str, Any],
    extradata: bytes | None,
    video_format: str | None,
) -> dict[str, str]:
    """The metadata of the color channel."""
    meta = {
        "width": str(width),
        "height": str(height),
        "codec": json.dumps(config),
        "extradata": base64.b64encode(extradata).decode() if extradata else "",
    }
    if video_format:
        meta["format"] = video_format
    return meta


def extradata_of(index: fmt.FileIndex) -> bytes | None:
    """The color decoder's set-up bytes, from the color channel's metadata."""
    channel = index.channel(fmt.TOPIC_COLOR)
    if channel is not None and channel.metadata.get("extradata"):
        return base64.b64decode(channel.metadata["extradata"])
    return None


def depth_channel(
    width: int, height: int, config: dict[str, Any], depth_scale: float
) -> dict[str, str]:
    """The metadata of the depth channel."""
    return {
        "width": str(width),
        "height": str(height),
        "codec": json.dumps(config),
        "depth_scale": repr(depth_scale),
    }


def check_channels(
    index: fmt.FileIndex, name: str, settings: Settings, camera: str | None = None
) -> None:
    """The channels (inside CRC-checked chunks) must agree with the settings record (of
    ``camera`` of a rig, whose :func:`~pcdcodec.recording._index.camera_view` ``index`` is)."""
    cam = settings.intrinsics
    expected: dict[str, dict[str, Any]] = {
        fmt.TOPIC_DEPTH: {
            "width": cam.width,
            "height": cam.height,
            "codec": settings.depth_codec,
            "depth_scale": settings.depth_scale,
        },
        fmt.TOPIC_COLOR: {
            "width": settings.color_shape[1],
            "height": settings.color_shape[0],
            "codec": settings.color_codec,
        },
    }
    for topic, want in expected.items():
        channel = index.channel(topic)
        if channel is None:
            continue
        for key, value in want.items():
            if key not in channel.metadata:
                continue
            text = channel.metadata[key]
            try:
                got: Any = json.loads(text) if key == "codec" else float(text)
            except (ValueError, RecursionError):
                got = text
            if got != value:
                real = topic if camera is None else fmt.camera_topic(topic, camera)
                record = fmt.METADATA_NAME if camera is None else fmt.camera_record(camera)
                of = "" if camera is None else f" camera {camera!r}:"
                raise DecodeError(
                    f"{name!r}:{of} channel {real!r} says {key} is {text}, but the "
                    f"{record!r} record says {value!r}"
                )


# -- the calibration messages -------------------------------------------------------------------


def calibration(intr: CameraIntrinsics, frame_id: str, timestamp: int) -> bytes:
    """A camera's calibration message (a Foxglove ``CameraCalibration``)."""
    info = intr.to_camera_info()
    return CameraCalibration(
        timestamp,
        frame_id,
        intr.width,
        intr.height,
        info["distortion_model"],
        [float(v) for v in info["D"]],
        [float(v) for v in info["K"]],
        [float(v) for v in info["R"]],
        [float(v) for v in info["P"]],
    ).encode()


def calibration_problems(
    f: IO[bytes], index: fmt.FileIndex, cam: CameraIntrinsics, *, readable_only: bool = False
) -> list[str]:
    """The calibration message (inside a CRC-checked chunk) must match the intrinsics.

    With ``readable_only``, a message that cannot be read is no problem (only one that
    disagrees is). The caller holds whatever lock guards ``f``.
    """
    offsets = index.offsets.get(fmt.TOPIC_CALIBRATION, [])
    channel = index.channel(fmt.TOPIC_CALIBRATION)
    if not offsets or channel is None:
        return []
    try:
        messages = fmt.read_chunk_messages(f, offsets[0], what="calibration")
        data = next(m.data for m in messages if m.channel_id == channel.id)
        cal = CameraCalibration.decode(data)
    except PcdcodecError as exc:
        return [] if readable_only else [str(exc)]
    except Exception as exc:
        return (
            []
            if readable_only
            else [
                f"the calibration message at byte offset {offsets[0]} does not parse "
                f"({type(exc).__name__}: {exc})"
            ]
        )
    k = [cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0]
    if (cal.width, cal.height) != (cam.width, cam.height) or not np.allclose(cal.k, k):
        return [
            f"the calibration message at byte offset {offsets[0]} ({cal.width}x{cal.height}, "
            f"K={list(cal.k)}) disagrees with the recording's intrinsics {cam}"
        ]
    return []


# -- transforms: the extrinsics and the poses ---------------------------------------------------


def transform(matrix: npt.NDArray[np.float64], timestamp: int, parent: str, child: str) -> bytes:
    """A rigid 4 × 4 transform as a Foxglove ``FrameTransform`` message."""
    q = matrix_to_quaternion(matrix[:3, :3])
    t = matrix[:3, 3]
    return FrameTransform(
        timestamp,
        parent,
        child,
        (float(t[0]), float(t[1]), float(t[2])),
        (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
    ).encode()


def transform_matrix(data: bytes) -> npt.NDArray[np.float64]:
    """The 4 × 4 matrix of a ``FrameTransform`` message."""
    msg = FrameTransform.decode(data)
    pose = np.eye(4)
    pose[:3, :3] = quaternion_to_matrix(msg.rotation)
    pose[:3, 3] = msg.translation
    return pose


def extrinsics(depth_to_color: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """What the extrinsics message holds: the color camera's pose in the depth camera's frame,
    the inverse of ``depth_to_color``."""
    return np.asarray(np.linalg.inv(depth_to_color), dtype=np.float64)


def pose_matrix(pose: npt.NDArray[np.float64]) -> bytes:
    """A pose matrix message: the quaternion is a rounding away from the matrix given; this
    keeps it exactly (16 float64, row-major, little-endian)."""
    return np.ascontiguousarray(pose, dtype="<f8").tobytes()


def parse_pose_matrix(data: bytes | memoryview, i: int, offset: int) -> npt.NDArray[np.float64]:
    """The rigid pose of a pose matrix message (frame ``i``, at byte ``offset``)."""
    if len(data) != 128:
        raise DecodeError(
            f"frame {i}: pose matrix at byte offset {offset} has {len(data)} "
            "bytes, expected 128 (16 float64)"
        )
    matrix = np.frombuffer(data, dtype="<f8").reshape(4, 4).astype(np.float64)
    try:
        return as_rigid(matrix, f"frame {i} pose")
    except PcdcodecError as exc:
        raise DecodeError(str(exc)) from None
