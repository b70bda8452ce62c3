"""frames.json of the paper layout: the layout's file names and constants, the document
:func:`~pcdcodec.convert.paper.export_paper` writes, and reading it back, field by field.

The layout itself is described in :mod:`pcdcodec.convert.paper`. Everything here is shared by
the export (:mod:`.paper_export`) and the import (:mod:`.paper_import`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..color.pyav import PyAVCodec
from ..errors import CodecUnavailableError, DecodeError, InputError
from ..geometry.camera import CameraIntrinsics
from ..geometry.transform import as_rigid

if TYPE_CHECKING:
    from ..recording.reader import Recording

__all__ = [
    "AVI_CODECS",
    "CODEC_IDS",
    "DEPTH_DTYPES",
    "DEPTH_FILE",
    "FORMAT_NAME",
    "FRAMES_FILE",
    "LAYOUT_VERSION",
    "NS_PER_S",
    "VIDEO_FILES",
    "Layout",
    "LayoutFrame",
    "bitstream_name",
    "field_error",
    "frames_document",
    "read_layout",
]

#: The ``format`` and ``version`` written into frames.json.
FORMAT_NAME = "pcdcodec-paper-layout"
LAYOUT_VERSION = 1

FRAMES_FILE = "frames.json"
DEPTH_FILE = "depth.lz4"
#: Video file name by FFmpeg container format.
VIDEO_FILES = {"matroska": "color.mkv", "avi": "color.avi"}

NS_PER_S = 1_000_000_000
#: Codecs Matroska does not list (FFmpeg refuses them there); AVI is their usual home.
AVI_CODECS = frozenset({"huffyuv", "ffvhuff"})
#: FFmpeg's codec names (``AVCodecDescriptor``) and the pcdcodec color codec for each.
CODEC_IDS = {
    "h264": "h264",
    "hevc": "h265",
    "av1": "av1",
    "vp9": "vp9",
    "mjpeg": "mjpeg",
    "mpeg4": "mpeg4",
    "ffv1": "ffv1",
    "huffyuv": "huffyuv",
    "ffvhuff": "ffvhuff",
}
#: The depth pixel types frames.json may name, as stored (little-endian).
DEPTH_DTYPES: dict[str, np.dtype[Any]] = {"uint16": np.dtype("<u2"), "float32": np.dtype("<f4")}


def bitstream_name(codec: PyAVCodec) -> str:
    """FFmpeg's name for the bitstream of ``codec`` (``hevc`` for H.265, ``av1`` for dav1d)."""
    import av

    try:
        return str(av.Codec(codec.decoder_name, "r").canonical_name)
    except Exception:
        pass
    try:
        return str(av.Codec(codec.encoder_name, "w").canonical_name)
    except Exception:
        pass
    raise CodecUnavailableError(
        f"this FFmpeg build knows neither {codec.decoder_name!r} nor {codec.encoder_name!r} "
        f"(color codec {codec.name!r}); {codec.install_hint}"
    )


# -- writing -------------------------------------------------------------------------------------


def frames_document(
    rec: Recording,
    spans: Sequence[tuple[int, int]],
    depth_dtype: str,
    video: dict[str, Any] | None,
    pts_of: Mapping[int, int],
) -> dict[str, Any]:
    """frames.json for ``rec``: ``spans`` holds each frame's (offset, length) in depth.lz4,
    ``video`` the video's description (``None`` for a depth-only recording) and ``pts_of`` the
    video pts of each frame's timestamp.

    Beside the paper's fields it keeps what the recording holds that the video and the LZ4
    depth do not: the user's ``metadata``, ``frame_id``, a color camera apart
    (``color_intrinsics`` and ``depth_to_color``, 4 × 4 row-major, metres) and, per frame, its
    ``pose`` (4 × 4 row-major, camera-to-world; absent without one) and the images' own times
    ``color_timestamp_ns`` and ``depth_timestamp_ns`` where they were stamped apart."""
    poses = rec.poses() if rec.has_poses else [None] * len(rec)
    stamps = rec.image_timestamps()
    frames = []
    for i, t in enumerate(int(t) for t in rec.timestamps):
        entry: dict[str, Any] = {
            "index": i,
            "timestamp_ns": t,
            "depth_offset": spans[i][0],
            "depth_length": spans[i][1],
            "pts": pts_of[t] if video else None,
        }
        if stamps[i] != (t, t):
            entry["color_timestamp_ns"], entry["depth_timestamp_ns"] = stamps[i]
        pose = poses[i]
        if pose is not None:
            entry["pose"] = np.asarray(pose, np.float64).tolist()
        frames.append(entry)
    color_cam = rec.color_intrinsics
    return {
        "format": FORMAT_NAME,
        "version": LAYOUT_VERSION,
        "width": rec.intrinsics.width,
        "height": rec.intrinsics.height,
        "depth_dtype": depth_dtype,
        "depth_byte_order": "little",
        "depth_scale": rec.depth_scale,
        "intrinsics": rec.intrinsics.to_dict(),
        "fps": rec.fps,
        "depth_file": DEPTH_FILE,
        "depth_codec": {"id": "lz4-frame", "store_size": True, "content_checksum": True},
        "video_file": video["file"] if video else None,
        "color_codec": rec.codecs["color"],
        "video": video,
        "frame_id": rec.frame_id,
        "color_intrinsics": None if color_cam is None else color_cam.to_dict(),
        "depth_to_color": (
            None if color_cam is None else np.asarray(rec.depth_to_color, np.float64).tolist()
        ),
        "metadata": dict(rec.metadata),
        "frames": frames,
    }


# -- reading -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LayoutFrame:
    """One entry of frames.json's ``frames``: where the frame's depth lies in depth.lz4 and the
    pts of its color frame in the video (``None`` without a video)."""

    index: int
    timestamp_ns: int
    depth_offset: int
    depth_length: int
    pts: int | None
    #: The camera-to-world pose, and the images' own times where they were stamped apart.
    pose: npt.NDArray[np.float64] | None = None
    color_timestamp_ns: int | None = None
    depth_timestamp_ns: int | None = None


@dataclass(frozen=True)
class Layout:
    """frames.json, read and checked (:func:`read_layout`)."""

    path: Path
    width: int
    height: int
    depth_dtype: np.dtype[Any]
    depth_scale: float
    intrinsics: CameraIntrinsics
    fps: float
    depth_file: str
    video_file: str | None
    color_codec: dict[str, Any] | None
    #: What frames.json says of the video: the time base of the pts, the time in ns at pts 0,
    #: and the pts of packets that are no listed frame's (color without depth).
    time_base: Fraction | None
    time_origin_ns: int
    color_only_pts: list[int]
    frames: list[LayoutFrame]
    #: What the recording held beside the paper's fields (absent in older layouts).
    frame_id: str = "camera"
    color_intrinsics: CameraIntrinsics | None = None
    depth_to_color: npt.NDArray[np.float64] | None = None
    metadata: dict[str, str] = field(default_factory=dict)


def field_error(path: Path, field: str, problem: str) -> DecodeError:
    """The error for a malformed ``field`` of the frames.json at ``path``."""
    return DecodeError(f"{str(path)!r}: field {field!r} {problem}")


def _get(doc: Mapping[str, Any], key: str, path: Path, prefix: str = "") -> Any:
    if key not in doc:
        raise field_error(path, prefix + key, "is missing")
    return doc[key]


def _int(value: Any, path: Path, field: str, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise field_error(path, field, f"must be an int >= {lo}, got {value!r}")
    return value


def _number(value: Any, path: Path, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise field_error(path, field, f"must be a positive number, got {value!r}")
    return float(value)


def _file_name(value: Any, path: Path, field: str) -> str:
    # A bare name: the layout is one folder, and a path here must not reach outside it.
    if not isinstance(value, str) or not value or Path(value).name != value or value == "..":
        raise field_error(path, field, f"must be a file name in the same folder, got {value!r}")
    return value


def read_layout(folder: Path) -> Layout:
    """Read and check ``folder``'s frames.json; a malformed field raises
    :class:`~pcdcodec.DecodeError` naming it, a missing file :class:`~pcdcodec.InputError`."""
    path = folder / FRAMES_FILE
    if not path.is_file():
        raise InputError(f"{str(path)!r} does not exist; {str(folder)!r} is not a paper layout")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DecodeError(f"{str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise DecodeError(f"{str(path)!r} must hold a JSON object, got {type(doc).__name__}")
    if doc.get("format") != FORMAT_NAME:
        raise field_error(path, "format", f"must be {FORMAT_NAME!r}, got {doc.get('format')!r}")
    version = _int(_get(doc, "version", path), path, "version", 1)
    if version > LAYOUT_VERSION:
        raise field_error(
            path, "version", f"is {version}, newer than this pcdcodec reads ({LAYOUT_VERSION})"
        )
    width = _int(_get(doc, "width", path), path, "width", 1)
    height = _int(_get(doc, "height", path), path, "height", 1)
    dtype = _get(doc, "depth_dtype", path)
    if dtype not in DEPTH_DTYPES:
        raise field_error(
            path, "depth_dtype", f"must be one of {list(DEPTH_DTYPES)}, got {dtype!r}"
        )
    if doc.get("depth_byte_order", "little") != "little":
        raise field_error(
            path, "depth_byte_order", f"must be 'little', got {doc['depth_byte_order']!r}"
        )
    try:
        intrinsics = CameraIntrinsics.from_dict(_get(doc, "intrinsics", path))
    except InputError as exc:
        raise field_error(path, "intrinsics", f"is not valid: {exc}") from None
    if (intrinsics.width, intrinsics.height) != (width, height):
        raise field_error(
            path,
            "intrinsics",
            f"are for {intrinsics.width}x{intrinsics.height}, but width x height is "
            f"{width}x{height}",
        )
    video_file = doc.get("video_file")
    if video_file is not None:
        video_file = _file_name(video_file, path, "video_file")
    color_codec = doc.get("color_codec")
    if color_codec is not None and not (isinstance(color_codec, dict) and "id" in color_codec):
        raise field_error(
            path, "color_codec", f"must be a codec config with an 'id', got {color_codec!r}"
        )
    video = doc.get("video") or {}
    if not isinstance(video, dict):
        raise field_error(path, "video", f"must be an object, got {video!r}")
    time_base: Fraction | None = None
    if "time_base" in video:
        tb = video["time_base"]
        if not (
            isinstance(tb, list)
            and len(tb) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in tb)
        ):
            raise field_error(
                path, "video.time_base", f"must be [numerator, denominator], got {tb!r}"
            )
        time_base = Fraction(tb[0], tb[1])
    origin = _int(video.get("time_origin_ns", 0), path, "video.time_origin_ns")
    color_only = video.get("color_only_pts", [])
    if not isinstance(color_only, list):
        raise field_error(path, "video.color_only_pts", f"must be a list, got {color_only!r}")
    for i, v in enumerate(color_only):
        _int(v, path, f"video.color_only_pts[{i}]", -(2**62))
    raw_frames = _get(doc, "frames", path)
    if not isinstance(raw_frames, list) or not raw_frames:
        raise field_error(path, "frames", "must be a non-empty list")
    frames: list[LayoutFrame] = []
    for i, entry in enumerate(raw_frames):
        where = f"frames[{i}]."
        if not isinstance(entry, dict):
            raise field_error(path, f"frames[{i}]", f"must be an object, got {entry!r}")
        index = _int(_get(entry, "index", path, where), path, where + "index")
        if index != i:
            raise field_error(path, where + "index", f"is {index}, expected {i}")
        ts = _int(_get(entry, "timestamp_ns", path, where), path, where + "timestamp_ns")
        if frames and ts <= frames[-1].timestamp_ns:
            raise field_error(
                path,
                where + "timestamp_ns",
                f"{ts} does not increase (frame {i - 1}: {frames[-1].timestamp_ns})",
            )
        offset = _int(_get(entry, "depth_offset", path, where), path, where + "depth_offset")
        length = _int(_get(entry, "depth_length", path, where), path, where + "depth_length", 1)
        pts = entry.get("pts")
        if video_file is not None:
            pts = _int(_get(entry, "pts", path, where), path, where + "pts", -(2**62))
        own = [
            None if entry.get(key) is None else _int(entry[key], path, where + key)
            for key in ("color_timestamp_ns", "depth_timestamp_ns")
        ]
        pose = entry.get("pose")
        pose = None if pose is None else _transform(pose, path, where + "pose")
        frames.append(LayoutFrame(i, ts, offset, length, pts, pose, *own))
    return Layout(
        path=path,
        width=width,
        height=height,
        depth_dtype=DEPTH_DTYPES[dtype],
        depth_scale=_number(_get(doc, "depth_scale", path), path, "depth_scale"),
        intrinsics=intrinsics,
        fps=_number(doc.get("fps", 30.0), path, "fps"),
        depth_file=_file_name(doc.get("depth_file", DEPTH_FILE), path, "depth_file"),
        video_file=video_file,
        color_codec=color_codec,
        time_base=time_base,
        time_origin_ns=origin,
        color_only_pts=color_only,
        frames=frames,
        **_kept(doc, path),
    )


def _transform(value: Any, path: Path, name: str) -> npt.NDArray[np.float64]:
    try:
        return as_rigid(value, name)
    except (InputError, ValueError, TypeError) as exc:
        raise field_error(path, name, f"is not a rigid 4x4 transform: {exc}") from None


def _kept(doc: Mapping[str, Any], path: Path) -> dict[str, Any]:
    """The fields beyond the paper's that frames.json may hold (see :func:`frames_document`),
    checked, as :class:`Layout`'s keyword arguments."""
    out: dict[str, Any] = {}
    frame_id = doc.get("frame_id", "camera")
    if not isinstance(frame_id, str) or not frame_id:
        raise field_error(path, "frame_id", f"must be a non-empty string, got {frame_id!r}")
    out["frame_id"] = frame_id
    metadata = doc.get("metadata") or {}
    if not isinstance(metadata, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in metadata.items()
    ):
        raise field_error(path, "metadata", f"must map strings to strings, got {metadata!r}")
    out["metadata"] = dict(metadata)
    color_cam = doc.get("color_intrinsics")
    if color_cam is not None:
        try:
            out["color_intrinsics"] = CameraIntrinsics.from_dict(color_cam)
        except (InputError, TypeError, AttributeError) as exc:
            raise field_error(path, "color_intrinsics", f"is not valid: {exc}") from None
        out["depth_to_color"] = _transform(doc.get("depth_to_color"), path, "depth_to_color")
    return out
