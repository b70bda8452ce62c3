"""A recording as an input: written again with other codecs, depth bit-exact, the rest kept."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pcdcodec
from pcdcodec import CameraIntrinsics, DecodeError, InputError, PcdcodecError
from pcdcodec.recording import CameraSpec, RigRecording
from pcdcodec.sources.base import detect_kind

from .conftest import REPO, to_metres

#: The training color codec (pcdcodec.torch.TRAINING_COLOR), without importing torch.
AV1_GOP1 = {"id": "av1", "gop": 1, "crf": 52, "preset": 6, "low_delay": True}
AV1_CLI = "av1:gop=1,crf=52,preset=6,low_delay=true"
_MS = 1_000_000


def _pose(i: int) -> np.ndarray[Any, Any]:
    pose = np.eye(4)
    a = 0.05 * i
    pose[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    pose[:3, 3] = [0.1 * i, -0.02 * i, 1.5]
    return pose


def _write(path: Path, n: int = 4, *, fps: float = 15.0, **options: Any) -> None:
    """The sample's first ``n`` frames with poses (h264 and depthac, the defaults)."""
    seq = pcdcodec.load_sample(max_frames=n)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        fps=fps,
        metadata={"site": "lab 2"},
        **options,
    ) as w:
        for i, f in enumerate(seq):
            w.write(f.color, f.depth, f.timestamp_ns, pose=_pose(i))


def _psnr(a: np.ndarray[Any, Any], b: np.ndarray[Any, Any]) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def _same_but_color(src: Path, out: Path, *, min_psnr: float) -> None:
    """``out`` holds ``src``'s frames: depth bit for bit, stamps, poses, the camera; color
    within ``min_psnr`` dB of ``src``'s decoded color."""
    with pcdcodec.open(src) as a, pcdcodec.open(out) as b:
        assert len(b) == len(a) > 0
        assert b.intrinsics == a.intrinsics
        assert b.depth_scale == a.depth_scale
        assert b.fps == a.fps
        assert b.frame_id == a.frame_id
        assert b.color_intrinsics == a.color_intrinsics
        assert (b.depth_to_color is None) == (a.depth_to_color is None)
        if a.depth_to_color is not None:
            assert np.array_equal(b.depth_to_color, a.depth_to_color)
        assert b.metadata == a.metadata
        assert np.array_equal(b.timestamps, a.timestamps)
        for fa, fb in zip(a, b, strict=True):
            assert fb.depth.dtype == fa.depth.dtype
            assert np.array_equal(fb.depth, fa.depth, equal_nan=fa.depth.dtype.kind == "f")
            assert fb.timestamp_ns == fa.timestamp_ns
            assert (fb.pose is None) == (fa.pose is None)
            if fa.pose is not None:
                assert np.array_equal(fb.pose, fa.pose)
            if fa.color is None:
                assert fb.color is None
            else:
                assert fb.color is not None
                assert fb.color.shape == fa.color.shape
                assert _psnr(fa.color, fb.color) >= min_psnr


def test_a_recording_is_an_input_and_nothing_else_is_taken_for_one(tmp_path: Path) -> None:
    rec = tmp_path / "run.pcdc"
    _write(rec, 2)
    assert detect_kind(rec) == "recording"
    renamed = tmp_path / "run.bin"  # by content, not by name
    renamed.write_bytes(rec.read_bytes())
    assert detect_kind(renamed) == "recording"
    # Other MCAP files, other files and folders are not recordings.
    other = tmp_path / "other.pcdc"
    other.write_bytes(rec.read_bytes()[:8] + b"\x01" + bytes(40))
    assert detect_kind(other) is None
    text = tmp_path / "notes.pcdc"
    text.write_text("not a recording")
    assert detect_kind(text) is None
    assert detect_kind(tmp_path) is None
    with pcdcodec.open_source(rec) as src:
        assert type(src).__name__ == "RecordingSource"
        assert len(src) == 2
        assert src.fps == 15.0
        assert src.metadata == {"site": "lab 2"}


def test_recode_to_other_codecs_keeps_depth_stamps_poses_and_camera(tmp_path: Path) -> None:
    src = tmp_path / "run.pcdc"
    _write(src, 4)
    out = tmp_path / "train.pcdc"
    summary = pcdcodec.encode(src, out, color=AV1_GOP1, depth="zstd")
    assert summary.frames == 4
    assert summary.source["codecs"]["depth"] == {"id": "depthac"}
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"] is not None
        assert rec.codecs["color"]["id"] == "av1"
        assert rec.codecs["color"]["gop"] == 1
        assert rec.codecs["depth"] is not None
        assert rec.codecs["depth"]["id"] == "zstd"
    # crf 52 is coarse: the second generation stays near the first (measured 33-34 dB).
    _same_but_color(src, out, min_psnr=28.0)
    # h264 at its default crf again: one more generation costs little.
    again = tmp_path / "again.pcdc"
    pcdcodec.encode(src, again, depth="rvl")
    _same_but_color(src, again, min_psnr=38.0)


def test_recode_options_apply_as_for_other_inputs(tmp_path: Path) -> None:
    src = tmp_path / "run.pcdc"
    _write(src, 5)
    out = tmp_path / "cut.pcdc"
    summary = pcdcodec.encode(src, out, color=None, max_frames=3, fps=10.0)
    assert summary.frames == 3
    with pcdcodec.open(src) as a, pcdcodec.open(out) as b:
        assert b.fps == 10.0
        assert b.codecs["color"] is None
        assert len(b) == 3
        for i in range(3):
            fa, fb = a[i], b[i]
            assert fb.color is None
            assert np.array_equal(fb.depth, fa.depth)
            assert fb.pose is not None
            assert np.array_equal(fb.pose, fa.pose)
    # A recording's own camera and scale win over those given, with a note naming both ...
    cam = CameraIntrinsics(640, 480, 500.0, 500.0, 320.0, 240.0)
    other = tmp_path / "other.pcdc"
    kept = pcdcodec.encode(src, other, color=None, intrinsics=cam, depth_scale=1000.0)
    with pcdcodec.open(src) as a, pcdcodec.open(other) as b:
        assert (b.intrinsics, b.depth_scale) == (a.intrinsics, a.depth_scale)
    assert len(kept.source["camera_notes"]) == 2
    # ... and override=True replaces them; depth values stay as stored.
    pcdcodec.encode(
        src, other, color="ffv1", intrinsics=cam, depth_scale=1000.0, override=True, overwrite=True
    )
    with pcdcodec.open(src) as a, pcdcodec.open(other) as b:
        assert b.intrinsics.pinhole() == cam.pinhole()
        assert b.depth_scale == 1000.0
        assert all(np.array_equal(x.depth, y.depth) for x, y in zip(a, b, strict=True))
        # ffv1 is lossless: the color is the source's decoded color, bit for bit.
        assert all(np.array_equal(x.color, y.color) for x, y in zip(a, b, strict=True))


def test_float32_depth_with_nan_and_a_color_camera_apart(tmp_path: Path) -> None:
    seq = pcdcodec.load_sample(max_frames=3)
    color_cam = CameraIntrinsics(320, 240, 262.5, 262.5, 159.75, 119.75)
    d2c = np.eye(4)
    d2c[0, 3] = 0.025
    src = tmp_path / "metres.pcdc"
    with pcdcodec.open(
        src,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=1.0,  # float32 metres
        depth="zstd",
        color_intrinsics=color_cam,
        depth_to_color=d2c,
        frame_id="cam_optical",
    ) as w:
        for i, f in enumerate(seq):
            assert f.color is not None
            depth = to_metres(f.depth, seq.depth_scale)
            w.write(f.color[::2, ::2].copy(), depth, f.timestamp_ns, pose=_pose(i))
    out = tmp_path / "again.pcdc"
    pcdcodec.encode(src, out, depth="lz4")
    with pcdcodec.open(out) as rec:
        first = rec[0].depth
        assert first.dtype == np.float32
        assert np.isnan(first).any()
    _same_but_color(src, out, min_psnr=30.0)


def test_cli_recodes_a_recording(tmp_path: Path) -> None:
    src = tmp_path / "run.pcdc"
    _write(src, 3)
    out = tmp_path / "train.pcdc"
    cmd = [sys.executable, "-m", "pcdcodec", "encode", str(src), "-o", str(out)]
    done = subprocess.run(
        [*cmd, "--color", AV1_CLI, "--depth", "zstd"],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "wrote 3 frames" in done.stdout
    assert "depth scale  5000" in done.stdout
    assert "color decoded from the recording's h264 and encoded again" in done.stdout
    with pcdcodec.open(out) as rec:
        assert rec.codecs["color"] is not None
        assert rec.codecs["color"]["id"] == "av1"
    _same_but_color(src, out, min_psnr=28.0)
    # Flags for other kinds of input are refused, naming the kind.
    wrong = subprocess.run(
        [*cmd, "--overwrite", "--depth-topic", "/d"],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert wrong.returncode == 1
    assert "--depth-topic applies to bags" in wrong.stderr
    assert "recording" in wrong.stderr


def test_a_damaged_recording_as_input_names_the_file(tmp_path: Path) -> None:
    src = tmp_path / "run.pcdc"
    _write(src, 4)
    cut = tmp_path / "cut.pcdc"
    data = src.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    assert detect_kind(cut) == "recording"  # the probe reads the head only
    with pytest.raises(PcdcodecError) as info:
        pcdcodec.encode(cut, tmp_path / "out.pcdc")
    assert isinstance(info.value, DecodeError)
    assert str(cut) in str(info.value)
    assert not (tmp_path / "out.pcdc").exists()
    done = subprocess.run(
        [sys.executable, "-m", "pcdcodec", "encode", str(cut), "-o", str(tmp_path / "o.pcdc")],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert done.returncode == 1
    assert "cut.pcdc" in done.stderr
    assert "pcdcodec recover" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_recording_damaged_inside_names_the_file_and_writes_nothing(tmp_path: Path) -> None:
    src = tmp_path / "run.pcdc"
    _write(src, 4)
    with pcdcodec.open(src) as rec:
        offset = int(rec._offsets[2])  # the chunk of frame 2's depth
    data = bytearray(src.read_bytes())
    data[offset + 200] ^= 0xFF
    bad = tmp_path / "bad.pcdc"
    bad.write_bytes(bytes(data))
    out = tmp_path / "out.pcdc"
    with pytest.raises(DecodeError) as info:
        pcdcodec.encode(bad, out, depth="zstd")
    assert str(bad) in str(info.value)
    assert not out.exists()


def _rig(path: Path) -> dict[str, list[int]]:
    """Two cameras of the sample at different rates (30 and 15 fps) and start times, the
    wrist depth-only with its own frame name and rig pose; returns each camera's stamps."""
    seq = pcdcodec.load_sample(max_frames=6)
    wrist_cam = CameraIntrinsics(320, 240, 262.5, 262.5, 159.75, 119.75)
    wrist_pose = _pose(3)
    specs = [
        CameraSpec("head", seq.intrinsics, seq.depth_scale, fps=30.0),
        CameraSpec(
            "wrist",
            wrist_cam,
            1000.0,
            fps=15.0,
            color=None,
            depth="rvl",
            rig_pose=wrist_pose,
            frame_id="wrist_depth_optical",
        ),
    ]
    head_t = [1_000 * _MS + k * 33_333_333 for k in range(6)]
    wrist_t = [1_010 * _MS + k * 66_666_667 for k in range(3)]
    meta = {"robot": "r2", "head.serial": "A1", "wrist.serial": "B2"}
    with pcdcodec.open(path, "w", cameras=specs, metadata=meta, rig_frame_id="base_link") as rig:
        for k, f in enumerate(seq):
            rig.write("head", f.color, f.depth, head_t[k], pose=_pose(k))
            if k < 3:
                rig.write("wrist", None, f.depth[::2, ::2].copy(), wrist_t[k])
    return {"head": head_t, "wrist": wrist_t}


def _same_rig(src: Path, out: Path, *, min_psnr: float) -> None:
    with pcdcodec.open(src) as a, pcdcodec.open(out) as b:
        assert isinstance(a, RigRecording)
        assert isinstance(b, RigRecording)
        assert b.camera_names == a.camera_names
        assert b.rig_frame_id == a.rig_frame_id
        assert b.metadata == a.metadata
        for name in a.camera_names:
            ca, cb = a.cameras[name], b.cameras[name]
            assert np.array_equal(cb.rig_pose, ca.rig_pose)
            assert cb.frame_id == ca.frame_id
            assert cb.intrinsics == ca.intrinsics
            assert cb.depth_scale == ca.depth_scale
            assert cb.fps == ca.fps
            assert (cb.color_codec is None) == (ca.color_codec is None)
            fa, fb = a.frames(name), b.frames(name)
            assert np.array_equal(fb.timestamps, fa.timestamps)
            for x, y in zip(fa, fb, strict=True):
                assert np.array_equal(y.depth, x.depth)
                assert (y.pose is None) == (x.pose is None)
                if x.pose is not None:
                    assert np.array_equal(y.pose, x.pose)
                if x.color is not None:
                    assert y.color is not None
                    assert _psnr(x.color, y.color) >= min_psnr


def test_a_rig_is_recoded_to_a_rig(tmp_path: Path) -> None:
    src = tmp_path / "rig.pcdc"
    stamps = _rig(src)
    out = tmp_path / "again.pcdc"
    summary = pcdcodec.encode_rig([src], out, color=AV1_GOP1, depth="zstd")
    assert list(summary.cameras) == ["head", "wrist"]
    assert summary.rig_frame == "base_link"
    assert summary.cameras["head"].frames == len(stamps["head"])
    assert summary.cameras["wrist"].frames == len(stamps["wrist"])
    assert summary.warnings == []
    _same_rig(src, out, min_psnr=28.0)
    with pcdcodec.open(out) as rec:
        assert rec.cameras["head"].depth_codec == {"id": "zstd", "level": 3}
        assert rec.cameras["wrist"].color_codec is None
    # The one-camera call names the cameras and the way to read them all.
    with pytest.raises(InputError, match="head, wrist"):
        pcdcodec.encode(src, tmp_path / "one.pcdc")
    # One camera of it, picked by name, is a one-camera recording.
    pcdcodec.encode(src, tmp_path / "wrist.pcdc", camera="wrist")
    with pcdcodec.open(tmp_path / "wrist.pcdc") as one, pcdcodec.open(src) as rig:
        assert one.frame_id == "wrist_depth_optical"
        assert one.fps == 15.0
        assert one.metadata == {"serial": "B2"}
        wrist = rig.frames("wrist")
        assert all(np.array_equal(x.depth, y.depth) for x, y in zip(one, wrist, strict=True))


def test_cli_recodes_a_rig_with_another_input(tmp_path: Path) -> None:
    src = tmp_path / "rig.pcdc"
    _rig(src)
    out = tmp_path / "again.pcdc"
    cmd = [sys.executable, "-m", "pcdcodec", "encode"]
    done = subprocess.run(
        [*cmd, str(src), "-o", str(out), "--depth", "zstd"],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "of 2 cameras" in done.stdout
    _same_rig(src, out, min_psnr=38.0)
    # --max-frames applies per camera.
    cut = tmp_path / "cut.pcdc"
    done = subprocess.run(
        [*cmd, str(src), "-o", str(cut), "--max-frames", "2", "-q"],
        capture_output=True,
        text=True,
        cwd=REPO,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    with pcdcodec.open(cut) as rec:
        assert [len(rec.frames(n)) for n in rec.camera_names] == [2, 2]
    # A rig and a one-camera recording together: three cameras, the new one named by its file.
    one = tmp_path / "side.pcdc"
    _write(one, 2)
    both = tmp_path / "both.pcdc"
    summary = pcdcodec.encode_rig([src, one], both)
    assert list(summary.cameras) == ["head", "wrist", "side"]
    with pcdcodec.open(both) as rec:
        assert np.array_equal(rec.rig_poses["wrist"], _pose(3))
        assert np.array_equal(rec.rig_poses["side"], np.eye(4))
        assert rec.metadata["side.site"] == "lab 2"
        assert rec.metadata["robot"] == "r2"
