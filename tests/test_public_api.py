"""The public API: what ``import pcdcodec`` offers, pinned so that a change to it is deliberate."""

from __future__ import annotations

import subprocess
import sys

import pytest

import pcdcodec

PUBLIC = [
    "ArchiveLockedError",
    "CameraIntrinsics",
    "CameraSpec",
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
    "FrameSet",
    "InputError",
    "InputTypeError",
    "KINDS",
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


def test_the_public_names_are_these() -> None:
    assert sorted(pcdcodec.__all__) == PUBLIC


def test_every_public_name_imports_from_the_package() -> None:
    for name in PUBLIC:
        assert getattr(pcdcodec, name) is not None, name
    assert set(PUBLIC) <= set(dir(pcdcodec))  # lazily loaded names too


def _run(code: str) -> str:
    return subprocess.run(
        [sys.executable, "-W", "error::DeprecationWarning", "-c", code],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()


def test_star_import_gives_every_public_name() -> None:
    names = _run("from pcdcodec import *\nimport pcdcodec\nprint(sorted(pcdcodec.__all__))")
    assert names == str(PUBLIC)
    # lazily loaded names resolve to their home modules
    assert pcdcodec.evaluate.__module__ == "pcdcodec.bench.evaluation"
    assert pcdcodec.export_bag.__module__ == "pcdcodec.convert.rosbag"


#: The most pcdcodec modules `import pcdcodec` may load (it loaded 35 before the rooms).
MAX_MODULES_AT_IMPORT = 35


def test_import_pcdcodec_stays_light() -> None:
    out = _run(
        "import sys, pcdcodec\n"
        "print(len([m for m in sys.modules if m == 'pcdcodec' or m.startswith('pcdcodec.')]))\n"
        "print(','.join(m for m in ('open3d', 'av', 'cv2', 'pcdcodec.bench', 'pcdcodec.cli',"
        " 'pcdcodec.archive', 'pcdcodec.convert') if m in sys.modules))"
    )
    count, heavy = out.splitlines() if "\n" in out else (out, "")
    assert int(count) <= MAX_MODULES_AT_IMPORT
    assert heavy == ""


@pytest.mark.parametrize(("old", "new"), sorted(pcdcodec.MOVED_MODULES.items()))
def test_old_module_paths_still_import_with_a_warning(old: str, new: str) -> None:
    code = (
        "import importlib, warnings\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        f"    old = importlib.import_module({old!r})\n"
        f"new = importlib.import_module({new!r})\n"
        "assert old is new\n"
        # the module keeps its own spec, so its relative imports resolve in its real package
        f"assert new.__spec__.name == {new!r}\n"
        "print('|'.join(str(w.message) for w in caught if w.category is DeprecationWarning))\n"
    )
    message = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert old in message
    assert new in message


def test_old_paths_work_in_from_imports() -> None:
    code = (
        "import warnings\n"
        "import pcdcodec\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    from pcdcodec.projector import Projector\n"
        "    from pcdcodec import evaluation\n"
        "    from pcdcodec.recording.paper import export_paper\n"
        "assert Projector is pcdcodec.Projector\n"
        "assert evaluation.evaluate is pcdcodec.evaluate\n"
        "from pcdcodec.convert.paper import export_paper as new\n"
        "assert export_paper is new\n"
        "print(len([w for w in caught if w.category is DeprecationWarning]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "3"


def test_export_bag_from_recording_still_works_with_a_warning() -> None:
    import pcdcodec.recording

    with pytest.warns(DeprecationWarning, match="pcdcodec.convert.rosbag"):
        old = pcdcodec.recording.export_bag
    assert old is pcdcodec.export_bag


def test_attributes_import_pcdcodec_used_to_provide() -> None:
    out = _run(
        "import pcdcodec\n"
        "print(pcdcodec.recording.reader.Recording is pcdcodec.Recording,"
        " pcdcodec.recording.writer.RecordingWriter is pcdcodec.RecordingWriter)"
    )
    assert out == "True True"


def test_given_intrinsics_still_works_with_a_warning() -> None:
    from pcdcodec.sources import base

    with pytest.warns(DeprecationWarning, match="as_intrinsics"):
        camera = base.given_intrinsics({"fx": 5, "fy": 5, "cx": 2, "cy": 2}, 4, 4)
    assert camera == pcdcodec.CameraIntrinsics(4, 4, 5.0, 5.0, 2.0, 2.0)
