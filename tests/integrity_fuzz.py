"""Fuzz cases past one recording read alone: joins of damaged parts, and Zarr format 2 chunks.

What ``tests/test_fuzz_integrity.py`` and ``python -m tests.run_fuzz_integrity`` run (rig files are
among ``tests/recording_fuzz.py``'s codec pairs, read alone and, here, joined).

* A join case mutates the second of two clean parts of one recording (a case of
  :func:`tests.recording_fuzz.mutate`) and joins the two. It passes when the join refuses with a
  :class:`~pcdcodec.PcdcodecError` naming the damaged part and leaves no output, or when the
  joined file verifies and gives every frame of both clean parts, bit for bit, with their
  settings.
* A Zarr case replaces one chunk of a Zarr format 2 array (a depth numcodec its compressor)
  with other bytes: the chunk's bytes mutated (:func:`tests.fuzzing.mutate`), or a frame of
  another shape, another dtype, or another codec, or nothing. It passes when reading the frame
  gives it back exactly or raises a :class:`~pcdcodec.PcdcodecError`. (Zarr calls the codec
  without the chunk's key, so the error names the codec and what the chunk holds.)

Everything is seeded: case ``k`` of seed ``s`` is the same on every run.
"""

from __future__ import annotations

import os
import shutil
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.depth import FrameCodec
from pcdcodec.recording.join import join

from .fuzzing import mutate as mutate_frame
from .recording_fuzz import STEP, Clean, Result, make_clean, mutate, settings_of, watchdog

JOIN_OK = ("joined-right", "refused-naming-part")
ZARR_OK = ("identical", "detected")


@dataclass
class JoinParts:
    """Two clean parts of one recording: ``second`` starts 10 s after ``first``."""

    first: Clean
    second: Clean


def make_join_parts(name: str, folder: Path) -> JoinParts:
    return JoinParts(
        make_clean(name, folder, stem="first"),
        make_clean(name, folder, offset_ns=10**10, stem="second"),
    )


def join_case(parts: JoinParts, seed: int, case: int, folder: Path, timeout: float = 60) -> Result:
    """Case ``case`` of ``seed``: the second part mutated, then joined after the first."""
    data, what = mutate(parts.second, seed, case)
    part = folder / f"part-{os.getpid()}.pcdc"
    part.write_bytes(data)
    out = folder / f"joined-{os.getpid()}.pcdc"
    out.unlink(missing_ok=True)
    with watchdog(timeout, what):
        result = _check_join(parts, part, out)
    result.detail = f"join, {what}: {result.detail}"
    return result


def _same(expected: tuple[Any, Any], frame: Any) -> bool:
    color, depth = expected
    same_color = (color is None and frame.color is None) or (
        color is not None and frame.color is not None and np.array_equal(color, frame.color)
    )
    return same_color and depth.dtype == frame.depth.dtype and np.array_equal(depth, frame.depth)


def _check_join(parts: JoinParts, part: Path, out: Path) -> Result:
    try:
        join([parts.first.path, part], out)
    except pcdcodec.PcdcodecError as exc:
        if out.exists():
            return Result("LEFT-OUTPUT", str(exc))
        if str(part) not in str(exc):
            return Result("ERROR-NOT-NAMING-PART", f"{type(exc).__name__}: {exc}")
        return Result("refused-naming-part", str(exc))
    except Exception as exc:
        return Result("FOREIGN-EXCEPTION", f"join: {type(exc).__name__}: {exc}")
    expected = {**parts.first.frames, **parts.second.frames}
    try:
        with pcdcodec.open(out) as rec:
            if settings_of(rec) != parts.first.settings:
                return Result("WRONG-SETTINGS", f"{settings_of(rec)} != {parts.first.settings}")
            report = rec.verify()
            if not report.ok:
                return Result("JOINED-BAD", "; ".join(report.errors[:3]))
            got = 0
            for name in rec.camera_names:
                for frame in rec.frames(name):
                    want = expected.get((name, frame.timestamp_ns))
                    if want is None:
                        return Result("WRONG-TIMESTAMP", f"{name} t={frame.timestamp_ns}")
                    if not _same(want, frame):
                        return Result("WRONG-FRAME", f"{name} t={frame.timestamp_ns} differs")
                    got += 1
            if got != len(expected):
                return Result("SILENT-LOSS", f"{got} of {len(expected)} frames")
    except pcdcodec.PcdcodecError as exc:
        return Result("JOINED-BAD", f"{type(exc).__name__}: {exc}")
    except Exception as exc:
        return Result("FOREIGN-EXCEPTION", f"reading the joined file: {type(exc).__name__}: {exc}")
    return Result("joined-right")


# -- Zarr format 2 --------------------------------------------------------------------------------

ZARR_FRAMES = 4
ZARR_KINDS = ("mutate", "mutate", "mutate", "transposed", "float32", "other-codec", "empty")


@dataclass
class ZarrClean:
    """A Zarr format 2 array of depth frames at ``path``, one frame per chunk, ``name`` the
    depth codec of its compressor, and each chunk's bytes as written."""

    name: str
    path: Path
    frames: Any
    chunks: list[bytes]


def _frames() -> Any:
    sample = pcdcodec.load_sample(max_frames=ZARR_FRAMES)
    return np.stack([np.ascontiguousarray(f.depth[::STEP, ::STEP]) for f in sample])


def make_zarr(name: str, folder: Path) -> ZarrClean:
    """Write the clean Zarr format 2 array of depth codec ``name``."""
    import zarr

    from pcdcodec.zarr.numcodecs import numcodec

    frames = _frames()
    path = folder / f"zarr-{name}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Zarr warns that v2 arrays are not the newest format
        array = zarr.create_array(
            zarr.storage.LocalStore(path),
            shape=frames.shape,
            chunks=(1, *frames.shape[1:]),
            dtype=frames.dtype,
            zarr_format=2,
            filters=None,
            compressors=numcodec(name),
            fill_value=0,
        )
        array[:] = frames
    chunks = [(path / f"{i}.0.0").read_bytes() for i in range(len(frames))]
    return ZarrClean(name, path, frames, chunks)


def zarr_case(clean: ZarrClean, seed: int, case: int, folder: Path, timeout: float = 60) -> Result:
    """Case ``case`` of ``seed``: one chunk of a copy of the array replaced, the frame read."""
    import zarr

    rng = np.random.default_rng([seed, case, 3])
    own = folder / f"{clean.path.name}-{os.getpid()}"
    if not own.exists():
        shutil.copytree(clean.path, own)
    i = int(rng.integers(len(clean.frames)))
    kind = ZARR_KINDS[int(rng.integers(len(ZARR_KINDS)))]
    codec = pcdcodec.get_codec(clean.name, kind="depth")
    assert isinstance(codec, FrameCodec)
    frame = clean.frames[i]
    if kind == "mutate":
        how, data = mutate_frame(clean.chunks[i], rng, clean.chunks[(i + 1) % len(clean.chunks)])
        kind = f"mutate-{how}"
    elif kind == "transposed":
        data = codec.encode(np.ascontiguousarray(frame.T))
    elif kind == "float32":
        metres = (frame / 1000.0).astype(np.float32)
        floats = codec if "float32" in codec.dtypes else pcdcodec.get_codec("zstd", kind="depth")
        assert isinstance(floats, FrameCodec)
        data = floats.encode(metres)
    elif kind == "other-codec":
        names = [n for n in pcdcodec.list_codecs("depth") if n != clean.name]
        other = pcdcodec.get_codec(names[int(rng.integers(len(names)))], kind="depth")
        assert isinstance(other, FrameCodec)
        data = other.encode(np.ascontiguousarray(frame.T if rng.random() < 0.5 else frame))
        kind = f"other-codec-{other.name}"
    else:
        data = b""
    what = f"zarr {clean.name} case {case} seed {seed} ({kind}): chunk {i}"
    chunk = own / f"{i}.0.0"
    chunk.write_bytes(data)
    try:
        with watchdog(timeout, what), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            array = zarr.open_array(zarr.storage.LocalStore(own), mode="r")
            try:
                got = array[i]
            except pcdcodec.PcdcodecError as exc:
                return Result("detected", f"{what}: {type(exc).__name__}: {exc}")
            except Exception as exc:
                return Result("FOREIGN-EXCEPTION", f"{what}: {type(exc).__name__}: {exc}")
    finally:
        chunk.write_bytes(clean.chunks[i])
    if got.shape == frame.shape and got.dtype == frame.dtype and np.array_equal(got, frame):
        return Result("identical", what)
    return Result("WRONG-DATA", f"{what}: read back {got.dtype} {got.shape}, not the frame")
