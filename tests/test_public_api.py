"""The public API: what ``import pcdcodec`` offers, pinned so that a change to it is deliberate."""

from __future__ import annotations

import pcdcodec

PUBLIC = [
    "ArchiveLockedError",
    "CameraIntrinsics",
    "Codec",
    "CodecUnavailableError",
    "ColorCodec",
    "DEFAULT_COLOR_CODEC",
    "DEFAULT_DEPTH_CODEC",
    "DecodeError",
    "DiskFullError",
    "EncodeSummary",
    "Evaluation",
    "Frame",
    "FrameCodec",
    "InputError",
    "InputTypeError",
    "KINDS",
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


def test_the_public_names_are_these() -> None:
    assert sorted(pcdcodec.__all__) == PUBLIC


def test_every_public_name_imports_from_the_package() -> None:
    for name in PUBLIC:
        assert getattr(pcdcodec, name) is not None, name
