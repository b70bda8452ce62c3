"""Compressing an archive of RGB-D inputs on a Dask cluster: resumable, verified, in parallel.

:func:`archive` turns every input under the given paths (anything :func:`pcdcodec.open_source`
reads: bags, folders, camera recordings) into one ``.pcdc`` file under the output folder,
mirroring the source tree. It runs on a ``dask.distributed`` cluster: a local one sized to the
machine, or an existing one given by its scheduler address (for SLURM, start one with
``dask-jobqueue``; see ``docs/archive.md``). Needs the ``archive`` extra (``distributed``).

How a run is organised:

* **Segments.** A long input is cut into segments (:func:`segment_plan`: about
  :data:`SEGMENT_BYTES` of source and at least :data:`SEGMENT_MIN_FRAMES` frames each by
  default, lengths a multiple of the color keyframe interval). Each segment is one task that
  opens the source, seeks to its first frame and writes a recording with a new color encoder,
  so it starts with a keyframe and holds whole keyframe intervals. Folders seek by
  frame number; bags through a frame index the probe builds from the message headers
  (:meth:`pcdcodec.sources.Source.frame_index`), so a segment reads only its own messages.
  When all of an input's segments are written, a join task copies their messages into one
  recording (:func:`pcdcodec.recording.join`), which reads exactly like a file from one
  writer.
* **Manifest.** ``OUT/pcdcodec-archive.json`` records each input's size, modification time,
  content hash (BLAKE2b), frame count, segments, state and error. A rerun skips inputs that are
  done and unchanged (same size and modification time, same codecs), keeps the segments of a
  half-done input whose hash and plan are unchanged, and redoes the rest.
* **Atomic outputs.** Every file is written under a hidden name beside it (see
  :mod:`pcdcodec._atomic`; unique per writer) and renamed when complete, so a final name never
  holds a half-written file.
* **Lock.** ``OUT/pcdcodec-archive.lock`` (an OS file lock, released by the kernel if the run
  dies) refuses a second run on the same folder.
* **Verification.** With ``verify``, every output is decoded: depth and timestamps are compared
  bit-exactly with the source read again from disk, color with a hash of each frame as the
  codec decoded its own segment. Sources are deleted only after that, and only when asked.
* **Faults.** A task whose worker dies is rerun elsewhere by Dask; an input that fails (corrupt,
  unreadable) is reported and the others go on; a full disk stops the run with a clear error.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import math
import os
import shutil
import socket
import stat as stat_module
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import IO, Any

from .._atomic import is_partial, partial_path
from .._version import __version__
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import (
    ArchiveLockedError,
    CodecUnavailableError,
    DiskFullError,
    InputError,
    PcdcodecError,
    VerificationError,
)

__all__ = ["ArchiveItem", "ArchiveSummary", "archive", "find_inputs", "segment_plan"]

MANIFEST = "pcdcodec-archive.json"
LOCK = "pcdcodec-archive.lock"
PARTS = ".pcdcodec-parts"

#: default segment size: about this many bytes of source per segment ...
SEGMENT_BYTES = 1_000_000_000
#: ... and at least this many frames (a segment's fixed costs: a task, opening the source)
SEGMENT_MIN_FRAMES = 300

#: states an input goes through in the manifest
DONE_STATES = ("done", "verified", "source-deleted")


# -- summary ------------------------------------------------------------------------------------


@dataclass
class ArchiveItem:
    """What happened to one input."""

    source: str
    output: str
    #: ``done``, ``verified``, ``source-deleted``, ``skipped`` (done before), ``failed``, or
    #: ``pending`` (not reached: the run stopped first)
    state: str
    #: the input's size in bytes, following symbolic links; ``None`` when some of it could not
    #: be reached (a dangling link, an unreadable folder)
    bytes_in: int | None = 0
    bytes_out: int = 0
    frames: int = 0
    segments: int = 0
    error: str | None = None
    #: the depth camera recorded (:meth:`~pcdcodec.CameraIntrinsics.to_dict`), and where it
    #: came from: ``"input"`` (recorded in it), a file of the input (``"camera.json"``,
    #: ``"camera-intrinsics.txt"``...), ``"given"`` (``input_options``) or the origin of
    #: ``camera`` (``"--camera tum-ros"``); ``None``/``""`` when not known (not probed)
    camera: dict[str, Any] | None = None
    camera_from: str = ""
    #: the depth scale recorded (units per metre), and where it came from (as ``camera_from``,
    #: or a dataset's convention: ``"TUM RGB-D dataset"``, ``"7-Scenes dataset"``)
    depth_scale: float | None = None
    depth_scale_from: str = ""
    #: where ``camera`` contradicted what the input carries (the input's own was used)
    notes: list[str] = field(default_factory=list)

    def camera_text(self) -> str:
        """``camera 640x480 fx=525 ... (from X), depth scale 5000 (from Y)``, or ``""``."""
        if self.camera is None and self.depth_scale is None:
            return ""
        parts = []
        if self.camera is not None:
            c = self.camera
            parts.append(
                f"camera {c['width']}x{c['height']} fx={c['fx']:g} fy={c['fy']:g} "
                f"cx={c['cx']:g} cy={c['cy']:g} (from {self.camera_from})"
            )
        if self.depth_scale is not None:
            parts.append(f"depth scale {self.depth_scale:g} (from {self.depth_scale_from})")
        return ", ".join(parts)


@dataclass
class ArchiveSummary:
    """The outcome of :func:`archive`. ``ok`` is true when no input failed or was left over."""

    items: list[ArchiveItem]
    seconds: float
    workers: int
    dashboard: str | None = None
    #: why the run stopped before the end (a full disk), else ``None``
    stopped: str | None = None

    def _of(self, *states: str) -> list[ArchiveItem]:
        return [i for i in self.items if i.state in states]

    @property
    def done(self) -> list[ArchiveItem]:
        """Inputs written in this run."""
        return self._of("done", "verified", "source-deleted")

    @property
    def skipped(self) -> list[ArchiveItem]:
        """Inputs already done by an earlier run."""
        return self._of("skipped")

    @property
    def failed(self) -> list[ArchiveItem]:
        return self._of("failed")

    @property
    def pending(self) -> list[ArchiveItem]:
        return self._of("pending")

    @property
    def ok(self) -> bool:
        return not self.failed and not self.pending and self.stopped is None

    @property
    def bytes_in(self) -> int | None:
        """Source bytes encoded in this run; ``None`` when an input's size is unknown."""
        sizes = [i.bytes_in for i in self.done]
        return None if None in sizes else sum(s for s in sizes if s is not None)

    @property
    def bytes_out(self) -> int:
        return sum(i.bytes_out for i in self.done)

    @property
    def frames(self) -> int:
        return sum(i.frames for i in self.done)

    @property
    def ratio(self) -> float | None:
        """Source bytes over output bytes; ``None`` when either is unknown or zero."""
        size = self.bytes_in
        return size / self.bytes_out if size and self.bytes_out else None

    @property
    def throughput(self) -> float | None:
        """Source megabytes (10^6 bytes) per second encoded in this run (``None`` when an
        input's size is unknown)."""
        size = self.bytes_in
        if size is None:
            return None
        return size / 1e6 / self.seconds if self.seconds > 0 else 0.0

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "inputs": len(self.items),
            "done": len(self.done),
            "skipped": len(self.skipped),
            "failed": len(self.failed),
            "pending": len(self.pending),
            "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out,
            "ratio": self.ratio,
            "seconds": self.seconds,
            "throughput_mb_s": self.throughput,
            "frames": self.frames,
            "frames_per_s": self.frames_per_second,
            "workers": self.workers,
            "dashboard": self.dashboard,
            "stopped": self.stopped,
            "items": [asdict(i) for i in self.items],
        }

    def to_text(self) -> str:
        ratio = f"{self.ratio:.1f}x" if self.ratio else "-"
        size, rate = self.bytes_in, self.throughput
        size_in = "? MB (an input's size is unknown)" if size is None else f"{size / 1e6:.1f} MB"
        rate_text = "?" if rate is None else f"{rate:.2f}"
        lines = [
            f"inputs {len(self.items)}: {len(self.done)} written, {len(self.skipped)} already "
            f"done, {len(self.failed)} failed"
            + (f", {len(self.pending)} not reached" if self.pending else ""),
            f"bytes  {size_in} in, {self.bytes_out / 1e6:.1f} MB out (ratio {ratio})",
            f"time   {self.seconds:.1f} s on {self.workers} worker(s): "
            f"{rate_text} MB/s, {self.frames_per_second:.1f} frames/s",
        ]
        if self.stopped:
            lines.append(f"stopped: {self.stopped}")
        cameras = [(i, i.camera_text()) for i in self.items]
        if any(text for _, text in cameras):
            lines.append("cameras:")
            lines += [f"  {i.source}: {text}" for i, text in cameras if text]
        for item in self.items:
            lines += [f"NOTE {item.source}: {note}" for note in item.notes]
        for item in self.items:
            if item.error is not None and item.state != "failed":
                lines.append(f"WARNING {item.source}: {item.error}")
        for item in self.failed:
            lines.append(f"FAILED {item.source}: {item.error}")
        return "\n".join(lines)


# -- inputs -------------------------------------------------------------------------------------


def _is_input(path: Path) -> bool:
    from ..sources.base import source_kinds

    for kind in source_kinds():
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


def _disk_full(exc: BaseException, where: Path) -> DiskFullError | None:
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, DiskFullError):
            return e
        if isinstance(e, OSError) and e.errno in (errno.ENOSPC, errno.EDQUOT):
            return DiskFullError(
                f"no space left on the device holding {str(where)!r} ({e.strerror}); "
                "free space and run again: finished outputs are kept and skipped"
            )
        e = e.__cause__ or e.__context__
    return None


# -- tasks (run on the workers) ------------------------------------------------------------------

#: What an input without a camera needs, in the library's words (the CLI says its flags).
NO_CAMERA_HINT = "pass camera= (for every input that lacks one) or input_options= (for this input)"


def _probe(
    src: str, options: dict[str, Any], segment_frames: int | None, keyframes: int
) -> dict[str, Any]:
    """Size, hash and frame count of one input, and its frame index where it needs one."""
    import operator

    from ..sources import open_source

    path = Path(src)
    size, mtime = _stat(path)
    digest = _hash(path)
    index = None
    with open_source(path, **options) as source:
        if source.intrinsics is None:
            raise InputError(
                f"{src!r} does not say its camera intrinsics; {NO_CAMERA_HINT}, or put a "
                "camera.json in the folder"
            )
        camera = {
            "camera": source.intrinsics.to_dict(),
            "camera_from": source.intrinsics_origin,
            "depth_scale": float(source.depth_scale),
            "depth_scale_from": source.depth_scale_origin,
            "notes": list(source.camera_notes),
        }
        frames = source.frame_count
        # Index only inputs that may need more than one segment: a bag's message count bounds
        # its frame count from above.
        most = frames if frames is not None else operator.length_hint(source, -1)
        if most < 0 or len(segment_plan(most, size or 0, segment_frames, keyframes)) > 1:
            index = source.frame_index()
            if index is not None:
                frames = len(index)
    return {
        "size": size,
        "mtime_ns": mtime,
        "hash": digest,
        "frames": frames,
        "index": index,
        "camera": camera,
    }


def _encode_segment(
    src: str,
    options: dict[str, Any],
    part: str,
    start: int,
    stop: int | None,
    writer_options: dict[str, Any],
    digests: bool,
    index: Any = None,
) -> dict[str, Any]:
    """Write frames ``start:stop`` of ``src`` into the recording ``part`` (atomically); with
    ``index`` (a :class:`~pcdcodec.sources.FrameIndex` slice), the frames it lists."""
    from ..recording import Recording, RecordingWriter
    from ..sources import open_source

    target = Path(part)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = partial_path(target, unique=True)
    try:
        with open_source(src, **options) as source:
            frames = source.frames_at(index) if index is not None else source.frames(start, stop)
            meta = dict(source.metadata)
            opts = dict(writer_options)
            if not source.has_color:
                opts["color"] = None  # a depth-only input gives a depth-only recording
            with RecordingWriter(
                tmp,
                intrinsics=source.intrinsics,
                depth_scale=source.depth_scale,
                metadata=meta,
                # Sensors whose color camera is apart from the depth camera (RealSense bags).
                color_intrinsics=source.color_intrinsics,
                depth_to_color=source.depth_to_color,
                **opts,
            ) as writer:
                count = writer.write_frames(frames)
        if count == 0:
            raise InputError(f"{src!r} has no frames in {start}:{stop}")
        colors: list[str] = []
        if digests:
            # The codec's own decode of this segment, read alone: the joined file must give
            # back exactly these frames.
            with Recording(tmp) as rec:
                colors = [_digest(f.color) for f in rec]
        os.replace(tmp, target)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        full = _disk_full(exc, target)
        if full is not None:
            raise full from None
        raise
    return {"frames": count, "bytes": target.stat().st_size, "colors": colors}


def _existing_segment(part: str, digests: bool) -> dict[str, Any]:
    """What :func:`_encode_segment` returns, for a segment an earlier run wrote."""
    from ..recording import Recording

    with Recording(part) as rec:
        count = len(rec)
        colors = [_digest(f.color) for f in rec] if digests else []
    return {"frames": count, "bytes": Path(part).stat().st_size, "colors": colors}


def _digest(array: Any) -> str:
    """A digest of an image's values, shape and dtype, whatever its memory layout ("" for
    ``None``)."""
    import numpy as np

    if array is None:
        return ""
    a = np.ascontiguousarray(array)
    h = hashlib.blake2b(f"{a.dtype.str}{a.shape}".encode(), digest_size=16)
    h.update(a.data)
    return h.hexdigest()


def _join_parts(parts: list[str], output: str) -> dict[str, Any]:
    """Join the segments into ``output`` (atomically) and return its size."""
    from ..recording.join import join

    target = Path(output)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        if len(parts) == 1:
            os.replace(parts[0], target)  # already complete; a rename is atomic
            frames = -1
        else:
            frames = join(parts, target, overwrite=True)
    except BaseException as exc:
        full = _disk_full(exc, target)
        if full is not None:
            raise full from None
        raise
    return {"bytes": target.stat().st_size, "frames": frames}


def _verify(
    src: str, options: dict[str, Any], output: str, colors: list[str] | None
) -> dict[str, Any]:
    """Decode ``output`` and compare it with ``src`` read again; raise on any difference."""

    from ..recording import Recording
    from ..sources import open_source

    name = Path(output).name
    n = 0
    with open_source(src, **options) as source, Recording(output) as rec:
        if not rec.indexed:
            raise VerificationError(f"{name}: the output has no index")
        if colors is not None and len(colors) != len(rec):
            raise VerificationError(
                f"{name}: {len(rec)} frames, but its segments decoded {len(colors)}"
            )
        bound = _depth_bound(rec.codecs.get("depth") or {})
        decoded: Iterator[Any] = iter(rec)
        for original in source:
            frame = next(decoded, None)
            if frame is None:
                raise VerificationError(f"{name}: frame {n} of the source is missing")
            if frame.timestamp_ns != original.timestamp_ns:
                raise VerificationError(
                    f"{name}: frame {n} is at {frame.timestamp_ns} ns, the source's at "
                    f"{original.timestamp_ns} ns"
                )
            problem = _depth_mismatch(frame.depth, original.depth, bound)
            if problem:
                raise VerificationError(f"{name}: frame {n} depth {problem}")
            if colors is not None and _digest(frame.color) != colors[n]:
                raise VerificationError(
                    f"{name}: frame {n} color differs from the codec's decode of its segment"
                )
            n += 1
        if next(decoded, None) is not None:
            raise VerificationError(f"{name}: more frames than the source ({n})")
    return {"frames": n}


def _depth_bound(config: dict[str, Any]) -> Any:
    """The error bound a depth codec config states, or ``None`` for lossless coding."""
    from ..depth import FrameCodec
    from ..registry import get_codec

    codec = get_codec(config)
    return codec._bound() if isinstance(codec, FrameCodec) else None


def _depth_mismatch(decoded: Any, original: Any, bound: Any) -> str:
    """Why decoded depth does not stand for the source's ('' when it does).

    Lossless codecs must give the same bits (NaN, float32 "no measurement", equals itself);
    a codec with an error bound must keep every hole, and every valid pixel within its bound.
    """
    if decoded.dtype != original.dtype or decoded.shape != original.shape:
        return f"is {decoded.dtype} {decoded.shape}, the source's {original.dtype} {original.shape}"
    import numpy as np

    floats = decoded.dtype.kind == "f"
    if bound is None:
        same = np.array_equal(decoded, original, equal_nan=floats)
        return "" if same else "differs from the source"
    holes = ~np.isfinite(original) if floats else original == 0
    kept = ~np.isfinite(decoded) if floats else decoded == 0
    if not np.array_equal(holes, kept):
        return "has holes where the source has none, or the other way round"
    ref = original[~holes].astype(np.float64)
    err = np.abs(decoded[~holes].astype(np.float64) - ref)
    over = err > bound.of(ref)
    if over.any():
        i = int(np.argmax(over))
        return (
            f"is off by {err[i]:g} at a value of {ref[i]:g}, more than the codec's bound "
            f"(max_error={bound.abs_error:g}, max_rel_error={bound.rel_error:g})"
        )
    return ""


# -- the run (on the client) ---------------------------------------------------------------------


class _Lock:
    """An exclusive lock on the output folder, released by the OS if the process dies."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / LOCK
        self._file: IO[str] | None = None

    def __enter__(self) -> _Lock:
        f = self.path.open("a+")
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX
            fcntl = None  # type: ignore[assignment]
        if fcntl is not None:
            try:
                fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.seek(0)
                holder = f.read().strip() or "another process"
                f.close()
                raise ArchiveLockedError(
                    f"{str(self.path.parent)!r} is in use by another archive run ({holder}); "
                    "wait for it to finish or give another output folder"
                ) from None
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()} on {socket.gethostname()} since {time.ctime()}\n")
        f.flush()
        self._file = f
        return self

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.close()  # closing releases the lock
            self._file = None


class _Manifest:
    """The JSON manifest, rewritten atomically (at most every ``interval`` seconds)."""

    def __init__(self, folder: Path, interval: float = 1.0) -> None:
        self.path = folder / MANIFEST
        self.interval = interval
        self._last = 0.0
        self._dirty = False
        #: Why the last save failed for a full disk (the previous manifest stays in place).
        self.disk_full: str | None = None
        self.entries: dict[str, dict[str, Any]] = {}
        if self.path.exists():
            try:
                data = json.loads(self.path.read_text())
                self.entries = dict(data["inputs"])
            except (ValueError, KeyError, TypeError) as exc:
                raise InputError(
                    f"the manifest {str(self.path)!r} is damaged ({exc}); move it away to "
                    "start over (finished outputs are then encoded again)"
                ) from None

    def update(self, key: str, **values: Any) -> None:
        self.entries.setdefault(key, {}).update(values)
        self._dirty = True
        self.save(force=False)

    def save(self, force: bool = True) -> None:
        if not self._dirty or (not force and time.monotonic() - self._last < self.interval):
            return
        data = {"pcdcodec": __version__, "inputs": self.entries}
        tmp = partial_path(self.path, unique=True)
        try:
            with tmp.open("w") as f:
                json.dump(data, f, indent=1, sort_keys=True)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            full = _disk_full(exc, self.path)
            if full is None:
                raise
            # The manifest written before stays whole (it is only ever replaced); the run
            # stops with the reason, and the next save tries again.
            self.disk_full = str(full)
            return
        self._last = time.monotonic()
        self._dirty = False
        self.disk_full = None


def _sweep(out: Path) -> None:
    """Remove half-written files a dead run left (only names this module writes)."""
    for dirpath, _, filenames in os.walk(out):
        for name in filenames:
            if is_partial(name):
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(dirpath, name))


def _prune(folder: Path) -> None:
    """Remove the empty folders under ``folder`` (segments are gone once joined)."""
    if not folder.is_dir():
        return
    for dirpath, _, _ in sorted(os.walk(folder), key=lambda w: -len(w[0])):
        with contextlib.suppress(OSError):
            os.rmdir(dirpath)  # only succeeds when empty


def segment_plan(
    frames: int | None, size: int, segment_frames: int | None = None, keyframes: int = 1
) -> list[tuple[int, int | None]]:
    """The segments ``(start, stop)`` an input of ``frames`` frames and ``size`` bytes is cut
    into; ``[(0, None)]`` (one task) when it is not cut.

    A segment holds at most ``segment_frames`` frames; by default (``None``) as many as make
    about :data:`SEGMENT_BYTES` of source, and at least :data:`SEGMENT_MIN_FRAMES`. Segments
    are then made about equal, and where a segment is at least ``keyframes`` frames (the color
    codec's keyframe interval) their lengths are multiples of it: each segment starts with a
    keyframe (a new encoder) and holds whole keyframe intervals, so the joined stream has
    keyframes about as often as one writer's and cutting costs almost no compression.
    """
    if frames is None or frames < 2:
        return [(0, None)]
    if segment_frames is None:
        per_frame = max(size, 1) / frames
        segment_frames = max(SEGMENT_MIN_FRAMES, math.ceil(SEGMENT_BYTES / per_frame))
        align = max(keyframes, 1)
        segment_frames = -(-segment_frames // align) * align
    else:
        align = keyframes if keyframes > 1 and segment_frames >= keyframes else 1
        segment_frames -= segment_frames % align
    if frames <= segment_frames:
        return [(0, None)]
    k = math.ceil(frames / segment_frames)
    length = align * math.ceil(frames / (k * align))
    bounds = [min(i * length, frames) for i in range(k)] + [frames]
    return [(bounds[i], bounds[i + 1]) for i in range(k) if bounds[i] < bounds[i + 1]]


class _ByteProgress:
    def __init__(self, total: int, enabled: bool, stream: Any) -> None:
        self.total, self.done, self.enabled, self.stream = total, 0.0, enabled, stream
        self.inputs_done = 0
        self.inputs = 0
        self._start = time.perf_counter()
        self._last = 0.0

    def add(self, n: float) -> None:
        self.done = min(float(self.total), self.done + n)
        self.show()

    def show(self, force: bool = False) -> None:
        now = time.perf_counter()
        if not self.enabled or (not force and now - self._last < 0.2):
            return
        self._last = now
        pct = 100 * self.done / self.total if self.total else 100.0
        rate = self.done / 1e6 / max(now - self._start, 1e-9)
        self.stream.write(
            f"\rarchive {pct:3.0f}% {self.done / 1e6:,.1f}/{self.total / 1e6:,.1f} MB "
            f"({rate:.1f} MB/s), {self.inputs_done}/{self.inputs} inputs  "
        )
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.show(force=True)
            self.stream.write("\n")
            self.stream.flush()


def _dashboard(client: Any) -> str | None:
    import importlib.util

    if importlib.util.find_spec("bokeh") is None:
        return None  # the dashboard needs bokeh
    link = getattr(client, "dashboard_link", None)
    return str(link) if link else None


@contextlib.contextmanager
def _cluster(scheduler: str | None, workers: int | None, processes: bool) -> Iterator[Any]:
    try:
        import importlib
        import logging

        dist: Any = importlib.import_module("distributed")
    except ImportError as exc:
        raise CodecUnavailableError(
            "pcdcodec archive needs Dask's distributed scheduler: pip install 'pcdcodec[archive]'"
        ) from exc
    if scheduler is not None:
        with dist.Client(scheduler) as client:
            yield client
        return
    n = workers if workers is not None else (os.cpu_count() or 1)
    with (
        dist.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=processes,
            dashboard_address=":0",
            # A failing input is reported in the summary with its error; the workers' own
            # log lines and tracebacks for it would only repeat it on stderr.
            silence_logs=logging.CRITICAL,
        ) as cluster,
        dist.Client(cluster) as client,
    ):
        yield client


def archive(
    sources: Sequence[str | os.PathLike[str]],
    output: str | os.PathLike[str],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    color: Any = "h264",
    depth: Any = DEFAULT_DEPTH_CODEC,
    fps: float = 30.0,
    segment_frames: int | None = None,
    verify: bool = False,
    delete_source_after_verify: bool = False,
    source_options: dict[str, Any] | None = None,
    camera: Any = None,
    input_options: Mapping[Any, dict[str, Any]] | None = None,
    processes: bool = True,
    progress: bool | Callable[[int, int], None] | None = None,
    log: Callable[[str], None] | None = None,
) -> ArchiveSummary:
    """Encode every input under ``sources`` into a ``.pcdc`` file under ``output``.

    ``scheduler`` is the address of a running Dask scheduler (``tcp://host:8786``); without
    it a local cluster of ``workers`` processes (default: one per CPU core) runs the work
    (``processes=False`` makes them threads of this process). ``color`` and ``depth`` are
    codec names, configs or codecs as for :func:`pcdcodec.open`; ``fps`` is the nominal rate.
    Long inputs are cut into segments of at most ``segment_frames`` frames (default: about
    1 GB of source and at least 300 frames; see :func:`segment_plan`), encoded one task each
    and joined. ``verify`` decodes every output and compares it with its source;
    ``delete_source_after_verify`` (implies ``verify``) then deletes each verified source.
    ``source_options`` go to :func:`pcdcodec.open_source` for every input.

    Cameras: an input's own camera and depth scale (recorded in it, in its folder's
    ``camera.json`` or intrinsics file, or its dataset's convention) always win. ``camera``
    fills in only what an input lacks: a preset name
    (:data:`~pcdcodec.geometry.camera.CAMERA_PRESETS`,
    camera and depth scale), a :class:`~pcdcodec.CameraIntrinsics`, or a
    :class:`~pcdcodec.sources.CameraDefaults`; ``intrinsics`` and ``depth_scale`` in
    ``source_options`` are taken the same way. Where it contradicts what an input carries, the
    input's is used, and a warning goes to ``log`` and into the input's ``notes``.
    ``input_options`` maps an input (a path as given or found) to options of its own, which
    go to its reader and replace what the input says (``{"take3": {"intrinsics": cam,
    "depth_scale": 1000.0}}``). The summary lists each input's camera and depth scale and
    where each came from. ``progress`` is
    ``True`` for a progress line on stderr (default: when stderr is a terminal), ``False``
    for none, or a callable given (bytes done, bytes total). ``log`` receives messages (the
    dashboard link); default: printed to stderr when progress is shown.

    Returns an :class:`ArchiveSummary`; inputs that fail are in ``summary.failed`` with their
    error and do not stop the others. Raises :class:`~pcdcodec.ArchiveLockedError` when
    another run holds ``output``, :class:`~pcdcodec.InputError` for bad arguments or inputs
    that cannot be found, and :class:`~pcdcodec.DiskFullError` when not even the manifest can
    be written.
    """
    from ..codec import ColorCodec
    from ..registry import as_codec

    started = time.perf_counter()
    if scheduler is not None and workers is not None:
        raise InputError("give either a scheduler address or a number of workers, not both")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise InputError(f"workers must be a positive int, got {workers!r}")
    if segment_frames is not None and (
        isinstance(segment_frames, bool)
        or not isinstance(segment_frames, int)
        or segment_frames < 1
    ):
        raise InputError(f"segment_frames must be a positive int, got {segment_frames!r}")
    verify = verify or delete_source_after_verify
    color_codec = as_codec(color, "color") if color is not None else None
    color_config = color_codec.get_config() if color_codec is not None else None
    # Segments are cut on the color codec's keyframe interval (one for intra-only codecs).
    keyframes = (
        color_codec.keyframe_interval(float(fps)) if isinstance(color_codec, ColorCodec) else 1
    )
    depth_config = as_codec(depth, "depth").get_config()
    writer_options = {"color": color_config, "depth": depth_config, "fps": float(fps)}
    common = dict(source_options or {})
    defaults = _camera_defaults(camera, common)
    settings_all = {"color": color_config, "depth": depth_config, "fps": float(fps)}
    if defaults is not None:
        # Another default camera may change what inputs without one record.
        settings_all["camera"] = {
            "intrinsics": defaults.intrinsics.to_dict() if defaults.intrinsics else None,
            "depth_scale": defaults.depth_scale,
        }
        common["defaults"] = defaults

    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    inputs = find_inputs(sources, exclude=out)
    own = _input_options(inputs, input_options)
    options = {rel: {**common, **own.get(rel, {})} for _, rel in inputs}
    settings = {
        rel: {**settings_all, "input": _jsonable(own[rel])} if rel in own else settings_all
        for _, rel in inputs
    }
    show = sys.stderr.isatty() if progress is None else bool(progress)
    say = log if log is not None else (lambda m: print(m, file=sys.stderr) if show else None)
    warn = log if log is not None else (lambda m: print(m, file=sys.stderr))

    with _Lock(out):
        _sweep(out)
        try:
            return _archive(
                inputs,
                out,
                scheduler,
                workers,
                processes,
                options,
                writer_options,
                settings,
                (segment_frames, keyframes),
                verify,
                delete_source_after_verify,
                progress,
                show,
                say,
                warn,
                started,
            )
        finally:
            # Whatever stopped the run (Ctrl-C included), no half-written file stays behind.
            _sweep(out)
            _prune(out / PARTS)


def _camera_defaults(camera: Any, common: dict[str, Any]) -> Any:
    """The :class:`~pcdcodec.sources.CameraDefaults` for inputs that lack a camera, from
    ``camera`` and the ``intrinsics``/``depth_scale`` taken out of ``common``; or None."""
    from ..geometry.camera import CameraIntrinsics, camera_preset
    from ..sources.base import CameraDefaults

    intrinsics = common.pop("intrinsics", None)
    scale = common.pop("depth_scale", None)
    origin = "source_options"
    if isinstance(camera, CameraDefaults):
        if intrinsics is not None or scale is not None:
            raise InputError(
                "give the default camera once: as camera= or in source_options, not both"
            )
        return camera
    if isinstance(camera, str):
        preset = camera_preset(camera)
        origin = f"camera preset {camera}"
        if intrinsics is not None:
            raise InputError("give the default camera once: as camera= or in source_options")
        intrinsics = preset.intrinsics
        scale = scale if scale is not None else preset.depth_scale
    elif camera is not None:
        if intrinsics is not None:
            raise InputError("give the default camera once: as camera= or in source_options")
        intrinsics, origin = camera, "camera="
    if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
        raise InputError(
            "the default camera must be a preset name, a pcdcodec.CameraIntrinsics or a "
            f"CameraDefaults, got {type(intrinsics).__name__}"
        )
    if scale is not None:
        try:
            value = None if isinstance(scale, bool) else float(scale)
        except (TypeError, ValueError):
            value = None
        if value is None or not (math.isfinite(value) and value > 0):
            raise InputError(
                f"depth_scale must be a positive finite number of units per metre, got {scale!r}"
            )
    if intrinsics is None and scale is None:
        return None
    return CameraDefaults(intrinsics, None if scale is None else float(scale), origin)


def _input_options(
    inputs: list[tuple[Path, str]],
    given: Mapping[Any, dict[str, Any]] | None,
) -> dict[str, dict[str, Any]]:
    """``input_options`` keyed by each input's output name; a key naming no input is refused."""
    if not given:
        return {}
    by_path = {p.resolve(): rel for p, rel in inputs}
    out: dict[str, dict[str, Any]] = {}
    for key, opts in given.items():
        rel = by_path.get(Path(key).resolve())
        if rel is None:
            raise InputError(
                f"input_options names {str(key)!r}, which is not one of the inputs: "
                + ", ".join(repr(str(p)) for p, _ in inputs[:5])
                + (" ..." if len(inputs) > 5 else "")
            )
        if not isinstance(opts, dict):
            raise InputError(
                f"input_options for {str(key)!r} must be a dict of options, got {opts!r}"
            )
        out[rel] = dict(opts)
    return out


def _jsonable(options: dict[str, Any]) -> dict[str, Any]:
    """Per-input options as the manifest keeps them, to notice when they change."""
    out: dict[str, Any] = {}
    for k, v in sorted(options.items()):
        to_dict = getattr(v, "to_dict", None)
        out[k] = (
            to_dict() if callable(to_dict) else v if isinstance(v, (int, float, bool)) else str(v)
        )
    return out


def _archive(
    inputs: list[tuple[Path, str]],
    out: Path,
    scheduler: str | None,
    workers: int | None,
    processes: bool,
    options: dict[str, dict[str, Any]],
    writer_options: dict[str, Any],
    settings: dict[str, dict[str, Any]],
    segment: tuple[int | None, int],
    verify: bool,
    delete_source_after_verify: bool,
    progress: bool | Callable[[int, int], None] | None,
    show: bool,
    say: Callable[[str], None],
    warn: Callable[[str], None],
    started: float,
) -> ArchiveSummary:
    manifest = _Manifest(out)
    items: dict[str, ArchiveItem] = {}
    todo: list[tuple[Path, str, int, int]] = []
    for path, rel in inputs:
        size, mtime = _stat(path)
        entry = manifest.entries.get(rel, {})
        item = ArchiveItem(str(path), str(out / rel), "pending", bytes_in=size)
        items[rel] = item
        unchanged = (
            size is not None
            and entry.get("size") == size
            and entry.get("mtime_ns") == mtime
            and entry.get("settings") == settings[rel]
            and (out / rel).is_file()
        )
        if unchanged and entry.get("state") in DONE_STATES:
            if verify and entry.get("state") == "done":
                todo.append((path, rel, size or 0, mtime))  # encoded before, not yet verified
            else:
                item.state = "skipped"
                item.bytes_out = int(entry.get("bytes_out", 0))
                item.frames = int(entry.get("frames", 0))
                _take_camera(item, entry.get("camera"))
            continue
        todo.append((path, rel, size or 0, mtime))
    total = sum(s for _, _, s, _ in todo)
    bar = _ByteProgress(total, show and not callable(progress), sys.stderr)
    bar.inputs = len(todo)

    def advance(n: float) -> None:
        bar.add(n)
        if callable(progress):
            progress(round(bar.done), bar.total)

    stopped: str | None = None
    workers_seen = 0
    dashboard: str | None = None
    if todo:
        with _cluster(scheduler, workers, processes) as client:
            dashboard = _dashboard(client)
            workers_seen = len(client.scheduler_info().get("workers", {}))
            say(f"dashboard: {dashboard}" if dashboard else "dashboard: install bokeh to see it")
            try:
                stopped = _run(
                    client,
                    todo,
                    items,
                    manifest,
                    out,
                    options,
                    writer_options,
                    settings,
                    segment,
                    verify,
                    delete_source_after_verify,
                    advance,
                    bar,
                    warn,
                )
            finally:
                bar.close()
                manifest.save()
    # The cluster is closed, so no task of a failed input writes any more: its parts go.
    for rel, item in items.items():
        if item.state == "failed":
            shutil.rmtree(out / PARTS / rel, ignore_errors=True)
    if stopped is None and manifest.disk_full is not None:
        stopped = manifest.disk_full
    return ArchiveSummary(
        [items[rel] for _, rel in inputs],
        time.perf_counter() - started,
        workers_seen,
        dashboard,
        stopped,
    )


def _take_camera(item: ArchiveItem, camera: Any) -> None:
    """Fill in ``item``'s camera from what :func:`_probe` found (kept in the manifest)."""
    if not isinstance(camera, dict):
        return  # a manifest of an earlier version
    item.camera = camera.get("camera")
    item.camera_from = str(camera.get("camera_from", ""))
    scale = camera.get("depth_scale")
    item.depth_scale = float(scale) if scale is not None else None
    item.depth_scale_from = str(camera.get("depth_scale_from", ""))
    item.notes = [str(n) for n in camera.get("notes", [])]


@dataclass
class _Job:
    path: Path
    rel: str
    size: int
    mtime: int
    parts: list[Path] = field(default_factory=list)
    plan: list[tuple[int, int | None]] = field(default_factory=list)
    remaining: int = 0
    colors: dict[int, list[str]] = field(default_factory=dict)
    frames: int = 0
    futures: list[Any] = field(default_factory=list)
    retried_whole: bool = False


def _run(
    client: Any,
    todo: list[tuple[Path, str, int, int]],
    items: dict[str, ArchiveItem],
    manifest: _Manifest,
    out: Path,
    options: dict[str, dict[str, Any]],
    writer_options: dict[str, Any],
    settings: dict[str, dict[str, Any]],
    segment: tuple[int | None, int],
    verify: bool,
    delete_source: bool,
    advance: Callable[[float], None],
    bar: _ByteProgress,
    warn: Callable[[str], None],
) -> str | None:
    import importlib

    as_completed: Any = importlib.import_module("distributed").as_completed
    jobs: dict[str, _Job] = {}
    what: dict[Any, tuple[str, str, int]] = {}  # future key -> (rel, step, segment)
    pool = as_completed()

    def submit(rel: str, step: str, seg: int, fn: Callable[..., Any], *args: Any) -> None:
        # Joins and verifications first: they finish inputs and free their segment files.
        priority = {"probe": 0, "segment": 1, "join": 2, "verify": 3}[step]
        fut = client.submit(
            fn, *args, key=f"{step}-{uuid.uuid4().hex}", pure=False, priority=priority
        )
        what[fut.key] = (rel, step, seg)
        jobs[rel].futures.append(fut)
        pool.add(fut)

    for path, rel, size, mtime in todo:
        jobs[rel] = _Job(path, rel, size, mtime)
        entry = manifest.entries.get(rel, {})
        if entry.get("state") == "done" and entry.get("settings") == settings[rel] and verify:
            items[rel].state = "done"
            items[rel].bytes_out = int(entry.get("bytes_out", 0))
            items[rel].frames = int(entry.get("frames", 0))
            _take_camera(items[rel], entry.get("camera"))
            submit(rel, "verify", 0, _verify, str(path), options[rel], str(out / rel), None)
            advance(size)
            continue
        submit(rel, "probe", 0, _probe, str(path), options[rel], *segment)

    def fail(rel: str, exc: BaseException) -> None:
        job = jobs[rel]
        for f in job.futures:
            f.cancel()
        item = items[rel]
        item.state = "failed"
        item.error = (
            f"{type(exc).__name__}: {exc}" if not isinstance(exc, PcdcodecError) else str(exc)
        )
        manifest.update(rel, state="failed", error=item.error)
        shutil.rmtree(out / PARTS / rel, ignore_errors=True)
        bar.inputs_done += 1

    stopped: str | None = None
    for fut in pool:
        rel, step, seg = what.pop(fut.key)
        job = jobs[rel]
        if items[rel].state == "failed" or fut.status == "cancelled":
            if items[rel].state == "failed":
                # A segment already running when its input failed cannot be cancelled: what it
                # wrote after the failure goes now.
                shutil.rmtree(out / PARTS / rel, ignore_errors=True)
            continue
        exc = fut.exception() if fut.status == "error" else None
        if exc is not None:
            if (
                step == "join"
                and isinstance(exc, InputError)
                and "cannot follow" in str(exc)
                and not job.retried_whole
            ):
                # Segments whose codec set-up differs cannot be joined: encode the input whole.
                job.retried_whole = True
                shutil.rmtree(out / PARTS / rel, ignore_errors=True)
                job.plan, job.remaining, job.colors = [(0, None)], 1, {}
                job.parts = [out / PARTS / rel / "whole.pcdc"]
                submit(
                    rel,
                    "segment",
                    0,
                    _encode_segment,
                    str(job.path),
                    options[rel],
                    str(job.parts[0]),
                    0,
                    None,
                    writer_options,
                    verify,
                )
                continue
            full = _disk_full(exc, out)
            fail(rel, full if full is not None else exc)
            if full is not None and stopped is None:
                stopped = str(full)
                # Joins under way are let finish: they free their segments' space, and
                # their outputs are complete.
                for other in jobs.values():
                    for f in other.futures:
                        if f.key in what and what[f.key][1] != "join":
                            f.cancel()
            continue
        if stopped is not None and step != "join":
            continue  # a join that finished anyway left a complete output: record it
        result = fut.result()
        fut.release()
        if step == "probe":
            _take_camera(items[rel], result["camera"])
            for note in result["camera"]["notes"]:
                warn(f"warning: {job.path}: {note}")
            entry = manifest.entries.get(rel, {})
            plan = segment_plan(result["frames"], result["size"] or 0, *segment)
            index = result.get("index") if len(plan) > 1 else None
            parts_dir = out / PARTS / rel
            same = (
                entry.get("hash") == result["hash"]
                and entry.get("settings") == settings[rel]
                and [tuple(s) for s in entry.get("segments", [])] == plan
            )
            if not same:
                shutil.rmtree(parts_dir, ignore_errors=True)
            job.plan = plan
            job.parts = [parts_dir / f"seg-{i:05d}.pcdc" for i in range(len(plan))]
            manifest.update(
                rel,
                source=str(job.path),
                size=result["size"],
                mtime_ns=result["mtime_ns"],
                hash=result["hash"],
                frames=result["frames"],
                segments=[list(s) for s in plan],
                settings=settings[rel],
                camera=result["camera"],
                state="encoding",
                error=None,
            )
            for i, (start, stop) in enumerate(plan):
                job.remaining += 1
                if same and job.parts[i].is_file():
                    # Written by an earlier run, and complete: it was renamed when done.
                    submit(rel, "segment", i, _existing_segment, str(job.parts[i]), verify)
                    continue
                submit(
                    rel,
                    "segment",
                    i,
                    _encode_segment,
                    str(job.path),
                    options[rel],
                    str(job.parts[i]),
                    start,
                    stop,
                    writer_options,
                    verify,
                    index.slice(start, stop) if index is not None else None,
                )
        elif step == "segment":
            job.remaining -= 1
            job.colors[seg] = result["colors"]
            job.frames += result["frames"]
            start, stop = job.plan[seg]
            n = manifest.entries[rel].get("frames")
            advance(job.size * result["frames"] / n if n else job.size)
            if job.remaining == 0:
                submit(rel, "join", 0, _join_parts, [str(p) for p in job.parts], str(out / rel))
        elif step == "join":
            shutil.rmtree(out / PARTS / rel, ignore_errors=True)
            item = items[rel]
            item.state, item.bytes_out = "done", result["bytes"]
            item.frames = job.frames or int(manifest.entries[rel].get("frames") or 0)
            item.segments = len(job.plan)
            manifest.update(rel, state="done", bytes_out=item.bytes_out, frames=item.frames)
            if verify and stopped is None:
                colors = (
                    [c for i in sorted(job.colors) for c in job.colors[i]]
                    if writer_options["color"] is not None and len(job.colors) == len(job.plan)
                    else None
                )
                submit(
                    rel, "verify", 0, _verify, str(job.path), options[rel], str(out / rel), colors
                )
            else:
                bar.inputs_done += 1
        elif step == "verify":
            item = items[rel]
            item.state = "verified"
            manifest.update(rel, state="verified")
            if delete_source:
                try:
                    if job.path.is_dir() and not job.path.is_symlink():
                        shutil.rmtree(job.path)
                    else:  # a file, or a link (to a file or a folder): the link goes
                        job.path.unlink()
                except OSError as err:
                    item.error = f"verified, but the source could not be deleted: {err}"
                else:
                    item.state = "source-deleted"
                    manifest.update(rel, state="source-deleted")
            bar.inputs_done += 1
        manifest.save(force=False)
    manifest.save()
    return stopped
