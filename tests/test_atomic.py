"""The write-beside-then-rename helper every output goes through."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from pcdcodec._atomic import MARK, atomic_output, is_partial, partial_path


class BoomError(Exception):
    pass


def _write_and_fail(target: Path, *, folder: bool = False) -> None:
    with atomic_output(target) as tmp:
        if folder:
            (tmp / "deep").mkdir(parents=True)
            (tmp / "deep" / "f").write_text("x")
        else:
            tmp.write_bytes(b"half")
        raise BoomError("midway")


def test_partial_path_is_hidden_beside_the_target(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "run.pcdc"
    p = partial_path(target)
    assert p.parent == target.parent
    assert p.name == f".run.pcdc{MARK}{os.getpid()}"
    assert is_partial(p.name)
    assert partial_path(target, suffix=".mp4").name.endswith(".mp4")


def test_unique_names_differ_within_one_process(tmp_path: Path) -> None:
    names = {partial_path(tmp_path / "a", unique=True).name for _ in range(200)}
    assert len(names) == 200
    assert all(n.startswith(f".a{MARK}{os.getpid()}-") and is_partial(n) for n in names)
    assert partial_path(tmp_path / "a") == partial_path(tmp_path / "a")  # without: stable


def test_is_partial_only_hidden_partial_names() -> None:
    assert is_partial(".x.pcdc.partial-12-abcd0123")
    assert not is_partial("x.pcdc.partial-12")  # not hidden: a user's file
    assert not is_partial(".x.pcdc")
    assert not is_partial("run.pcdc")


def test_file_success_moves_into_place_and_replaces_old(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with atomic_output(target) as tmp:
        assert tmp != target
        assert not tmp.exists()
        tmp.write_bytes(b"new")
        assert target.read_bytes() == b"old"  # the old one stays until the end
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_file_failure_leaves_old_target_and_no_partial(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(BoomError, match="midway"):
        _write_and_fail(target)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
    # With no old target, nothing at all is left.
    fresh = tmp_path / "fresh.bin"
    with pytest.raises(BoomError, match="midway"):
        _write_and_fail(fresh)
    assert not fresh.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def test_stale_leftover_is_cleared_first(tmp_path: Path) -> None:
    target = tmp_path / "out"
    stale = partial_path(target)
    stale.mkdir()
    (stale / "junk").write_text("x")
    with atomic_output(target) as tmp:
        assert not tmp.exists()
        tmp.mkdir()
        (tmp / "a.txt").write_text("a")
    assert [p.name for p in target.iterdir()] == ["a.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_folder_failure_removes_partial_tree(tmp_path: Path) -> None:
    target = tmp_path / "out"
    with pytest.raises(BoomError, match="midway"):
        _write_and_fail(target, folder=True)
    assert list(tmp_path.iterdir()) == []


def test_folder_place_replaces_existing_folder(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    (target / "old.txt").write_text("old")

    def swap(tmp: Path, final: Path) -> None:
        shutil.rmtree(final)
        os.replace(tmp, final)

    with atomic_output(target, place=swap) as tmp:
        tmp.mkdir()
        (tmp / "new.txt").write_text("new")
    assert [p.name for p in target.iterdir()] == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_failing_place_propagates_and_cleans_up(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    (target / "keep").write_text("k")  # os.replace cannot put a file over a non-empty folder

    def write() -> None:
        with atomic_output(target) as tmp:
            tmp.write_bytes(b"x")

    with pytest.raises(OSError, match="out"):
        write()
    assert [p.name for p in target.iterdir()] == ["keep"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
