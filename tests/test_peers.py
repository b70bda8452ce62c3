"""Peer-library comparison rows (pcdcodec.bench.peers): Draco through DracoPy, RVL through rvl."""

from __future__ import annotations

import math
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec.bench import peers
from pcdcodec.depth.rvl import RVL

# Measured with rvl 1.0.4 on the bundled sample: after its 4-byte pixel count, the package
# writes exactly the bitstream of pcdcodec's RVL codec.
RVL_BYTE_IDENTICAL = True


@pytest.fixture(scope="module")
def sample() -> pcdcodec.RGBDSequence:
    return pcdcodec.load_sample(max_frames=3)


@pytest.fixture(scope="module")
def projector(sample: pcdcodec.RGBDSequence) -> pcdcodec.Projector:
    assert sample.intrinsics is not None
    return pcdcodec.Projector(sample.intrinsics, sample.depth_scale)


@pytest.fixture(scope="module")
def clouds(
    sample: pcdcodec.RGBDSequence, projector: pcdcodec.Projector
) -> list[np.ndarray[Any, Any]]:
    out = []
    for frame in sample:
        points, _ = projector.to_points(frame.depth, frame.color)
        out.append(points)
    return out


def _bound_m(points: np.ndarray[Any, Any], bits: int) -> float:
    """Largest per-point error of Draco's quantization, computed here independently."""
    step = float(np.ptp(points.astype(np.float64), axis=0).max()) / ((1 << bits) - 1)
    # Half a step per axis, plus a little float32 rounding of coordinates up to ~3 m.
    return math.sqrt(3.0) * (step / 2.0 + 1e-6)


# -- Draco -------------------------------------------------------------------------------


@pytest.mark.parametrize("preserve_order", [False, True], ids=["kdtree", "sequential"])
def test_draco_is_smaller_than_the_raw_cloud_and_within_the_quantization_bound(
    sample: pcdcodec.RGBDSequence,
    projector: pcdcodec.Projector,
    clouds: list[np.ndarray[Any, Any]],
    preserve_order: bool,
) -> None:
    pytest.importorskip("DracoPy")
    result = peers.draco_cloud(
        sample.depths, sample.colors, projector, preserve_order=preserve_order
    )
    raw = np.mean([p.shape[0] * (12 + 3) for p in clouds])
    assert result.name == "draco"
    assert result.kind == "cloud"
    assert result.frames == 3
    assert result.package.startswith("DracoPy ")
    assert result.raw_bytes_per_frame == pytest.approx(raw)
    assert 0 < result.bytes_per_frame < raw
    assert result.ratio == pytest.approx(raw / result.bytes_per_frame)
    assert result.encode_ms > 0
    assert result.decode_ms > 0
    bound = max(_bound_m(p, 14) for p in clouds)
    # Quantization moves points (lossy), but never further than the bound.
    assert 0 < result.max_error_m <= bound
    assert 0 < result.rmse_m <= result.max_error_m
    assert not result.lossless
    assert "uint8 colors exact" in result.notes
    assert result.settings == {
        "quantization_bits": 14,
        "compression_level": 7,
        "preserve_order": preserve_order,
        "colors": True,
    }


def test_draco_quantization_bits_set_the_error(
    sample: pcdcodec.RGBDSequence,
    projector: pcdcodec.Projector,
    clouds: list[np.ndarray[Any, Any]],
) -> None:
    pytest.importorskip("DracoPy")
    fine = peers.draco_cloud(sample.depths[:1], None, projector, preserve_order=True)
    coarse = peers.draco_cloud(
        sample.depths[:1], None, projector, quantization_bits=8, preserve_order=True
    )
    # 8 bits: a step of about extent / 255, some 8 mm on this frame.
    assert _bound_m(clouds[0], 14) < coarse.max_error_m <= _bound_m(clouds[0], 8)
    assert coarse.bytes_per_frame < fine.bytes_per_frame
    assert fine.raw_bytes_per_frame == clouds[0].shape[0] * 12  # no colors
    assert "no colors" in fine.notes


def test_draco_step_and_bound_helpers(clouds: list[np.ndarray[Any, Any]]) -> None:
    points = np.array([[0.0, 0.0, 1.0], [2.0, 0.5, 1.5]])
    assert peers.draco_quantization_step_m(points, 14) == pytest.approx(2.0 / 16383)
    assert peers.draco_quantization_step_m(points, 1) == pytest.approx(2.0)
    # One repeated point: Draco uses an extent of 1.
    assert peers.draco_quantization_step_m(points[:1], 10) == pytest.approx(1.0 / 1023)
    bound = peers.draco_error_bound_m(clouds[0], 14)
    assert _bound_m(clouds[0], 14) == pytest.approx(bound, rel=0.02)
    # The TUM frame is about 2 m across: 14 bits is about a tenth of a millimetre.
    assert 0.05e-3 < bound < 0.2e-3
    with pytest.raises(pcdcodec.InputError, match=r"quantization_bits must be in 1\.\.30"):
        peers.draco_quantization_step_m(points, 31)
    with pytest.raises(pcdcodec.InputError, match=r"shape \(N, 3\)"):
        peers.draco_quantization_step_m(np.zeros((4, 2)), 14)


def test_draco_rejects_bad_arguments(
    sample: pcdcodec.RGBDSequence, projector: pcdcodec.Projector
) -> None:
    pytest.importorskip("DracoPy")
    depths, colors = sample.depths, sample.colors
    with pytest.raises(pcdcodec.InputError, match="depth_frames is empty"):
        peers.draco_cloud([], None, projector)
    with pytest.raises(pcdcodec.InputError, match="color_frames has 2 frames and depth_frames 3"):
        peers.draco_cloud(depths, colors[:2], projector)
    with pytest.raises(pcdcodec.InputError, match="got one array of shape"):
        peers.draco_cloud(depths[0], None, projector)  # type: ignore[arg-type]
    with pytest.raises(pcdcodec.InputTypeError, match=r"projector must be a pcdcodec\.Projector"):
        peers.draco_cloud(depths, colors, "camera")  # type: ignore[arg-type]
    with pytest.raises(pcdcodec.InputError, match=r"quantization_bits must be in 1\.\.30, got 0"):
        peers.draco_cloud(depths, colors, projector, quantization_bits=0)
    with pytest.raises(pcdcodec.InputError, match=r"compression_level must be in 0\.\.10, got 11"):
        peers.draco_cloud(depths, colors, projector, compression_level=11)
    with pytest.raises(pcdcodec.InputTypeError, match="quantization_bits must be an int"):
        peers.draco_cloud(depths, colors, projector, quantization_bits=14.0)  # type: ignore[arg-type]
    empty = np.zeros_like(depths[0])
    with pytest.raises(pcdcodec.InputError, match=r"depth_frames\[1\] has no valid depth"):
        peers.draco_cloud([depths[0], empty], None, projector)


# -- RVL (PyPI package) ------------------------------------------------------------------


def test_rvl_package_round_trips_bit_exact_and_matches_our_bitstream(
    sample: pcdcodec.RGBDSequence,
) -> None:
    pytest.importorskip("rvl")
    result = peers.rvl_package_depth(sample.depths, depth_scale=sample.depth_scale)
    assert result.name == "rvl-pypi"
    assert result.kind == "depth"
    assert result.package.startswith("rvl ")
    assert result.frames == 3
    assert result.lossless
    assert result.max_error_m == 0.0
    assert result.rmse_m == 0.0
    assert result.matches_pcdcodec is RVL_BYTE_IDENTICAL
    assert "byte-identical" in result.notes
    # The package's output is our body plus its 4-byte pixel count, frame by frame.
    ours = [len(RVL()._encode_body(np.ascontiguousarray(d))) + 4 for d in sample.depths]
    assert result.bytes_per_frame == pytest.approx(np.mean(ours))
    assert result.raw_bytes_per_frame == 640 * 480 * 2
    assert result.ratio > 3


def test_rvl_package_reports_a_different_bitstream(
    sample: pcdcodec.RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("rvl")
    real = RVL._encode_body

    def shifted(self: RVL, image: Any) -> bytes:
        body: bytes = real(self, image)
        return body[:-1] + bytes([body[-1] ^ 1])

    monkeypatch.setattr(RVL, "_encode_body", shifted)
    result = peers.rvl_package_depth(sample.depths[:2])
    assert result.matches_pcdcodec is False
    assert "differs from pcdcodec's RVL body on frames [0, 1]" in result.notes
    assert result.lossless  # the package itself still round-trips


def test_rvl_package_reports_a_lossy_round_trip(
    sample: pcdcodec.RGBDSequence, monkeypatch: pytest.MonkeyPatch
) -> None:
    rvl = pytest.importorskip("rvl")
    real = rvl.decompress

    def off_by_three(data: bytes) -> bytes:
        pixels = np.frombuffer(real(data), dtype="<u2").copy()
        pixels[1000] += 3
        out: bytes = pixels.tobytes()
        return out

    monkeypatch.setattr(rvl, "decompress", off_by_three)
    result = peers.rvl_package_depth(sample.depths[:1], depth_scale=5000.0)
    assert not result.lossless
    assert result.max_error_m == pytest.approx(3 / 5000)
    assert result.rmse_m == pytest.approx(3 / math.sqrt(640 * 480) / 5000)
    assert "NOT bit-exact" in result.notes


def test_rvl_package_rejects_bad_frames(sample: pcdcodec.RGBDSequence) -> None:
    pytest.importorskip("rvl")
    with pytest.raises(pcdcodec.InputTypeError, match=r"depth_frames\[0\] must be uint16"):
        peers.rvl_package_depth([sample.depths[0].astype(np.float32)])
    with pytest.raises(pcdcodec.InputError, match="depth_frames is empty"):
        peers.rvl_package_depth([])
    with pytest.raises(pcdcodec.InputError, match="depth_scale must be positive"):
        peers.rvl_package_depth(sample.depths[:1], depth_scale=0.0)


def test_rvl_package_takes_any_memory_layout(sample: pcdcodec.RGBDSequence) -> None:
    pytest.importorskip("rvl")
    depth = sample.depths[0]
    odd = [np.asfortranarray(depth), depth.astype(">u2"), depth[:, ::2]]
    result = peers.rvl_package_depth(odd)
    assert result.lossless
    assert result.matches_pcdcodec is RVL_BYTE_IDENTICAL


# -- missing packages --------------------------------------------------------------------


@pytest.mark.parametrize(("peer", "module"), [("draco", "DracoPy"), ("rvl-pypi", "rvl")])
def test_a_missing_peer_package_says_what_to_install(
    sample: pcdcodec.RGBDSequence,
    projector: pcdcodec.Projector,
    monkeypatch: pytest.MonkeyPatch,
    peer: str,
    module: str,
) -> None:
    def run() -> peers.PeerResult:
        if peer == "draco":
            return peers.draco_cloud(sample.depths, sample.colors, projector)
        return peers.rvl_package_depth(sample.depths)

    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` fail
    with pytest.raises(pcdcodec.CodecUnavailableError) as info:
        run()
    message = str(info.value)
    assert module in message
    assert 'pip install "pcdcodec[peers]"' in message
    assert isinstance(info.value, ImportError)
    status = peers.available_peers()
    assert set(status) == {"draco", "rvl-pypi"}
    reason = status[peer]
    assert reason is not None
    assert 'pip install "pcdcodec[peers]"' in reason


def test_available_peers_lists_installed_packages_as_usable() -> None:
    status = peers.available_peers()
    for peer, module in [("draco", "DracoPy"), ("rvl-pypi", "rvl")]:
        try:
            __import__(module)
        except ImportError:
            assert status[peer] is not None
        else:
            assert status[peer] is None


def test_importing_peers_imports_no_peer_package() -> None:
    code = (
        "import sys, pcdcodec.bench.peers; "
        "loaded = [m for m in ('DracoPy', 'rvl', 'open3d') if m in sys.modules]; "
        "assert not loaded, loaded"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
