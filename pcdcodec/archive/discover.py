"""Finding the inputs of an archive run, and what the manifest keeps of each: its output name
(:func:`find_inputs`), its size and modification time, and the hash of its content."""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat as stat_module
from collections.abc import Sequence
from pathlib import Path

from ..errors import InputError

__all__ = ["find_inputs"]


def _is_input(path: Path) -> bool:
    from ..sources.base import source_kinds

    for kind in source_kinds():
        if kind.name == "recording":
            continue  # recordings are what an archive run writes, not what it reads
        with contextlib.suppress(Exception):
            if kind.probe(path):
                return True
    return False


def _output_name(path: Path) -> str:
    return (path.name if path.is_dir() else path.stem) + ".pcdc"


def find_inputs(
    sources: Sequence[str | os.PathLike[str]], *, exclude: Path | None = None
) -> list[tuple[Path, str]]:
    """Every input under ``sources`` and the output path (relative, POSIX) it is written to.

    A path that is itself an input maps to ``NAME.pcdc``; inside a folder that is not an input,
    every input found (not descending into inputs, nor into ``exclude``) maps to
    ``FOLDER/SUB/NAME.pcdc``. Raises :class:`~pcdcodec.InputError` for a missing path, a path
    holding no input, or two inputs that would be written to the same output.
    """
    found: list[tuple[Path, str]] = []
    for src in sources:
        root = Path(src)
        if not root.exists():
            raise InputError(f"{str(root)!r} does not exist")
        if _is_input(root):
            found.append((root, _output_name(root)))
            continue
        if not root.is_dir():
            raise InputError(f"{str(root)!r} is not an input pcdcodec reads")
        before = len(found)
        skip = exclude.resolve() if exclude is not None else None
        for dirpath, dirnames, filenames in os.walk(root):
            here = Path(dirpath)
            dirnames.sort()
            keep = []
            for d in dirnames:
                sub = here / d
                if d.startswith(".") or (skip is not None and sub.resolve() == skip):
                    continue
                if _is_input(sub):
                    found.append((sub, (Path(root.name) / sub.relative_to(root)).as_posix()))
                else:
                    keep.append(d)
            dirnames[:] = keep
            for name in sorted(filenames):
                f = here / name
                if name.startswith(".") or name.endswith(".pcdc") or not _is_input(f):
                    continue
                rel = Path(root.name) / f.relative_to(root).parent / f.stem
                found.append((f, rel.as_posix()))
        if len(found) == before:
            raise InputError(f"{str(root)!r} holds no input pcdcodec reads")
        found[before:] = [(p, o if o.endswith(".pcdc") else o + ".pcdc") for p, o in found[before:]]
    seen: dict[str, Path] = {}
    for path, out in found:
        if out in seen:
            raise InputError(
                f"{str(seen[out])!r} and {str(path)!r} would both be written to {out!r}; "
                "archive them in separate runs or rename one"
            )
        seen[out] = path
    return found


def _walk(path: Path) -> tuple[list[tuple[Path, os.stat_result]], bool]:
    """The files of an input (the file itself, or a folder's files at any depth), sorted, with
    their ``stat``, and whether some of it could not be reached (an unreadable folder or file).

    Symbolic links are followed, to files and to folders alike (datasets are often assembled
    from links), each folder once however many links lead to it; a dangling link is no file.
    """
    missing = False

    def stat(f: Path) -> os.stat_result | None:
        nonlocal missing
        try:
            return os.stat(f)  # follows links
        except FileNotFoundError:
            return None  # a dangling link
        except OSError:
            missing = True
            return None

    if not path.is_dir():
        st = stat(path)
        return ([(path, st)] if st is not None else []), missing or st is None
    files: list[tuple[Path, os.stat_result]] = []
    seen: set[str] = set()

    def unreadable(_: OSError) -> None:
        nonlocal missing
        missing = True

    for dirpath, dirnames, filenames in os.walk(path, onerror=unreadable, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen:  # a second link to a folder already walked, or a loop
            dirnames[:] = []
            continue
        seen.add(real)
        for name in filenames:
            f = Path(dirpath) / name
            st = stat(f)
            if st is not None and stat_module.S_ISREG(st.st_mode):
                files.append((f, st))
    files.sort(key=lambda item: item[0])
    return files, missing


def _files(path: Path) -> list[Path]:
    return [f for f, _ in _walk(path)[0]]


def _stat(path: Path) -> tuple[int | None, int]:
    """Total size (``None`` when some of the input could not be reached) and latest
    modification time (ns) of a file or a folder's files, following symbolic links."""
    files, missing = _walk(path)
    size = sum(st.st_size for _, st in files)
    mtime = max((st.st_mtime_ns for _, st in files), default=0)
    return (None if missing else size), mtime


def _hash(path: Path) -> str:
    """BLAKE2b of a file, or of a folder's files (relative names and contents, sorted)."""
    h = hashlib.blake2b(digest_size=20)
    for f in _files(path):
        if path.is_dir():
            h.update(f.relative_to(path).as_posix().encode() + b"\0")
        with f.open("rb") as fh:
            while block := fh.read(1 << 20):
                h.update(block)
    return "blake2b:" + h.hexdigest()
