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

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import TYPE_CHECKING, Any

from . import metrics
from ._validate import as_uint16_depth
from ._version import __version__
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
    OutputError,
    PcdcodecError,
    UnknownCodecError,
    VerificationError,
)
from .frame import Frame
from .geometry.camera import CameraIntrinsics
from .geometry.projector import Projector, Reprojection
from .recording import EncodeSummary, encode, open, recover
from .registry import codec_class, get_codec, list_codecs, register_codec
from .sources import Source, open_source

if TYPE_CHECKING:
    from .bench.evaluation import Evaluation, evaluate
    from .convert.rosbag import export_bag
    from .recording import (
        CameraSpec,
        FrameSet,
        Recording,
        RecordingWriter,
        RigRecording,
        RigSummary,
        RigWriter,
        encode_rig,
    )

#: Public names whose modules load on first use, so that ``import pcdcodec`` stays light.
_LAZY = {
    "Evaluation": "pcdcodec.bench.evaluation",
    "evaluate": "pcdcodec.bench.evaluation",
    "export_bag": "pcdcodec.convert.rosbag",
    "Recording": "pcdcodec.recording.reader",
    "RecordingWriter": "pcdcodec.recording.writer",
    "CameraSpec": "pcdcodec.recording.rig",
    "RigWriter": "pcdcodec.recording.rig",
    "RigRecording": "pcdcodec.recording.rig_reader",
    "FrameSet": "pcdcodec.recording.framesets",
    "RigSummary": "pcdcodec.recording.encode_rig",
    "encode_rig": "pcdcodec.recording.encode_rig",
}

#: Module paths of earlier releases, and where their contents live now. Importing an old path
#: still works, with a DeprecationWarning naming the new one; the old paths go in 0.3.
MOVED_MODULES = {
    "pcdcodec.camera": "pcdcodec.geometry.camera",
    "pcdcodec.transform": "pcdcodec.geometry.transform",
    "pcdcodec.projector": "pcdcodec.geometry.projector",
    "pcdcodec.evaluation": "pcdcodec.bench.evaluation",
    "pcdcodec.peers": "pcdcodec.bench.peers",
    "pcdcodec.recording.rosbag_export": "pcdcodec.convert.rosbag",
    "pcdcodec.recording.paper": "pcdcodec.convert.paper",
}


def _moved_module(old: str) -> ModuleType:
    new = MOVED_MODULES[old]
    warnings.warn(
        f"{old} has moved to {new}; import it from there ({old} goes in a later release)",
        DeprecationWarning,
        stacklevel=3,
    )
    return importlib.import_module(new)


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Answers imports of :data:`MOVED_MODULES` with the module at its new path."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if fullname not in MOVED_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def __init__(self) -> None:
        self._specs: dict[int, Any] = {}

    def create_module(self, spec: ModuleSpec) -> ModuleType:
        module = _moved_module(spec.name)
        # The import system sets the old path's spec on the module it is handed; the module
        # keeps its own, so that its relative imports resolve against its real package.
        self._specs[id(module)] = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        """The module was imported at its new path; only its own spec is put back."""
        module.__spec__ = self._specs.pop(id(module), module.__spec__)


if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
    sys.meta_path.insert(0, _MovedModuleFinder())


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    if f"pcdcodec.{name}" in MOVED_MODULES:
        return importlib.import_module(f"pcdcodec.{name}")
    raise AttributeError(f"module 'pcdcodec' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "DEFAULT_COLOR_CODEC",
    "DEFAULT_DEPTH_CODEC",
    "KINDS",
    "ArchiveLockedError",
    "CameraIntrinsics",
    "CameraSpec",
    "Codec",
    "CodecUnavailableError",
    "ColorCodec",
    "DecodeError",
    "DiskFullError",
    "EncodeSummary",
    "Evaluation",
    "Frame",
    "FrameCodec",
    "FrameSet",
    "InputError",
    "InputTypeError",
    "OutputError",
    "PcdcodecError",
    "Projector",
    "RGBDFrame",
    "RGBDSequence",
    "Recording",
    "RecordingWriter",
    "Reprojection",
    "RigRecording",
    "RigSummary",
    "RigWriter",
    "Source",
    "UnknownCodecError",
    "VerificationError",
    "__version__",
    "as_uint16_depth",
    "codec_class",
    "decode_depth",
    "encode",
    "encode_rig",
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
