"""Color codecs: video, one module per backend.

Stream codecs (:class:`StreamCodec`) turn RGB frames into packets and back; the PyAV backend
provides them. File codecs (:class:`FileVideoCodec`) write and read whole video files: the
OpenCV backend, the path of the original method. Adding a codec means adding a class and one
registration line below.

``base.py`` holds both interfaces; ``pyav.py`` the PyAV codecs (their parameters and options),
``ffmpeg.py`` the encoder and decoder they run on, loaded when a stream starts; ``opencv.py``
the OpenCV backend.
"""

from __future__ import annotations

from ..registry import register_codec
from .base import (
    DecodedFrame,
    FileVideoCodec,
    Packet,
    StreamCodec,
    VideoDecoder,
    VideoEncoder,
    VideoFileReader,
    VideoFileWriter,
    decode_packets,
    encode_frames,
)
from .opencv import OpenCVVideo
from .pyav import (
    AV1,
    FFV1,
    H264,
    H264NVENC,
    H265,
    HEVCNVENC,
    MJPEG,
    MPEG4,
    VP9,
    FFVHuff,
    H264Lossless,
    HuffYUV,
    PyAVCodec,
)

__all__ = [
    "AV1",
    "DEFAULT_COLOR_CODEC",
    "FFV1",
    "H264",
    "H264NVENC",
    "H265",
    "HEVCNVENC",
    "MJPEG",
    "MPEG4",
    "VP9",
    "DecodedFrame",
    "FFVHuff",
    "FileVideoCodec",
    "H264Lossless",
    "HuffYUV",
    "OpenCVVideo",
    "Packet",
    "PyAVCodec",
    "StreamCodec",
    "VideoDecoder",
    "VideoEncoder",
    "VideoFileReader",
    "VideoFileWriter",
    "decode_packets",
    "encode_frames",
]

#: The color codec used when none is named.
DEFAULT_COLOR_CODEC = "h264"

for _cls in (
    H264,
    H265,
    AV1,
    VP9,
    MJPEG,
    MPEG4,
    FFV1,
    HuffYUV,
    FFVHuff,
    H264Lossless,
    H264NVENC,
    HEVCNVENC,
    OpenCVVideo,
):
    register_codec(_cls)
