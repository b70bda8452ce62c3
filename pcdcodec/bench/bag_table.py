"""One row of the whole-bag table: what a bag costs as a ``.pcdc`` and under its peers, what
its kept topics cost, and how fast and in how much memory it is encoded and exported.

:func:`measure_bag` encodes the bag with :func:`pcdcodec.encode` at the defaults (every other
topic kept) and exports the recording back to a bag of the kind it came in
(``pcdcodec export REC OUT --to rosbag1|rosbag2``), each in a process of its own
(:func:`run_child`), so that each gets its own wall time and peak resident memory. It then runs
the peers of :mod:`~pcdcodec.bench.bag_peers` on the bag (MCAP zstd at the default level and at
19, ROS 1 lz4 for a ROS 1 bag, Cloudini when the bag holds a PointCloud2 topic), and writes the
kept topics alone under MCAP zstd at the default level to compare their chunks with the kept
chunks of the ``.pcdc`` (:func:`chunk_bytes`). Every file it writes goes under a given folder
and is removed as soon as it is measured.

Run as ``python -m pcdcodec.bench.bag_table OP JSON``, it is the child process of
:func:`run_child` and prints one JSON line.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError, PcdcodecError
from . import bag_peers

__all__ = [
    "PEERS",
    "BagRow",
    "Child",
    "bag_kind",
    "chunk_bytes",
    "measure_bag",
    "peak_rss_bytes",
    "remove_output",
    "run_child",
    "table",
]

#: The peers measured, by the name the table and ``peers=`` give them.
PEERS = ("zstd1", "zstd19", "lz4", "cloudini")
_CLOUD = {"sensor_msgs/msg/PointCloud2", "sensor_msgs/PointCloud2"}


@dataclass(frozen=True)
class Child:
    """One encode or export run in a process of its own: its wall ``seconds`` (the work only,
    not the interpreter's start), the process's peak resident memory, and what it reported."""

    seconds: float
    peak_rss_bytes: int
    info: dict[str, Any]


def run_child(op: str, **kwargs: Any) -> Child:
    """Run ``op`` (``encode`` or ``export``) with ``kwargs`` in a fresh Python process."""
    root = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    proc = subprocess.run(
        [sys.executable, "-m", "pcdcodec.bench.bag_table", op, json.dumps(kwargs)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise PcdcodecError(f"{op} failed (exit {proc.returncode}): {tail}")
    out = json.loads(lines[-1])
    return Child(out.pop("seconds"), out.pop("peak_rss_bytes"), out)


def _child(op: str, kwargs: dict[str, Any]) -> dict[str, Any]:
    import pcdcodec

    if op == "encode":
        start = time.perf_counter()
        summary = pcdcodec.encode(kwargs["bag"], kwargs["out"], **kwargs["options"])
        seconds = time.perf_counter() - start
        with pcdcodec.open(kwargs["out"]) as rec:
            duration = rec.duration
            kept = [t.topic for t in rec.kept_topics]
        return {
            "seconds": seconds,
            "frames": summary.frames,
            "bytes": summary.bytes,
            "duration": duration,
            "kept": kept,
        }
    if op == "export":  # what `pcdcodec export REC OUT --to ... [--storage ...]` runs
        start = time.perf_counter()
        pcdcodec.export_bag(kwargs["rec"], kwargs["out"], **kwargs["options"])
        seconds = time.perf_counter() - start
        return {"seconds": seconds, "bytes": bag_peers.bag_bytes(kwargs["out"])}
    raise InputError(f"unknown operation {op!r}; known: encode, export")


def bag_kind(path: str | os.PathLike[str]) -> str:
    """``ros1``, ``ros2-sqlite3``, ``ros2-mcap`` (a folder or one file) or ``mkv``."""
    p = Path(path)
    if p.is_dir():
        import yaml

        meta = yaml.safe_load((p / "metadata.yaml").read_text())
        return "ros2-" + str(meta["rosbag2_bagfile_information"]["storage_identifier"])
    if p.suffix.lower() in (".mkv", ".mka"):
        return "mkv"
    with p.open("rb") as f:
        head = f.read(16)
    if head.startswith(b"#ROSBAG"):
        return "ros1"
    return "ros2-sqlite3" if p.suffix == ".db3" else "ros2-mcap"


def _topic_types(path: Path) -> dict[str, str]:
    from ..ros import bagfile

    reader, tmp = bagfile.open_reader(path)
    try:
        return {c.topic: c.msgtype for c in reader.connections}
    finally:
        reader.close()
        if tmp is not None:
            tmp.cleanup()


def chunk_bytes(path: str | os.PathLike[str], pick: Callable[[Any], bool]) -> int:
    """The bytes of an MCAP file's chunks (each record with its message indexes) that hold the
    channels ``pick`` chooses. Raises :class:`~pcdcodec.InputError` for a chunk that mixes
    chosen channels with others (its bytes cannot be shared out)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    if summary is None:
        raise InputError(f"{str(path)!r} has no summary to list its chunks")
    total = 0
    for ci in summary.chunk_indexes:
        ids = set(ci.message_index_offsets)
        chosen = {i for i in ids if pick(summary.channels[i])}
        if not chosen:
            continue
        if chosen != ids:
            raise InputError(f"{str(path)!r}: a chunk mixes chosen channels with others")
        total += ci.chunk_length + ci.message_index_length
    return total


@dataclass
class BagRow:
    """Every figure of one bag's row (bytes; ``None`` where the measure does not apply)."""

    name: str
    kind: str
    bytes: int
    pcdc: int | None = None
    frames: int = 0
    duration: float = 0.0
    encode: Child | None = None
    export: Child | None = None
    peers: dict[str, int | None] = field(default_factory=dict)
    kept_topics: list[str] = field(default_factory=list)
    kept_pcdc: int | None = None
    kept_zstd1: int | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def bag_fps(self) -> float | None:
        """The bag's frame rate, from the recorded frames' times."""
        return (self.frames - 1) / self.duration if self.frames > 1 and self.duration else None


def _export_options(kind: str) -> dict[str, str] | None:
    """The bag a recording of a ``kind`` bag is exported to: the same kind."""
    if kind == "ros1":
        return {"to": "rosbag1"}
    if kind.startswith("ros2-"):
        return {"to": "rosbag2", "storage": kind.removeprefix("ros2-")}
    return None


def remove_output(path: Path) -> None:
    import shutil

    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists():
        path.unlink()


def _sized(out: Path, make: Callable[[Path], Any]) -> int:
    try:
        make(out)
        return bag_peers.bag_bytes(out)
    finally:
        remove_output(out)


def measure_bag(
    bag: str | os.PathLike[str],
    work: str | os.PathLike[str],
    *,
    name: str | None = None,
    options: dict[str, Any] | None = None,
    peers: Sequence[str] = PEERS,
    export: bool = True,
    log: Callable[[str], None] = lambda line: None,
) -> BagRow:
    """Measure the bag at ``bag`` (see the module's text), writing under the folder ``work``.
    ``options`` go to :func:`pcdcodec.encode` (a camera the bag lacks, ...); ``peers`` picks
    among :data:`PEERS`. A step that fails leaves its cells empty and a note in the row."""
    path, work = Path(bag), Path(work)
    unknown = set(peers) - set(PEERS)
    if unknown:
        raise InputError(f"unknown peers {sorted(unknown)}; known: {', '.join(PEERS)}")
    kind = bag_kind(path)
    row = BagRow(name or path.name, kind, bag_peers.bag_bytes(path))
    rec = work / f"{path.stem}.pcdc"
    try:
        log(f"{row.name}: encode")
        opts = {"overwrite": True, **(options or {})}
        row.encode = run_child("encode", bag=str(path), out=str(rec), options=opts)
        row.pcdc = row.encode.info["bytes"]
        row.frames = row.encode.info["frames"]
        row.duration = row.encode.info["duration"]
        row.kept_topics = row.encode.info["kept"]
        if row.kept_topics:
            row.kept_pcdc = chunk_bytes(rec, lambda ch: "pcdcodec.kept" in ch.metadata)
        args = _export_options(kind)
        if export and args is not None:
            log(f"{row.name}: export {args}")
            out = work / (f"{path.stem}.export.bag" if kind == "ros1" else f"{path.stem}.export")
            try:
                row.export = run_child("export", rec=str(rec), out=str(out), options=args)
            finally:
                remove_output(out)
    except PcdcodecError as exc:
        row.notes.append(str(exc))
    finally:
        remove_output(rec)
    if kind == "mkv":
        return row  # not a bag: no peer reads it
    types = _topic_types(path)
    stem = str(work / path.stem)
    makers: dict[str, Callable[[Path], Any] | None] = {
        "zstd1": lambda out: bag_peers.mcap_zstd(path, out),
        "zstd19": lambda out: bag_peers.mcap_zstd(path, out, level=bag_peers.ZSTD_MAX_LEVEL),
        "lz4": (lambda out: bag_peers.ros1_lz4(path, out)) if kind == "ros1" else None,
        "cloudini": (lambda out: bag_peers.cloudini(path, out))
        if _CLOUD & set(types.values())
        else None,
    }
    for peer in peers:
        make = makers[peer]
        if make is None:
            row.peers[peer] = None
            continue
        log(f"{row.name}: {peer}")
        try:
            row.peers[peer] = _sized(Path(f"{stem}.{peer}.out"), make)
        except PcdcodecError as exc:
            row.peers[peer] = None
            row.notes.append(f"{peer}: {exc}")
    if row.kept_topics:
        log(f"{row.name}: kept topics under zstd1")
        out = Path(f"{stem}.kept.mcap")
        try:
            bag_peers.mcap_zstd(path, out, topics=set(row.kept_topics))
            row.kept_zstd1 = chunk_bytes(out, lambda ch: True)
        finally:
            remove_output(out)
    return row


def _size(n: int | None) -> str:
    if n is None:
        return "n/a"
    return f"{n / 1e6:,.1f} MB" if n >= 1e6 else f"{n / 1e3:,.1f} kB"


def _ratio(a: int | None, b: int | None) -> str:
    return f"{a / b:,.1f}×" if a and b else "n/a"


HEADER = (
    "bag",
    "kind",
    "original",
    ".pcdc (orig/.pcdc)",
    "zstd 1",
    "zstd 19",
    "ROS 1 lz4",
    "Cloudini",
    "zstd 1/.pcdc",
    "kept: .pcdc / zstd 1",
    "encode MB/s",
    "encode fps / bag fps",
    "encode RSS",
    "export MB/s",
    "export RSS",
)


def table(rows: Sequence[BagRow]) -> list[str]:
    """The rows as a Markdown table, then each row's notes ("n/a": the measure does not apply
    to the bag; "-": it was not asked for)."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "|".join("---" for _ in HEADER) + "|"]
    notes = []
    for r in rows:
        enc, exp = r.encode, r.export
        mb = r.bytes / 1e6
        fps = f"{r.frames / enc.seconds:.3g}" if enc and enc.seconds else "n/a"
        bag_fps = f"{r.bag_fps:.1f}" if r.bag_fps else "n/a"
        kept = (
            f"{_size(r.kept_pcdc)} / {_size(r.kept_zstd1)} ({len(r.kept_topics)} topics)"
            if r.kept_topics
            else "none"
        )
        cells = [
            r.name,
            r.kind,
            _size(r.bytes),
            f"{_size(r.pcdc)} ({_ratio(r.bytes, r.pcdc)})",
            *(_size(r.peers[p]) if p in r.peers else "-" for p in PEERS),
            _ratio(r.peers.get("zstd1"), r.pcdc),
            kept,
            f"{mb / enc.seconds:.3g}" if enc else "n/a",
            f"{fps} / {bag_fps}",
            f"{enc.peak_rss_bytes / 1e6:.0f} MB" if enc else "n/a",
            f"{mb / exp.seconds:.3g}" if exp else "n/a",
            f"{exp.peak_rss_bytes / 1e6:.0f} MB" if exp else "n/a",
        ]
        lines.append("| " + " | ".join(cells) + " |")
        notes += [f"{r.name}: {n}" for n in r.notes]
    return lines + notes


def peak_rss_bytes() -> int:
    """This process's peak resident memory. On Linux, the high-water mark of its own address
    space (``VmHWM``): ``ru_maxrss`` of a process started by ``subprocess`` also counts the
    parent's memory at the time it was started (the address space it came from)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)


if __name__ == "__main__":
    result = _child(sys.argv[1], json.loads(sys.argv[2]))
    result["peak_rss_bytes"] = peak_rss_bytes()
    print(json.dumps(result))
