"""The Azure Kinect .mkv reader, on a real k4arecorder file (skipped when it is absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec import InputError
from pcdcodec.sources.azure_kinect import AzureKinectSource

from .conftest import SHARED_DATA

MKV = SHARED_DATA / "bags" / "pyk4a_recording.mkv"
pytestmark = pytest.mark.skipif(not MKV.exists(), reason=f"{MKV} is not present")


def test_reads_depth_color_and_both_cameras() -> None:
    import av

    with pcdcodec.open_source(MKV) as src:
        assert isinstance(src, AzureKinectSource)
        assert src.metadata["serial"] == "001514394512"
        assert src.metadata["depth_mode"] == "NFOV_UNBINNED"
        frames = list(src)
        intr, color = src.intrinsics, src.color_intrinsics
        d2c = src.depth_to_color
    assert intr is not None
    assert color is not None
    # The SDK's mode-specific rule: scale to the binned sensor, crop (192, 180), centre pixels.
    assert intr.shape == (576, 640)
    assert intr.fx == pytest.approx(0.4927808940410614 * 1024)
    assert intr.cx == pytest.approx(0.5129697918891907 * 1024 - 192 - 0.5)
    assert intr.cy == pytest.approx(0.5169235467910767 * 1024 - 180 - 0.5)
    assert intr.distortion_model == "rational_polynomial"
    assert color.shape == (720, 1280)
    assert color.fy == pytest.approx(0.6374239325523376 * 960)
    assert color.cy == pytest.approx(0.5066176056861877 * 960 - 120 - 0.5)
    assert d2c[0, 3] == pytest.approx(-0.032083429396152496)  # metres, depth -> color
    assert len(frames) == 1
    f = frames[0]
    # Depth is the DEPTH track's packet, read as big-endian 16-bit, untouched.
    with av.open(str(MKV)) as c:
        stream = next(s for s in c.streams if s.metadata.get("title") == "DEPTH")
        raw = next(bytes(p) for p in c.demux(stream) if p.size)
    assert np.array_equal(f.depth, np.frombuffer(raw, ">u2").reshape(576, 640))
    assert f.color.shape == (720, 1280, 3)
    assert (f.depth == 0).mean() == pytest.approx(0.235, abs=0.005)
    assert np.median(f.depth[f.depth > 0]) == pytest.approx(1491, abs=5)
    proj = pcdcodec.Projector(intr, 1000.0, color_intrinsics=color, depth_to_color=d2c)
    points, colors = proj.to_points(f.depth, f.color)
    assert colors is not None
    assert points.shape[0] == int((f.depth > 0).sum())
    assert (colors.sum(axis=1) > 0).mean() > 0.9  # most points fall inside the color image


def _variant(tmp_path: Path, old: bytes, new: bytes) -> Path:
    data = MKV.read_bytes()
    assert data.count(old) >= 1
    out = tmp_path / "variant.mkv"
    out.write_bytes(data.replace(old, new))
    return out


def test_unknown_depth_mode(tmp_path: Path) -> None:
    path = _variant(tmp_path, b"NFOV_UNBINNED", b"NFOV_SUPERXXX")
    with pytest.raises(InputError, match="depth mode 'NFOV_SUPERXXX'; expected one of"):
        pcdcodec.open_source(path)


def test_missing_calibration(tmp_path: Path) -> None:
    path = _variant(tmp_path, b"calibration.json", b"calibratiox.json")
    with pytest.raises(InputError, match=r"no calibration\.json attachment"):
        pcdcodec.open_source(path)


def test_no_clusters(tmp_path: Path) -> None:
    data = MKV.read_bytes()
    path = tmp_path / "cut.mkv"
    path.write_bytes(data[: data.find(b"\x1f\x43\xb6\x75")])
    with pytest.raises(InputError, match="holds no clusters"):
        pcdcodec.open_source(path)


def test_cli_encodes_a_camera_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from pcdcodec.cli import main

    out = tmp_path / "ak.pcdc"
    assert main(["encode", str(MKV), "-o", str(out), "--color", "ffv1", "-q"]) == 0
    assert "depth scale  1000 units per metre" in capsys.readouterr().out
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format_version"] == 2
    assert info["color_intrinsics"]["width"] == 1280
    assert info["intrinsics"]["distortion_model"] == "rational_polynomial"
    assert info["metadata"]["serial"] == "001514394512"
    with pcdcodec.open(out) as rec, pcdcodec.open_source(MKV) as src:
        (original,) = list(src)
        assert np.array_equal(rec[0].depth, original.depth)
        assert np.array_equal(rec[0].color, original.color)  # ffv1: lossless
