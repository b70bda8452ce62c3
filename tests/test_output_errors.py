"""An output that cannot be written (a folder not writable, a full disk) is said of the user's
own path, with what to do: never of the hidden partial file, nor of no file at all.

Read-only folders and full disks are simulated (tests may run as root, for whom a read-only
folder is writable): the file system calls on partial names fail as the system's would.
"""

from __future__ import annotations

import builtins
import errno
import io
import os
import pathlib
from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from pcdcodec import DiskFullError, OutputError
from pcdcodec._atomic import is_partial, output_error
from pcdcodec.cli import main
from pcdcodec.datasets import sample_dir

_REAL_OPEN = builtins.open
_REAL_MKDIR = os.mkdir


def _partial(path: Any) -> bool:
    p = Path(os.fsdecode(path))
    return any(is_partial(q.name) for q in (p, *p.parents))


def _denied(path: Any) -> OSError:
    return PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fsdecode(path))


class _FullDisk:
    """A file on a disk that fills after ``room`` bytes: writes then fail with ENOSPC."""

    def __init__(self, f: Any, room: int) -> None:
        self._f, self._room = f, room

    def write(self, data: Any) -> int:
        n = len(memoryview(data).cast("B"))
        if n > self._room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._room -= n
        return int(self._f.write(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._f, name)

    def __enter__(self) -> _FullDisk:
        return self

    def __exit__(self, *exc: object) -> None:
        self._f.close()


def _read_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """Creating a file or folder under a partial name fails: its folder is not writable."""

    def fake_open(file: Any, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        if isinstance(file, (str, os.PathLike)) and _partial(file) and "r" not in mode:
            raise _denied(file)
        return _REAL_OPEN(file, mode, *args, **kwargs)

    def fake_mkdir(path: Any, *args: Any, **kwargs: Any) -> None:
        if _partial(path):
            raise _denied(path)
        _REAL_MKDIR(path, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(io, "open", fake_open)
    monkeypatch.setattr(os, "mkdir", fake_mkdir)


def _disk_full(monkeypatch: pytest.MonkeyPatch, room: int = 200_000) -> None:
    """Files written under partial names fill the disk after ``room`` bytes."""

    def fake_open(file: Any, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        f = _REAL_OPEN(file, mode, *args, **kwargs)
        if isinstance(file, (str, os.PathLike)) and _partial(file) and set(mode) & set("wxa"):
            return _FullDisk(f, room)
        return f

    def write_bytes(self: Path, data: Any) -> int:
        if _partial(self):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        with _REAL_OPEN(self, "wb") as f:
            return int(f.write(data))

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(pathlib.Path, "write_bytes", write_bytes)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "rec.pcdc"
    pcdcodec.encode(sample_dir(), path, max_frames=3)
    return path


def _says_the_output(err: str, target: Path, *words: str) -> None:
    assert f"'{target}'" in err, err
    assert ".partial-" not in err, err
    for word in words:
        assert word in err, err


def _commands(recording: Path, out: Path) -> dict[str, tuple[list[str], Path]]:
    return {
        "encode": (["encode", str(sample_dir()), "-o", str(out / "x.pcdc")], out / "x.pcdc"),
        "decode": (["decode", str(recording), "-o", str(out / "frames")], out / "frames"),
        "export": (
            ["export", str(recording), str(out / "x.bag"), "--to", "rosbag1"],
            out / "x.bag",
        ),
        "paper": (["export", str(recording), str(out / "paper")], out / "paper"),
    }


@pytest.mark.parametrize("command", ["encode", "decode", "export", "paper"])
def test_a_folder_not_writable_is_said_of_the_output(
    command: str,
    recording: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv, target = _commands(recording, tmp_path)[command]
    _read_only(monkeypatch)
    if command == "paper":  # its folder is made first; the files in it fail
        monkeypatch.setattr(os, "mkdir", _REAL_MKDIR)
    assert main([*argv, "-q"]) == 1
    err = capsys.readouterr().err
    _says_the_output(err, target, "cannot write", "not writable", "folder you can write to")
    assert not [p for p in tmp_path.rglob("*") if is_partial(p.name)]
    assert not target.exists()  # the paper layout's folder, made by the export, is gone too


@pytest.mark.parametrize("command", ["encode", "decode", "paper"])
def test_a_full_disk_is_said_of_the_output(
    command: str,
    recording: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv, target = _commands(recording, tmp_path)[command]
    _disk_full(monkeypatch)
    assert main([*argv, "-q"]) == 1
    err = capsys.readouterr().err
    _says_the_output(err, target, "no space left to write", "free space")
    assert not target.exists()  # the paper layout's folder, made by the export, is gone too


def test_a_paper_layout_into_a_folder_there_before_keeps_the_folder(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "paper"
    target.mkdir()
    _disk_full(monkeypatch)
    assert main(["export", str(recording), str(target), "-q"]) == 1
    assert target.is_dir()
    assert list(target.iterdir()) == []


#: What Rerun (0.41) raises when it cannot create its file, or when the disk fills.
_RERUN_ERRORS = {
    "read-only": "Failed to create file: Permission denied (os error 13), path: {path}",
    "full": "Failed to encode LogMsg: Failed to write: No space left on device (os error 28)",
}


@pytest.mark.parametrize("case", ["read-only", "full"])
def test_view_save_says_the_output_not_rerun_s_partial_file(
    case: str,
    recording: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    rr = pytest.importorskip("rerun")
    real_save, real_flush = rr.RecordingStream.save, rr.RecordingStream.flush

    def save(self: Any, path: Any, *args: Any, **kwargs: Any) -> Any:
        if case == "read-only":
            raise RuntimeError(_RERUN_ERRORS[case].format(path=path))
        return real_save(self, path, *args, **kwargs)

    def flush(self: Any, *args: Any, **kwargs: Any) -> Any:
        if case == "full":
            raise RuntimeError(_RERUN_ERRORS[case])
        return real_flush(self, *args, **kwargs)

    monkeypatch.setattr(rr.RecordingStream, "save", save)
    monkeypatch.setattr(rr.RecordingStream, "flush", flush)
    target = tmp_path / "v.rrd"
    assert main(["view", str(recording), "--save", str(target)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    if case == "read-only":
        _says_the_output(err, target, "cannot write", "not writable", "folder you can write to")
    else:
        _says_the_output(err, target, "no space left to write", "free space")
    assert list(tmp_path.iterdir()) == []


def test_errors_of_the_input_are_left_as_they_are(tmp_path: Path) -> None:
    target = tmp_path / "out.pcdc"
    own = PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "input.bag"))
    assert output_error(target, own) is own
    hidden = _denied(tmp_path / ".out.pcdc.partial-12")
    named = output_error(target, hidden)
    assert isinstance(named, OutputError)
    assert isinstance(named, OSError)  # still caught as before
    full = output_error(target, RuntimeError("wrapped"))
    assert not isinstance(full, DiskFullError)
    wrapper = RuntimeError("writing failed")
    wrapper.__cause__ = OSError(errno.ENOSPC, "No space left on device")
    assert isinstance(output_error(target, wrapper), DiskFullError)
