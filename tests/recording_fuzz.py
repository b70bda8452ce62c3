"""Mutated recordings: what ``tests/test_fuzz_recording.py`` and ``run_fuzz_recordings.py`` run.

A clean recording is written for each codec pair and decoded once. Each case changes its bytes
(bit flips, overwrites, zeroed or special values, truncation, deletion, duplication), most of
them aimed at the parts that say how to read the rest: the header, the metadata records, record
headers and lengths, the summary and the footer. A quarter of the cases change whole records
instead (remove, swap, duplicate, move or retime a message, swap two payloads, drop a metadata
record, write the file unchunked) and write the file anew, every CRC and the summary matching.
The mutant is then opened, every frame decoded and compared with the clean file's frame of the
same timestamp, and ``verify()`` run.

A case passes when only :class:`~pcdcodec.PcdcodecError` subclasses were raised, every frame
that came back equals the clean one, the settings equal the clean ones, and frames are missing
only where the file says so (an error, a failing ``verify()``, or a file that reads as
unfinished because its end was cut off). Everything is seeded: case ``k`` of seed ``s`` is the
same mutation on every run (given the same clean file).
"""

from __future__ import annotations

import faulthandler
import io
import os
import struct
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec
from pcdcodec.recording.rewrite import read, write

#: name -> writer options; small frames so a case takes milliseconds.
CONFIGS: dict[str, dict[str, Any]] = {
    "h264+jpegxl": {"color": "h264", "depth": "jpegxl"},
    "ffv1+zstd": {"color": "ffv1", "depth": "zstd"},
    "mjpeg+lz4": {"color": "mjpeg", "depth": "lz4"},
    "png16": {"color": None, "depth": "png16"},
    # Two cameras in one file (format version 3): each camera's frames checked on their own.
    "rig": {"color": "h264", "depth": "jpegxl", "rig": True},
}
FRAMES = 8
STEP = 10  # 640x480 sample frames, every 10th pixel: 64x48

#: outcomes that are fine; anything else is a failure
OK_OUTCOMES = ("identical", "detected-at-open", "detected", "read-as-unfinished")


@dataclass
class Clean:
    name: str
    path: Path
    data: bytes
    frames: dict[tuple[str, int], tuple[Any, Any]]  # (camera, timestamp) -> (color, depth)
    settings: dict[str, Any]
    regions: list[tuple[int, int, str]]
    #: the records of the data section, for the structural mutations
    contents: Any = None


@dataclass
class Result:
    outcome: str
    detail: str = ""
    frames_read: int = 0
    errors: list[str] = field(default_factory=list)


def settings_of(rec: Any) -> dict[str, Any]:
    """Every camera's settings (a one-camera recording has one camera) and the metadata."""
    out: dict[str, Any] = {"metadata": rec.metadata}
    for name in rec.camera_names:
        cam = rec.frames(name)
        out[name] = {
            "intrinsics": cam.intrinsics,
            "depth_scale": cam.depth_scale,
            "fps": cam.fps,
            "codecs": cam.codecs,
            "rig_pose": rec.rig_poses[name].tolist(),
        }
    return out


def make_clean(name: str, folder: Path, offset_ns: int = 0, stem: str = "clean") -> Clean:
    """Write and decode the clean recording of one codec pair (its timestamps ``offset_ns``
    later than the sample's: a later part of the same recording, for join)."""
    sample = pcdcodec.load_sample(max_frames=FRAMES)
    cam = sample.intrinsics
    intrinsics = pcdcodec.CameraIntrinsics(
        cam.width // STEP,
        cam.height // STEP,
        cam.fx / STEP,
        cam.fy / STEP,
        cam.cx / STEP,
        cam.cy / STEP,
    )
    path = folder / f"{stem}-{name.replace('+', '-')}.pcdc"
    options = dict(CONFIGS[name])
    if options.pop("rig", False):
        pose = np.eye(4)
        pose[:3, 3] = [0.1, -0.2, 0.3]
        specs = [
            pcdcodec.CameraSpec("a", intrinsics, sample.depth_scale, **options),
            pcdcodec.CameraSpec(
                "b", intrinsics, 1000.0, color=None, depth="zstd", fps=15.0, rig_pose=pose
            ),
        ]
        with pcdcodec.RigWriter(path, specs, metadata={"site": "lab"}) as rig:
            for k, f in enumerate(sample):
                depth = np.ascontiguousarray(f.depth[::STEP, ::STEP])
                color = np.ascontiguousarray(f.color[::STEP, ::STEP])
                rig.write("a", color, depth, f.timestamp_ns + offset_ns)
                if k % 2 == 0:
                    rig.write("b", None, depth, f.timestamp_ns + offset_ns + 5_000_000)
        return load_clean(name, path)
    with pcdcodec.open(
        path,
        "w",
        intrinsics=intrinsics,
        depth_scale=sample.depth_scale,
        metadata={"site": "lab", "run": 7},
        overwrite=True,
        **options,
    ) as rec:
        for f in sample:
            color = np.ascontiguousarray(f.color[::STEP, ::STEP]) if options["color"] else None
            depth = np.ascontiguousarray(f.depth[::STEP, ::STEP])
            rec.write(color, depth, f.timestamp_ns + offset_ns)
    return load_clean(name, path)


def load_clean(name: str, path: Path) -> Clean:
    """A clean recording written before (by :func:`make_clean`), decoded."""
    with pcdcodec.open(path) as rec:
        frames = {
            (name, f.timestamp_ns): (f.color, f.depth)
            for name in rec.camera_names
            for f in rec.frames(name)
        }
        settings = settings_of(rec)
        expected = FRAMES + (FRAMES + 1) // 2 if len(rec.camera_names) == 2 else FRAMES
        if len(frames) != expected or not rec.verify().ok:
            raise RuntimeError(f"{path} is not a clean {expected}-frame recording")
    data = path.read_bytes()
    return Clean(name, path, data, frames, settings, regions(data), read(path))


def regions(data: bytes) -> list[tuple[int, int, str]]:
    """(start, end, kind) of the parts of an MCAP file that mutations aim at."""
    out = [(0, 8, "magic")]
    pos = 8
    in_summary = False
    end = len(data) - 8 - 29
    names = {0x01: "header", 0x0C: "metadata", 0x07: "message-index", 0x0F: "data-end"}
    while pos + 9 <= end:
        opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        stop = min(pos + 9 + length, end)
        if in_summary:
            out.append((pos, stop, "summary"))
        elif opcode == 0x06:
            out.append((pos, min(pos + 9 + 48, stop), "record-head"))
            out.append((pos + 9 + 48, stop, "chunk-body"))
        else:
            out.append((pos, stop, names.get(opcode, "record")))
            if opcode != 0x0C:
                out.append((pos, min(pos + 9, stop), "record-head"))
        if opcode == 0x0F:
            in_summary = True
        pos += 9 + length
    out.append((end, len(data), "footer"))
    return out


#: how often each kind of region is aimed at; the rest of the weight hits anywhere
AIM = {
    "metadata": 0.2,
    "summary": 0.22,
    "footer": 0.08,
    "record-head": 0.15,
    "header": 0.04,
    "chunk-body": 0.06,
    "data-end": 0.02,
    "magic": 0.01,
}
OPERATORS = ("flip", "overwrite", "zero", "special", "truncate", "delete", "duplicate")


#: the share of cases that change whole records, every CRC and the summary made to match
STRUCTURAL = 0.25
STRUCTURAL_OPERATORS = (
    "remove",
    "swap",
    "duplicate",
    "move",
    "swap-payloads",
    "retime",
    "unchunked",
    "drop-metadata",
)


def mutate_structure(clean: Clean, rng: np.random.Generator) -> tuple[bytes, str]:
    """Remove, swap, duplicate, move or retime whole MCAP messages (or swap the payloads of
    two on one channel, drop a metadata record, or write the file unchunked), then write the
    file anew with the ``mcap`` library, so that every CRC, offset and the summary agree."""
    contents = replace(
        clean.contents,
        metadata=list(clean.contents.metadata),
        messages=list(clean.contents.messages),
    )
    ms = contents.messages
    n = len(ms)
    op = STRUCTURAL_OPERATORS[rng.integers(len(STRUCTURAL_OPERATORS))]
    k, other = int(rng.integers(n)), int(rng.integers(n))
    chunked = True
    what = f"{op} message {k} ({ms[k].topic} t={ms[k].log_time})"
    if op == "remove":
        del ms[k]
    elif op == "swap":
        ms[k], ms[other] = ms[other], ms[k]
        what += f" with message {other}"
    elif op == "duplicate":
        ms.insert(other, ms[k])
        what += f" at {other}"
    elif op == "move":
        ms.insert(other, ms.pop(k))
        what += f" to {other}"
    elif op == "swap-payloads":
        same = [j for j, m in enumerate(ms) if m.topic == ms[k].topic and j != k]
        if same:
            other = same[int(rng.integers(len(same)))]
            ms[k], ms[other] = (
                replace(ms[k], data=ms[other].data),
                replace(ms[other], data=ms[k].data),
            )
        what += f" with message {other}"
    elif op == "retime":
        delta = [-1, 1, -33_333_333, 33_333_333, 10**9][int(rng.integers(5))]
        ms[k] = replace(ms[k], log_time=max(0, ms[k].log_time + delta))
        what += f" by {delta} ns"
    elif op == "unchunked":
        chunked = False
        what = "unchunked"
    else:
        j = int(rng.integers(len(contents.metadata)))
        what = f"drop metadata record {contents.metadata[j][0]!r}"
        del contents.metadata[j]
    out = io.BytesIO()
    write(contents, out, chunked=chunked)
    return out.getvalue(), what


def mutate(clean: Clean, seed: int, case: int) -> tuple[bytes, str]:
    """Case ``case`` of ``seed``: the mutant's bytes and a description to reproduce it by."""
    if clean.contents is not None and np.random.default_rng([seed, case, 1]).random() < STRUCTURAL:
        data, what = mutate_structure(clean, np.random.default_rng([seed, case, 2]))
        return data, f"{clean.name} case {case} seed {seed} (structure): {what}"
    rng = np.random.default_rng([seed, case])
    data = bytearray(clean.data)
    n = len(data)
    kinds = [*AIM, "anywhere"]
    weights = np.array([*AIM.values(), 1 - sum(AIM.values())])
    kind = kinds[rng.choice(len(kinds), p=weights / weights.sum())]
    spans = [(a, b) for a, b, k in clean.regions if k == kind and b > a]
    a, b = spans[rng.integers(len(spans))] if spans else (0, n)
    pos = int(rng.integers(a, b))
    op = OPERATORS[rng.integers(len(OPERATORS))]
    if op == "flip":
        bits = int(rng.integers(1, 4))
        for _ in range(bits):
            p = min(n - 1, pos + int(rng.integers(0, 8)))
            data[p] ^= 1 << int(rng.integers(8))
        what = f"flip {bits} bit(s) near {pos}"
    elif op == "overwrite":
        size = int(rng.integers(1, 9))
        data[pos : pos + size] = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        what = f"overwrite {size} byte(s) at {pos}"
    elif op == "zero":
        size = int(rng.integers(1, 33))
        end = min(n, pos + size)
        data[pos:end] = bytes(end - pos)
        what = f"zero {end - pos} byte(s) at {pos}"
    elif op == "special":
        value = [
            b"\xff" * 8,
            b"\x00" * 8,
            struct.pack("<Q", 2**63),
            struct.pack("<Q", 2**32),
            struct.pack("<I", 2**31),
            struct.pack("<Q", n),
            struct.pack("<Q", 1),
        ][int(rng.integers(7))]
        data[pos : pos + len(value)] = value
        del data[n:]
        what = f"write {value.hex()} at {pos}"
    elif op == "truncate":
        del data[pos:]
        what = f"truncate at {pos}"
    elif op == "delete":
        size = int(rng.integers(1, 65))
        del data[pos : pos + size]
        what = f"delete {size} byte(s) at {pos}"
    else:
        size = int(rng.integers(1, 129))
        src = int(rng.integers(0, n))
        piece = bytes(data[src : src + size])
        data[pos:pos] = piece
        what = f"insert a copy of {len(piece)} byte(s) from {src} at {pos}"
    return bytes(data), f"{clean.name} case {case} seed {seed} ({kind}): {what}"


def check(clean: Clean, path: Path) -> Result:
    """Open, decode and verify the mutant at ``path``; classify what happened."""
    try:
        rec = pcdcodec.open(path)
    except pcdcodec.PcdcodecError as exc:
        return Result("detected-at-open", str(exc))
    except Exception as exc:
        return Result("FOREIGN-EXCEPTION", f"open: {type(exc).__name__}: {exc}")
    try:
        with rec:
            if settings_of(rec) != clean.settings:
                return Result("WRONG-SETTINGS", f"{settings_of(rec)} != {clean.settings}")
            result = Result("identical")
            failed = 0
            total = 0
            for name in rec.camera_names:
                cam = rec.frames(name)
                total += len(cam)
                for i in range(len(cam)):
                    try:
                        frame = cam[i]
                    except pcdcodec.PcdcodecError as exc:
                        failed += 1
                        result.errors.append(str(exc))
                        continue
                    expected = clean.frames.get((name, frame.timestamp_ns))
                    if expected is None:
                        return Result(
                            "WRONG-TIMESTAMP", f"{name} frame {i} at t={frame.timestamp_ns}"
                        )
                    color, depth = expected
                    same_color = (color is None and frame.color is None) or (
                        color is not None
                        and frame.color is not None
                        and np.array_equal(color, frame.color)
                    )
                    if not same_color or not (
                        depth.dtype == frame.depth.dtype and np.array_equal(depth, frame.depth)
                    ):
                        return Result(
                            "WRONG-FRAME", f"{name} frame {i} at t={frame.timestamp_ns} differs"
                        )
                    result.frames_read += 1
            report = rec.verify()
            if failed and report.ok:
                return Result("VERIFY-MISSED-ERRORS", f"{failed} frames failed, verify says OK")
            if total > len(clean.frames):
                return Result("EXTRA-FRAMES", f"{total} frames, the clean file has fewer")
            if report.ok and total < len(clean.frames):
                if rec.index.indexed:
                    return Result("SILENT-LOSS", f"{total} of {len(clean.frames)} frames")
                result.outcome = "read-as-unfinished"
            elif not report.ok or failed:
                result.outcome = "detected"
                result.errors.extend(report.errors)
            return result
    except pcdcodec.PcdcodecError as exc:
        return Result("ESCAPED-PCDCODEC-ERROR", f"{type(exc).__name__}: {exc}")
    except Exception as exc:
        return Result("FOREIGN-EXCEPTION", f"{type(exc).__name__}: {exc}")


@contextmanager
def watchdog(seconds: float, what: str) -> Iterator[None]:
    """Dump every thread's stack and exit the process if the block takes over ``seconds``."""

    def fire() -> None:
        sys.stderr.write(f"\nHANG: {what} took over {seconds} s; stacks of all threads:\n")
        sys.stderr.flush()
        faulthandler.dump_traceback(all_threads=True)
        os._exit(3)

    timer = threading.Timer(seconds, fire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def run_case(clean: Clean, seed: int, case: int, folder: Path, timeout: float = 60.0) -> Result:
    data, what = mutate(clean, seed, case)
    path = folder / f"mutant-{os.getpid()}.pcdc"
    path.write_bytes(data)
    with watchdog(timeout, what):
        result = check(clean, path)
    result.detail = f"{what}: {result.detail}"
    return result
