"""ROS message payloads to numpy arrays, and back: header stamps, images, compressed images,
camera info and encoded video packets. Organized point clouds are read by :mod:`.clouds` (their
names are served here too).

Messages are the objects ``rosbags`` deserializes (attributes named as in the ``.msg`` files), of
ROS 1 or ROS 2; both field spellings of ``CameraInfo`` (``K``/``k``, ``D``/``d``) are read.
Every function takes the topic name to put in its errors, so a bad message can be found.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..depth.rvl import rvl_decode, rvl_encode
from ..errors import DecodeError, InputError
from ..geometry.camera import CameraIntrinsics
from .bagindex import stamp_value
from .clouds import CloudLayout, cloud_layout, cloud_points, cloud_to_rgbd, fit_intrinsics

__all__ = [
    "COLOR_ENCODINGS",
    "DEPTH_ENCODINGS",
    "CloudLayout",
    "camera_info",
    "cloud_layout",
    "cloud_points",
    "cloud_to_rgbd",
    "compressed_depth_encode",
    "compressed_kind",
    "compressed_size",
    "decode_compressed",
    "decode_image",
    "fit_intrinsics",
    "image_kind",
    "stamp_ns",
    "video_packet",
]

DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
COLOR_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8", "mono8")
#: image_transport's compressedDepth header: int32 format, then two float32 depth parameters.
_CDEPTH_HEADER = 12
_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def stamp_ns(msg: Any, topic: str, *, ros1: bool) -> int:
    """The header stamp of ``msg`` in nanoseconds (``timestamp`` for Foxglove messages).

    ROS 1 seconds are unsigned: rosbags gives them as int32, so a stamp at or after 2**31 s
    comes back negative and is turned back here, as the raw readers of
    :mod:`~pcdcodec.ros.bagindex` read it. Raises :class:`~pcdcodec.DecodeError` for a
    damaged stamp (see :func:`~pcdcodec.ros.bagindex.stamp_value`).
    """
    s = msg.header.stamp if hasattr(msg, "header") else msg.timestamp
    sec, nsec = int(s.sec), int(s.nanosec)
    if ros1 and sec < 0:
        sec += 1 << 32
    return stamp_value(sec, nsec, f"topic {topic!r}")


def image_kind(encoding: str) -> str | None:
    """``"depth"``, ``"color"`` or ``None`` for a ``sensor_msgs/Image`` encoding."""
    if encoding in DEPTH_ENCODINGS:
        return "depth"
    if encoding in COLOR_ENCODINGS:
        return "color"
    return None


def compressed_kind(fmt: str) -> str | None:
    """``"depth"`` or ``"color"`` for a ``sensor_msgs/CompressedImage`` format string."""
    head = fmt.split(";")[0].strip()
    if "compresseddepth" in fmt.lower() or head in DEPTH_ENCODINGS:
        return "depth"
    low = fmt.lower()
    if "jpeg" in low or "jpg" in low or "png" in low or head in COLOR_ENCODINGS:
        return "color"
    return None


def _rows(msg: Any, bpp: int, topic: str) -> npt.NDArray[np.uint8]:
    """The pixel bytes of an Image as height × (width·bpp), without the row padding."""
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = (
        np.frombuffer(msg.data, dtype=np.uint8)
        if not isinstance(msg.data, np.ndarray)
        else msg.data
    )
    if h < 1 or w < 1:
        raise InputError(f"topic {topic!r}: image is {w}x{h}, expected a non-empty image")
    if step < w * bpp:
        raise InputError(
            f"topic {topic!r}: row step {step} is shorter than width {w} x {bpp} bytes "
            f"({msg.encoding!r})"
        )
    if data.size < step * h:
        raise DecodeError(
            f"topic {topic!r}: image data is {data.size} bytes, expected step {step} x height "
            f"{h} = {step * h}"
        )
    return data[: step * h].reshape(h, step)[:, : w * bpp]


def decode_image(
    msg: Any, role: str, topic: str, shape: tuple[int, int] | None = None
) -> npt.NDArray[Any]:
    """A ``sensor_msgs/Image`` as depth (H×W uint16 or float32 metres) or color (H×W×3 RGB).

    ``role`` is ``"depth"`` or ``"color"``; an encoding that does not fit the role raises
    :class:`~pcdcodec.InputError` naming the topic and the encoding. ``shape`` (height, width),
    when given, is the size the image must declare; the declared size is checked against it
    and against the data's length before anything is allocated.
    """
    if shape is not None and (int(msg.height), int(msg.width)) != tuple(shape):
        raise InputError(
            f"{role} topic {topic!r}: image is {int(msg.width)}x{int(msg.height)}, expected "
            f"{shape[1]}x{shape[0]} (the camera's size)"
        )
    enc = str(msg.encoding)
    big = bool(msg.is_bigendian)
    if role == "depth":
        if enc in ("16UC1", "mono16"):
            rows = _rows(msg, 2, topic)
            return np.ascontiguousarray(rows).view(">u2" if big else "<u2").astype(np.uint16)
        if enc == "32FC1":
            rows = _rows(msg, 4, topic)
            return np.ascontiguousarray(rows).view(">f4" if big else "<f4").astype(np.float32)
        raise InputError(
            f"depth topic {topic!r} has encoding {enc!r}; expected one of "
            f"{', '.join(DEPTH_ENCODINGS)}"
        )
    if enc in ("rgb8", "bgr8"):
        px = _rows(msg, 3, topic).reshape(int(msg.height), int(msg.width), 3)
        return np.ascontiguousarray(px if enc == "rgb8" else px[..., ::-1])
    if enc in ("rgba8", "bgra8"):
        px = _rows(msg, 4, topic).reshape(int(msg.height), int(msg.width), 4)
        return np.ascontiguousarray(px[..., :3] if enc == "rgba8" else px[..., 2::-1])
    if enc == "mono8":
        px = _rows(msg, 1, topic)
        return np.repeat(px[..., None], 3, axis=2)
    raise InputError(
        f"color topic {topic!r} has encoding {enc!r}; expected one of {', '.join(COLOR_ENCODINGS)}"
    )


#: The largest image a bag may declare when no camera fixes its size: a side, and in all.
MAX_IMAGE_SIDE = 16384
MAX_IMAGE_PIXELS = 1 << 26  # 64 megapixels: 128 MiB as 16-bit depth, 192 MiB as RGB


def _check_size(width: int, height: int, where: str, shape: tuple[int, int] | None) -> None:
    """Refuse a declared image size other than ``shape`` (height, width), or, without one,
    beyond :data:`MAX_IMAGE_SIDE` / :data:`MAX_IMAGE_PIXELS`; before anything is decoded."""
    if shape is not None:
        if (height, width) != tuple(shape):
            raise InputError(
                f"{where}: the image declares {width}x{height} pixels, expected "
                f"{shape[1]}x{shape[0]} (the camera's size)"
            )
        return
    if width > MAX_IMAGE_SIDE or height > MAX_IMAGE_SIDE or width * height > MAX_IMAGE_PIXELS:
        raise DecodeError(
            f"{where}: the image declares {width}x{height} pixels, more than the "
            f"{MAX_IMAGE_SIDE} a side or {MAX_IMAGE_PIXELS} in all read without a camera info "
            "giving its size"
        )


def _imread(data: bytes, where: str, header: Any) -> npt.NDArray[Any]:
    import imagecodecs

    try:
        img = np.asarray(imagecodecs.imread(data))
    except Exception as exc:
        raise DecodeError(f"{where}: cannot decode the compressed image: {exc}") from exc
    if img.shape[:2] != (header.height, header.width):
        raise DecodeError(
            f"{where}: the {header.format.upper()} image decodes to {img.shape[1]}x{img.shape[0]} "
            f"pixels but declares {header.width}x{header.height}"
        )
    return img


@dataclass(frozen=True)
class _Compressed:
    """A CompressedImage taken apart: what it holds and the size it declares."""

    kind: str  # "image" (JPEG/PNG, color or 16-bit depth PNG), "cdepth-png" or "cdepth-rvl"
    body: bytes  # the JPEG/PNG, or the RVL words after the size
    width: int
    height: int
    header: Any  # the ImageHeader of a JPEG/PNG, else None
    float_depth: bool  # compressedDepth of 32FC1 (quantized inverse depth)
    quant: tuple[float, float]


def _take_apart(msg: Any, role: str, topic: str) -> _Compressed:
    """Check a CompressedImage's format and structure and read its declared size, decoding
    nothing (see :func:`decode_compressed`)."""
    from ..color.images import image_header

    fmt = str(msg.format)
    data = bytes(msg.data) if not isinstance(msg.data, bytes) else msg.data
    head = fmt.split(";")[0].strip() if ";" in fmt else ""
    where = f"{role} topic {topic!r}"
    if role == "color":
        if head and head not in COLOR_ENCODINGS:
            raise InputError(
                f"color topic {topic!r} has format {fmt!r}; expected an original encoding of "
                f"{', '.join(COLOR_ENCODINGS)}"
            )
        h = image_header(data, where)
        if h.bits != 8:
            raise InputError(f"color topic {topic!r}: image has {h.bits}-bit samples, expected 8")
        return _Compressed("image", data, h.width, h.height, h, False, (0.0, 0.0))
    if "compresseddepth" not in fmt.lower():
        if head not in ("16UC1", "mono16"):
            raise InputError(
                f"depth topic {topic!r} has format {fmt!r}; expected '16UC1; png compressed' or "
                "a compressedDepth format"
            )
        h = image_header(data, where)
        if h.format != "png" or h.bits != 16 or h.channels != 1:
            raise DecodeError(
                f"depth topic {topic!r}: image is a {h.bits}-bit {h.format.upper()} with "
                f"{h.channels} channels, expected a 16-bit one-channel PNG"
            )
        return _Compressed("image", data, h.width, h.height, h, False, (0.0, 0.0))
    if head not in ("16UC1", "mono16", "32FC1"):
        raise InputError(
            f"depth topic {topic!r} has format {fmt!r}; compressedDepth holds 16UC1 or 32FC1"
        )
    if len(data) < _CDEPTH_HEADER:
        raise DecodeError(
            f"depth topic {topic!r}: compressedDepth message is {len(data)} bytes, shorter than "
            f"its {_CDEPTH_HEADER}-byte header"
        )
    quant = struct.unpack_from("<ff", data, 4)
    body = data[_CDEPTH_HEADER:]
    tail = fmt.split(";", 1)[1].lower() if ";" in fmt else fmt.lower()
    if "rvl" in tail:
        if len(body) < 8:
            raise DecodeError(f"depth topic {topic!r}: RVL body is {len(body)} bytes, too short")
        cols, rows = struct.unpack_from("<II", body, 0)
        if not (0 < cols <= MAX_IMAGE_SIDE and 0 < rows <= MAX_IMAGE_SIDE):
            raise DecodeError(
                f"depth topic {topic!r}: RVL image size {cols}x{rows} at byte offset "
                f"{_CDEPTH_HEADER} is not plausible"
            )
        # ROS pads nothing after the words; a stream cut inside a word is corrupt.
        words = body[8 : 8 + (len(body) - 8) // 4 * 4]
        return _Compressed("cdepth-rvl", words, cols, rows, None, head == "32FC1", quant)
    if not body.startswith(_PNG_MAGIC):
        raise DecodeError(
            f"depth topic {topic!r}: no PNG after the compressedDepth header at byte offset "
            f"{_CDEPTH_HEADER} (found {body[:8]!r})"
        )
    h = image_header(body, where)
    if h.bits != 16 or h.channels != 1:
        raise DecodeError(
            f"depth topic {topic!r}: compressedDepth PNG is {h.bits}-bit with {h.channels} "
            "channels, expected 16-bit with one"
        )
    return _Compressed("cdepth-png", body, h.width, h.height, h, head == "32FC1", quant)


def compressed_size(msg: Any, role: str, topic: str) -> tuple[int, int]:
    """``(width, height)`` a CompressedImage declares, read from its header without decoding
    it; raises as :func:`decode_compressed` does for a bad format or a cut or damaged image."""
    c = _take_apart(msg, role, topic)
    _check_size(c.width, c.height, f"{role} topic {topic!r}", None)
    return c.width, c.height


def decode_compressed(
    msg: Any, role: str, topic: str, shape: tuple[int, int] | None = None
) -> npt.NDArray[Any]:
    """A ``sensor_msgs/CompressedImage`` as depth or color (see :func:`decode_image`).

    Color: JPEG or PNG. Depth: a 16-bit PNG (``"16UC1; png compressed"``) or image_transport's
    ``compressedDepth`` (PNG or RVL after its 12-byte header; the header's depth parameters
    are only used for 32FC1, which compressedDepth stores as quantized inverse depth).

    Before decoding, the image's whole structure is checked (a JPEG or PNG cut short or
    damaged, see :mod:`pcdcodec.color.images`) and its declared size compared with
    ``shape`` (height, width: the camera's), or without one bounded by
    :data:`MAX_IMAGE_SIDE` and :data:`MAX_IMAGE_PIXELS`, so a few bytes declaring a huge
    image allocate nothing. Raises :class:`~pcdcodec.DecodeError` (damaged, cut, wrong size)
    or :class:`~pcdcodec.InputError` (a format pcdcodec does not read), naming the topic.
    """
    c = _take_apart(msg, role, topic)
    where = f"{role} topic {topic!r}"
    _check_size(c.width, c.height, where, shape)
    if c.kind == "image":
        img = _imread(c.body, where, c.header)
        if role == "depth":
            return img.astype(np.uint16, copy=False)
        if img.dtype != np.uint8:
            raise InputError(f"color topic {topic!r}: image is {img.dtype}, expected 8-bit")
        if img.ndim == 2:
            return np.repeat(img[..., None], 3, axis=2)
        if img.shape[2] < 3:  # gray with alpha
            return np.repeat(img[..., :1], 3, axis=2)
        return np.ascontiguousarray(img[..., :3])
    if c.kind == "cdepth-rvl":
        try:
            image = rvl_decode(memoryview(c.body), c.width * c.height).reshape(c.height, c.width)
        except DecodeError as exc:
            raise DecodeError(f"{where}: {exc}") from None
    else:
        image = _imread(c.body, where, c.header)
        if image.dtype != np.uint16 or image.ndim != 2:
            raise DecodeError(
                f"depth topic {topic!r}: compressedDepth PNG is {image.dtype} {image.shape}"
            )
    if not c.float_depth:
        return image.astype(np.uint16, copy=False)
    quant_a, quant_b = c.quant
    out = np.full(image.shape, np.nan, np.float32)
    valid = image != 0
    out[valid] = np.float32(quant_a) / (image[valid].astype(np.float32) - np.float32(quant_b))
    return out


def video_packet(msg: Any, topic: str) -> tuple[str, bytes, bool]:
    """(video format, bitstream, keyframe) of a ``foxglove_msgs/CompressedVideo`` or an
    ffmpeg_image_transport ``FFMPEGPacket``; H.264 and H.265 in Annex B are recorded as they
    are."""
    data = bytes(msg.data) if not isinstance(msg.data, bytes) else msg.data
    if hasattr(msg, "format"):
        fmt = str(msg.format).lower()
        key = None
    else:  # FFMPEGPacket: the encoder's name, and flags bit 0 for keyframes
        enc = str(msg.encoding).lower()
        fmt = "h265" if ("hevc" in enc or "265" in enc) else "h264" if "264" in enc else enc
        key = bool(int(msg.flags) & 1)
    fmt = {"hevc": "h265"}.get(fmt, fmt)
    if fmt not in ("h264", "h265"):
        raise InputError(
            f"video topic {topic!r} holds {fmt!r}; pass-through records h264 and h265 packets"
        )
    if key is None:
        key = _annexb_keyframe(data, fmt)
    return fmt, data, key


def _annexb_keyframe(data: bytes, fmt: str) -> bool:
    """Whether an Annex B access unit starts a decodable sequence (IDR/IRAP with parameter sets
    or an IDR alone)."""
    i = data.find(b"\x00\x00\x01")
    while i != -1 and i + 3 < len(data):
        head = data[i + 3]
        if fmt == "h264":
            if head & 0x1F in (5, 7):
                return True
        elif 16 <= (head >> 1) & 0x3F <= 21 or (head >> 1) & 0x3F in (32, 33):
            return True
        i = data.find(b"\x00\x00\x01", i + 3)
    return False


def compressed_depth_encode(depth: npt.NDArray[np.uint16], *, rvl: bool = False) -> bytes:
    """16UC1 depth as image_transport's compressedDepth payload (PNG, or RVL when ``rvl``).

    The header's format field is 1 (PNG) or 2 (RVL) and its depth parameters zero: they mean
    nothing for 16-bit depth.
    """
    if rvl:
        h, w = depth.shape
        return (
            struct.pack("<iff", 2, 0.0, 0.0)
            + struct.pack("<II", w, h)
            + rvl_encode(np.ascontiguousarray(depth).reshape(-1))
        )
    import imagecodecs

    png = imagecodecs.png_encode(np.ascontiguousarray(depth), level=1)
    return struct.pack("<iff", 1, 0.0, 0.0) + bytes(png)


def camera_info(msg: Any, topic: str) -> tuple[Any, str, list[float]]:
    """Intrinsics, distortion model and distortion coefficients of a ``CameraInfo``.

    Reads ``K``/``k`` and ``D``/``d``; the distortion is returned, not applied.
    """
    k = getattr(msg, "k", None)
    if k is None:
        k = getattr(msg, "K", None)
    d = getattr(msg, "d", None)
    if d is None:
        d = getattr(msg, "D", None)
    try:
        kk = np.asarray(k, dtype=np.float64).reshape(3, 3)
        intr = CameraIntrinsics(
            int(msg.width), int(msg.height), kk[0, 0], kk[1, 1], kk[0, 2], kk[1, 2]
        )
    except (ValueError, TypeError, InputError) as exc:
        raise InputError(
            f"camera info topic {topic!r} has no usable camera (width {msg.width}, height "
            f"{msg.height}, K {list(np.asarray(k).ravel()) if k is not None else None}): {exc}"
        ) from None
    dist = [float(v) for v in np.asarray(d if d is not None else [], dtype=np.float64).ravel()]
    return intr, str(msg.distortion_model), dist
