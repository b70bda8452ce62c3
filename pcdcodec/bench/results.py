"""What an evaluation measures: one row per depth codec, color codec, stream and color
rate-distortion point, the settings the rate-distortion sweep runs through, and how a codec
configuration is named in tables and plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..registry import codec_class

__all__ = [
    "COMPARED_COLOR_CODECS",
    "POINTCLOUD2_BYTES_PER_POINT",
    "RD_SETTINGS",
    "ColorRow",
    "DepthRow",
    "RDPoint",
    "StreamRow",
    "config_label",
    "rd_setting",
]

#: Bytes per point of a PointCloud2 with float32 x, y, z, packed RGB and padding, as ROS
#: publishes RGB-D clouds (organized: one point per pixel).
POINTCLOUD2_BYTES_PER_POINT = 32

#: The color codecs compared when none are named: the lossy video codecs people choose
#: between (those of them that are available).
COMPARED_COLOR_CODECS = ("h264", "h265", "av1")

#: Quality settings swept for the color rate-distortion curves (each codec's default setting,
#: and the setting of the codec measured, are added to its sweep).
RD_SETTINGS: dict[str, tuple[str, tuple[int, ...]]] = {
    "h264": ("crf", (14, 18, 23, 28, 33)),
    "h265": ("crf", (16, 22, 28, 34)),
    "av1": ("crf", (20, 30, 40, 50)),
    "vp9": ("crf", (20, 32, 44, 56)),
    "mjpeg": ("quality", (2, 4, 8, 16)),
    "mpeg4": ("qscale", (2, 4, 8, 16)),
}


@dataclass(frozen=True)
class DepthRow:
    """One depth codec on the sequence. Sizes in bytes, times in ms per frame."""

    codec: str
    config: dict[str, Any]
    frames: int
    bytes_per_frame: float
    ratio_uint16: float
    ratio_float32: float
    ratio_float32_input: float | None
    encode_ms: float
    decode_ms: float
    exact: bool
    exact_fraction: float
    rmse_m: float
    max_error_m: float
    edge_rmse_m: float
    interior_rmse_m: float
    cloud_rmse_m: float


@dataclass(frozen=True)
class ColorRow:
    """One color codec on the sequence."""

    codec: str
    config: dict[str, Any]
    frames: int
    bytes_per_frame: float
    bits_per_pixel: float
    ratio_rgb24: float
    encode_ms: float
    decode_ms: float
    psnr: float
    ssim: float
    lossless: bool


@dataclass(frozen=True)
class StreamRow:
    """A color and a depth codec together: the whole stream."""

    color: str
    depth: str
    bytes_per_frame: float
    ratio_raw: float
    ratio_pointcloud2: float
    lossless: bool


@dataclass(frozen=True)
class RDPoint:
    """One point of a color rate-distortion curve."""

    codec: str
    setting: str
    bits_per_pixel: float
    psnr: float


def config_label(config: dict[str, Any]) -> str:
    """``"h264 (crf=28)"``: the codec's name and the settings that differ from its defaults."""
    name = str(config["id"])
    cls = codec_class(name)
    defaults = cls().get_config() if cls.is_available() else {}
    changed = [f"{k}={v}" for k, v in config.items() if k != "id" and defaults.get(k) != v]
    return f"{name} ({', '.join(changed)})" if changed else name


def rd_setting(key: str, value: Any) -> str:
    """``"crf=18"``: a swept setting as RD points name it (18.0 and 18 alike)."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    return f"{key}={value}"


def default_setting(codec: str) -> str | None:
    """``"crf=23"``: the swept setting at the codec's default, as RD points name it."""
    if codec not in RD_SETTINGS:
        return None
    key = RD_SETTINGS[codec][0]
    cls = codec_class(codec)
    return rd_setting(key, cls().get_config().get(key)) if cls.is_available() else None
