"""pcdcodec: small RGB-D point cloud streams, given back as Open3D point clouds.

An RGB-D stream is split into color and depth: color is encoded as video, depth with a lossless
codec, and each point cloud is rebuilt with a pinhole camera model. Codecs are pluggable and
live in one registry that keeps the two kinds apart::

    import pcdcodec

    codec = pcdcodec.get_codec("depthac")         # the default depth codec
    data = codec.encode(depth)                     # uint16 H×W -> bytes
    assert (codec.decode(data) == depth).all()     # bit-exact

Importing pcdcodec does not import open3d, av or cv2; they are imported where they are used.
"""

from __future__ import annotations

from . import metrics
from ._validate import as_uint16_depth
from ._version import __version__
from .camera import CameraIntrinsics
from .codec import KINDS, Codec, ColorCodec
from .color import DEFAULT_COLOR_CODEC
from .datasets import RGBDFrame, RGBDSequence, load_folder, load_sample
from .depth import DEFAULT_DEPTH_CODEC, FrameCodec, decode_depth
from .errors import (
    ArchiveLockedError,
    CodecUnavailableError,
    DecodeError,
    DiskFullError,
    InputError,
    InputTypeError,
    PcdcodecError,
    UnknownCodecError,
    VerificationError,
)
from .evaluation import Evaluation, evaluate
from .frame import Frame
from .projector import Projector, Reprojection
from .recording import (
    EncodeSummary,
    Recording,
    RecordingWriter,
    encode,
    export_bag,
    open,
    recover,
)
from .registry import codec_class, get_codec, list_codecs, register_codec
from .sources import Source, open_source

__all__ = [
    "DEFAULT_COLOR_CODEC",
    "DEFAULT_DEPTH_CODEC",
    "KINDS",
    "ArchiveLockedError",
    "CameraIntrinsics",
    "Codec",
    "CodecUnavailableError",
    "ColorCodec",
    "DecodeError",
    "DiskFullError",
    "EncodeSummary",
    "Evaluation",
    "Frame",
    "FrameCodec",
    "InputError",
    "InputTypeError",
    "PcdcodecError",
    "Projector",
    "RGBDFrame",
    "RGBDSequence",
    "Recording",
    "RecordingWriter",
    "Reprojection",
    "Source",
    "UnknownCodecError",
    "VerificationError",
    "__version__",
    "as_uint16_depth",
    "codec_class",
    "decode_depth",
    "encode",
    "evaluate",
    "export_bag",
    "get_codec",
    "list_codecs",
    "load_folder",
    "load_sample",
    "metrics",
    "open",
    "open_source",
    "recover",
    "register_codec",
]
