"""A recording that ends before its writer closed it (cut short, or its writer stopped) is read
for the frames it holds, and every reader says so: a warning naming the file, the frames that
can be read and ``pcdcodec recover``, and ``complete`` false. A file cut before its settings
says it is a pcdcodec recording that nothing can be recovered from."""

from __future__ import annotations

import re
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest

import pcdcodec
from pcdcodec.cli import main
from pcdcodec.errors import DecodeError, IncompleteRecordingWarning
from pcdcodec.recording import CameraSpec

from .test_integrity import CAMERA, small_frames, write


def records(data: bytes) -> list[tuple[int, int]]:
    """(offset, opcode) of every record of the data section."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        out.append((pos, opcode))
        if opcode == 0x0F:  # the data section's end
            break
        pos += 9 + length
    return out


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("incomplete") / "whole.pcdc", small_frames(10))


def cut(src: Path, dst: Path, size: int) -> Path:
    dst.write_bytes(src.read_bytes()[:size])
    return dst


@pytest.fixture
def half(tmp_path: Path, whole: Path) -> Path:
    """``whole`` cut inside a record in its middle."""
    return cut(whole, tmp_path / "half.pcdc", whole.stat().st_size // 2 + 5)


def frames_of(path: Path) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IncompleteRecordingWarning)
        with pcdcodec.open(path) as rec:
            return len(rec)


def said(text: str, path: Path, frames: int) -> None:
    """``text`` names the file, the frames it holds and ``pcdcodec recover``."""
    assert str(path) in text
    assert f"{frames} frames can be read" in text
    assert "pcdcodec recover" in text


def test_a_cut_file_warns_when_opened_and_says_it_is_incomplete(half: Path, whole: Path) -> None:
    with pytest.warns(IncompleteRecordingWarning) as caught:
        rec = pcdcodec.open(half)
    with rec:
        n = len(rec)
        assert not rec.complete
        assert 0 < n < 10
    said(str(caught[0].message), half, n)
    assert "cut short" in str(caught[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteRecordingWarning)
        with pcdcodec.open(whole) as rec:
            assert rec.complete
            assert len(rec) == 10


def test_a_file_ending_at_a_record_boundary_is_incomplete_too(tmp_path: Path, whole: Path) -> None:
    """A writer stopped between two records leaves no record cut short: still incomplete."""
    data = whole.read_bytes()
    chunks = [o for o, op in records(data) if op == 0x06]
    path = cut(whole, tmp_path / "stopped.pcdc", chunks[len(chunks) // 2])
    with pytest.warns(IncompleteRecordingWarning, match="writer was stopped") as caught:
        rec = pcdcodec.open(path)
    with rec:
        assert not rec.complete
        said(str(caught[0].message), path, len(rec))


def test_a_warning_made_an_error_leaves_no_file_open(half: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteRecordingWarning)
        with pytest.raises(IncompleteRecordingWarning):
            pcdcodec.open(half)


def test_a_sealed_file_cut_in_its_summary_is_complete(tmp_path: Path, whole: Path) -> None:
    """Every frame is there (the seal and the data section's end say so): no warning."""
    data = whole.read_bytes()
    end = next(o for o, op in records(data) if op == 0x0F)
    path = cut(whole, tmp_path / "nosummary.pcdc", end + 9 + 4 + 20)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteRecordingWarning)
        with pcdcodec.open(path) as rec:
            assert rec.complete
            assert len(rec) == 10


@pytest.mark.parametrize("command", ["decode", "export", "view", "info"])
def test_every_command_reading_a_cut_file_says_so(
    command: str, half: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    args = {
        "decode": ["decode", str(half), "-o", str(out), "-q"],
        "export": ["export", str(half), str(out), "--to", "rosbag1", "-q"],
        "view": ["view", str(half), "--save", str(tmp_path / "x.rrd")],
        "info": ["info", str(half)],
    }[command]
    if command == "view":
        pytest.importorskip("rerun")
    assert main(args) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1, err
    said(lines[0], half, frames_of(half))


def _rig(path: Path) -> Path:
    specs = [CameraSpec("a", CAMERA, 5000.0, color=None), CameraSpec("b", CAMERA, 5000.0)]
    with pcdcodec.open(path, "w", cameras=specs) as w:
        for color, depth, ts in small_frames(8):
            w.write("a", None, depth, ts)
            w.write("b", color, depth, ts + 1000)
    return path


def test_a_cut_rig_warns_once_naming_each_cameras_frames(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = _rig(tmp_path / "rig.pcdc")
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteRecordingWarning)
        with pcdcodec.open(whole) as rig:
            assert rig.complete
    path = cut(whole, tmp_path / "cut.pcdc", whole.stat().st_size * 2 // 3)
    with pytest.warns(IncompleteRecordingWarning) as caught:
        rig = pcdcodec.open(path)
    with rig:
        assert not rig.complete
        counts = {name: len(rig.frames(name)) for name in rig.camera_names}
        depth = rig.frames("b")[0].depth
    assert len(caught) == 1
    text = str(caught[0].message)
    assert str(path) in text
    assert "pcdcodec recover" in text
    for name, n in counts.items():
        assert f"{n} of camera {name!r}" in text
    assert np.array_equal(depth, small_frames(1)[0][1])
    assert main(["decode", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: ") == 1
    assert str(path) in err


@pytest.mark.parametrize("size", [100, 25])
def test_a_recording_cut_before_its_settings_says_so(
    size: int, tmp_path: Path, whole: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = cut(whole, tmp_path / "tiny.pcdc", size)
    expected = re.escape(f"{str(path)!r} is a pcdcodec recording cut short at byte {size}")
    with pytest.raises(DecodeError, match=expected) as caught:
        pcdcodec.open(path)
    assert "nothing can be recovered" in str(caught.value)
    assert "not a pcdcodec recording" not in str(caught.value)
    with pytest.raises(DecodeError, match=expected):
        pcdcodec.recover(path, tmp_path / "out.pcdc")
    assert main(["info", str(path)]) == 1
    assert "nothing can be recovered" in capsys.readouterr().err


def test_another_mcap_file_is_still_not_a_recording(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "other.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="x")
        w.finish()
    with pytest.raises(DecodeError, match="is an MCAP file but not a pcdcodec recording"):
        pcdcodec.recording.Recording(path)


def test_paper_export_and_view_read_the_frames_of_a_cut_file(
    tmp_path: Path, whole: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Cut at every chunk: where the writer had written a color packet before its frame's
    digest, that packet is left out with its frame, as ``decode`` leaves it out, rather than
    stopping ``export --layout paper`` and ``view --save`` with an error."""
    pytest.importorskip("rerun")
    from pcdcodec.convert.paper import import_paper

    data = whole.read_bytes()
    tried = 0
    for k, offset in enumerate(o for o, op in records(data) if op == 0x06):
        path = cut(whole, tmp_path / f"cut{k}.pcdc", offset)
        n = frames_of(path)
        if n == 0:
            continue
        tried += 1
        layout, rrd = tmp_path / f"paper{k}", tmp_path / f"view{k}.rrd"
        assert main(["export", str(path), "-o", str(layout), "--layout", "paper", "-q"]) == 0
        assert main(["view", str(path), "--save", str(rrd)]) == 0
        err = capsys.readouterr().err
        assert "error" not in err, err
        assert rrd.stat().st_size > 0
        back = import_paper(layout, tmp_path / f"back{k}.pcdc")
        assert back == n
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IncompleteRecordingWarning)
            with pcdcodec.open(path) as rec, pcdcodec.open(tmp_path / f"back{k}.pcdc") as again:
                assert len(rec.packet_timestamps) == n  # h264 without B-frames: one per frame
                assert len(again) == n
                for a, b in zip(rec, again, strict=True):
                    assert b.timestamp_ns == a.timestamp_ns
                    assert np.array_equal(b.depth, a.depth)
                    assert b.color is not None
                    assert a.color is not None
                    assert np.array_equal(b.color, a.color)  # the packets, unchanged
    assert tried >= 5
