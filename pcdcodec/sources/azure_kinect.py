"""Azure Kinect ``.mkv`` recordings (``k4arecorder``, pyk4a) as a :class:`Source`.

A k4a recording is a Matroska file, read here with PyAV (no Azure Kinect SDK needed):

* a ``COLOR`` track (MJPEG, or raw NV12 / YUY2 / BGRA), a ``DEPTH`` track of raw 16-bit
  big-endian millimetres (``b16g``), an ``IR`` track and an ``IMU`` track; the captures'
  color and depth share a timestamp;
* tags ``K4A_DEPTH_MODE`` and ``K4A_COLOR_MODE`` on the tracks, ``K4A_DEVICE_SERIAL_NUMBER``
  and ``K4A_START_OFFSET_NS`` on the file;
* a ``calibration.json`` attachment: per camera the unitised Brown-Conrady intrinsics of the
  full sensor (``cx, cy, fx, fy, k1 … k6, codx, cody, p2, p1``, as fractions of the sensor
  size, 0 at the corner of the top-left pixel) and ``Rt``, the transform from the depth camera
  to that camera (rotation row-major, translation in metres).

The intrinsics of a depth mode or color resolution are those of the full sensor binned and
cropped to the mode's image, then moved so that pixel centres are whole numbers: the rule of
the Azure Kinect SDK's mode-specific calibration. The lens model is OpenCV's rational model.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..camera import CameraIntrinsics
from ..errors import DecodeError, InputError
from .base import Source, given_intrinsics, read_magic, register_source

__all__ = ["DEPTH_MODES", "AzureKinectSource", "open_azure_kinect"]

_EBML = b"\x1a\x45\xdf\xa3"
_CLUSTER_ID = b"\x1f\x43\xb6\x75"
_NS = 1_000_000_000

#: Depth mode -> (binned sensor resolution, crop offset, output size), all (x, y) in pixels.
DEPTH_MODES: dict[str, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    "NFOV_2X2BINNED": ((512, 512), (96, 90), (320, 288)),
    "NFOV_UNBINNED": ((1024, 1024), (192, 180), (640, 576)),
    "WFOV_2X2BINNED": ((512, 512), (0, 0), (512, 512)),
    "WFOV_UNBINNED": ((1024, 1024), (0, 0), (1024, 1024)),
    "PASSIVE_IR": ((1024, 1024), (0, 0), (1024, 1024)),
}
#: Color image height -> (sensor resolution scaled to 4:3, crop offset, output size).
COLOR_MODES: dict[int, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    720: ((1280, 960), (0, 120), (1280, 720)),
    1080: ((1920, 1440), (0, 180), (1920, 1080)),
    1440: ((2560, 1920), (0, 240), (2560, 1440)),
    1536: ((2048, 1536), (0, 0), (2048, 1536)),
    2160: ((3840, 2880), (0, 360), (3840, 2160)),
    3072: ((4096, 3072), (0, 0), (4096, 3072)),
}


def _is_azure_kinect(path: Path) -> bool:
    if not path.is_file() or read_magic(path, 4) != _EBML:
        return False
    with path.open("rb") as f:
        head = f.read(1 << 16)
    return b"K4A_" in head


def _has_cluster(path: Path, limit: int = 1 << 24) -> bool:
    """Whether a Matroska Cluster element starts within the first ``limit`` bytes."""
    with path.open("rb") as f:
        return _CLUSTER_ID in f.read(limit)


def _camera(
    cal: dict[str, Any],
    mode: tuple[tuple[int, int], tuple[int, int], tuple[int, int]],
    what: str,
) -> CameraIntrinsics:
    params = cal["Intrinsics"]["ModelParameters"]
    if len(params) < 14:
        raise InputError(f"{what} calibration has {len(params)} model parameters, expected 14")
    (bw, bh), (ox, oy), (w, h) = mode
    cx, cy, fx, fy = (float(v) for v in params[:4])
    k1, k2, k3, k4, k5, k6 = (float(v) for v in params[4:10])
    p2, p1 = float(params[12]), float(params[13])
    return CameraIntrinsics(
        w,
        h,
        fx * bw,
        fy * bh,
        cx * bw - ox - 0.5,
        cy * bh - oy - 0.5,
        "rational_polynomial",
        (k1, k2, p1, p2, k3, k4, k5, k6),
    )


def _rt(cal: dict[str, Any]) -> npt.NDArray[np.float64]:
    m = np.eye(4)
    m[:3, :3] = np.reshape(np.asarray(cal["Rt"]["Rotation"], dtype=np.float64), (3, 3))
    m[:3, 3] = np.asarray(cal["Rt"]["Translation"], dtype=np.float64)
    return m


class AzureKinectSource(Source):
    """Frames of an Azure Kinect ``.mkv``: depth in millimetres (depth scale 1000) with the
    depth camera's intrinsics, color with the color camera's, and ``depth_to_color``.

    ``max_frames`` stops early; ``intrinsics`` replaces the calibrated depth camera.
    ``metadata`` holds the serial number, the depth and color modes and the firmware versions.
    Raises :class:`~pcdcodec.InputError` for a file without a depth track, without the
    ``calibration.json`` attachment, with an unknown depth mode or color resolution, or without
    clusters (no captures).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        max_frames: int | None = None,
        intrinsics: CameraIntrinsics | None = None,
    ) -> None:
        import av

        self.path = Path(path)
        self.max_frames = max_frames
        name = str(self.path)
        try:
            container = av.open(name)
        except (av.error.FFmpegError, OSError) as exc:
            if _is_azure_kinect(self.path) and not _has_cluster(self.path):
                raise InputError(
                    f"{name!r} holds no clusters (no recorded captures): the recording stopped "
                    "before its first capture, or the file was cut short"
                ) from exc
            raise InputError(f"{name!r} is not a readable Matroska file: {exc}") from exc
        try:
            self._read_header(container, name)
        finally:
            container.close()
        if intrinsics is not None:
            own = self.intrinsics  # a bare matrix takes the recorded depth camera's size
            size = (own.width, own.height) if own is not None else (None, None)
            self.intrinsics = given_intrinsics(intrinsics, *size)

    def _read_header(self, container: Any, name: str) -> None:
        tags = dict(container.metadata)
        depth = color = None
        attachment = None
        for s in container.streams:
            meta = dict(s.metadata)
            if s.type == "video" and ("K4A_DEPTH_MODE" in meta or meta.get("title") == "DEPTH"):
                depth = s
            elif s.type == "video" and ("K4A_COLOR_MODE" in meta or meta.get("title") == "COLOR"):
                color = s
            elif s.type == "attachment" and meta.get("filename") == "calibration.json":
                attachment = s
        if depth is None:
            raise InputError(f"{name!r} has no Azure Kinect DEPTH track")
        if attachment is None:
            raise InputError(
                f"{name!r} has no calibration.json attachment: the cameras' intrinsics and "
                "extrinsics cannot be known"
            )
        try:
            calibration = json.loads(bytes(attachment.data))
            cameras = calibration["CalibrationInformation"]["Cameras"]
            by_purpose = {c["Purpose"]: c for c in cameras}
            depth_cal = by_purpose["CALIBRATION_CameraPurposeDepth"]
        except (ValueError, KeyError, TypeError) as exc:
            raise InputError(
                f"{name!r}: calibration.json is not a k4a calibration: {exc}"
            ) from None
        depth_mode = str(dict(depth.metadata).get("K4A_DEPTH_MODE", ""))
        if depth_mode not in DEPTH_MODES:
            raise InputError(
                f"{name!r} has depth mode {depth_mode!r}; expected one of {list(DEPTH_MODES)}"
            )
        mode = DEPTH_MODES[depth_mode]
        if (depth.codec_context.width, depth.codec_context.height) != mode[2]:
            raise InputError(
                f"{name!r}: depth mode {depth_mode} is {mode[2][0]}x{mode[2][1]}, but its track "
                f"is {depth.codec_context.width}x{depth.codec_context.height}"
            )
        self.intrinsics: CameraIntrinsics | None = _camera(depth_cal, mode, "depth camera")
        self.depth_scale = 1000.0
        self._depth_index = depth.index
        self._color_index: int | None = None
        self.metadata = {
            "source": "azure_kinect",
            "device": "Azure Kinect",
            "depth_mode": depth_mode,
        }
        for key, label in (
            ("K4A_DEVICE_SERIAL_NUMBER", "serial"),
            ("K4A_DEPTH_FIRMWARE_VERSION", "depth_firmware"),
            ("K4A_COLOR_FIRMWARE_VERSION", "color_firmware"),
        ):
            if key in tags:
                self.metadata[label] = str(tags[key])
        self._start_ns = int(tags.get("K4A_START_OFFSET_NS", 0) or 0)
        if color is not None:
            color_cal = by_purpose.get("CALIBRATION_CameraPurposePhotoVideo")
            if color_cal is None:
                raise InputError(f"{name!r}: calibration.json has no color camera")
            if color_cal["SensorWidth"] * 3 != color_cal["SensorHeight"] * 4:
                raise InputError(
                    f"{name!r}: color calibration of a {color_cal['SensorWidth']}x"
                    f"{color_cal['SensorHeight']} sensor; only 4:3 calibrations are supported"
                )
            h = int(color.codec_context.height)
            if h not in COLOR_MODES or COLOR_MODES[h][2][0] != color.codec_context.width:
                sizes = ", ".join(f"{m[2][0]}x{m[2][1]}" for m in COLOR_MODES.values())
                raise InputError(
                    f"{name!r}: color track is {color.codec_context.width}x{h}, not an Azure "
                    f"Kinect color resolution ({sizes})"
                )
            self.color_intrinsics = _camera(color_cal, COLOR_MODES[h], "color camera")
            self.depth_to_color = _rt(color_cal) @ np.linalg.inv(_rt(depth_cal))
            self._color_index = color.index
            self.metadata["color_mode"] = str(dict(color.metadata).get("K4A_COLOR_MODE", ""))
        self.has_color = color is not None
        self._count = int(depth.frames or 0)

    def __len__(self) -> int:
        if not self._count:
            raise TypeError("the depth track does not state its frame count")
        return self._count if self.max_frames is None else min(self._count, self.max_frames)

    def __iter__(self) -> Iterator[Any]:
        import av

        from ..datasets import RGBDFrame

        name = str(self.path)
        container = av.open(name)
        try:
            depth_stream = container.streams[self._depth_index]
            streams = [depth_stream]
            color_stream = None
            if self._color_index is not None:
                color_stream = container.streams[self._color_index]
                streams.append(color_stream)
            h, w = self.intrinsics.shape if self.intrinsics else (0, 0)
            depths: dict[int, npt.NDArray[np.uint16]] = {}
            colors: dict[int, npt.NDArray[np.uint8]] = {}
            emitted = 0
            seen = 0
            tb = depth_stream.time_base
            tb_ns = float(tb * _NS) if tb is not None else 1000.0
            for packet in container.demux(streams):
                if packet.size == 0 or packet.pts is None:
                    continue
                seen += 1
                pts = int(packet.pts)
                if packet.stream.index == self._depth_index:
                    raw = bytes(packet)
                    if len(raw) != 2 * w * h:
                        raise DecodeError(
                            f"{name!r}: depth packet at pts {pts} holds {len(raw)} bytes, "
                            f"expected {2 * w * h} for {w}x{h} 16-bit depth"
                        )
                    depths[pts] = np.frombuffer(raw, dtype=">u2").reshape(h, w).astype(np.uint16)
                else:
                    assert color_stream is not None
                    try:
                        frames: list[Any] = list(packet.decode())
                    except av.error.FFmpegError as exc:
                        raise DecodeError(
                            f"{name!r}: color packet at pts {pts} does not decode: {exc}"
                        ) from exc
                    for f in frames:
                        colors[pts] = np.asarray(f.to_ndarray(format="rgb24"), dtype=np.uint8)
                for t in sorted(set(depths) & set(colors)) if color_stream else sorted(depths):
                    ns = self._start_ns + round(t * tb_ns)
                    yield RGBDFrame(colors.pop(t) if color_stream else None, depths.pop(t), ns)
                    emitted += 1
                    if self.max_frames is not None and emitted >= self.max_frames:
                        return
                # A capture whose partner never came: keep only the newest few waiting.
                for pending in (depths, colors):
                    for old in sorted(pending)[:-4]:
                        del pending[old]
            if seen == 0:
                raise InputError(
                    f"{name!r} holds no captures (no clusters with color or depth data)"
                )
        finally:
            container.close()


def open_azure_kinect(path: str | Path, **options: Any) -> AzureKinectSource:
    """Open an Azure Kinect ``.mkv`` (see :class:`AzureKinectSource` for the options)."""
    return AzureKinectSource(path, **options)


register_source(
    "azure_kinect",
    _is_azure_kinect,
    open_azure_kinect,
    "an Azure Kinect .mkv from k4arecorder (Matroska with K4A tags)",
)
