"""Scaling of ``pcdcodec archive``: 1 against 2 (or more) workers on a generated archive.

Generates an archive of ``--inputs`` inputs (default 20) from the real RGB-D sequences in
``../shared/data`` (TUM fr1_rpy, RealSense D435 office, 7-Scenes redkitchen), each
``--frames`` consecutive frames, as organized PointCloud2 XYZRGB ROS 1 bags (``--format bags``,
through :func:`pcdcodec.export_bag`) or as TUM-layout folders (``--format folders``, images
linked, not copied). Then archives it with each worker count on a fresh local cluster and
prints input MB/s, frames/s, the compression ratio and each worker's peak memory (RSS).
``--memory`` adds the memory bound: one worker encoding one input of N frames and one of 4N
(whole, and the long one cut into segments). ``--segment-frames`` takes several values (a
value of at least ``--frames`` encodes each bag whole) and ``--repeat`` runs every
configuration that many times, interleaved, so that a change of load hits all of them.
Each run also reports, from Dask's task stream, the tasks of each kind (probe, segment, join)
and the seconds they computed, against the run's wall time on the workers: what is left is
scheduler and transfer overhead. ``--seek`` measures reading segment k of one long bag:
the time to its first frame must not grow with k.

    python benchmarks/archive_scaling.py --work /tmp/archive-bench --workers 1 2 --memory
    python benchmarks/archive_scaling.py --work /tmp/archive-bench --frames 30 \
        --segment-frames 15 1000 --repeat 2 --memory
    python benchmarks/archive_scaling.py --work /tmp/archive-bench --seek-only

Results are printed as a markdown table and written to ``WORK/results.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


def _tum_rows(root: Path) -> list[tuple[str, str, str]]:
    rows = []
    for line in (root / "associations.txt").read_text().splitlines():
        parts = line.split()
        if len(parts) >= 4 and not line.startswith("#"):
            rows.append((parts[0], parts[1], parts[3]))
    # The RealSense office list is not in time order everywhere: sort, drop repeated times.
    rows.sort(key=lambda r: float(r[0]))
    return [r for i, r in enumerate(rows) if i == 0 or float(r[0]) > float(rows[i - 1][0])]


def _sequences() -> dict[str, dict[str, Any]]:
    """Each real sequence: its (time, color, depth) rows and its camera."""
    seqs: dict[str, dict[str, Any]] = {}
    tum = DATA / "tum_fr1_rpy"
    if tum.is_dir():
        camera = {"width": 640, "height": 480, "fx": 525.0, "fy": 525.0, "cx": 319.5}
        camera |= {"cy": 239.5, "depth_scale": 5000.0}
        seqs["tum_fr1_rpy"] = {"root": tum, "rows": _tum_rows(tum), "camera": camera}
    rs = DATA / "realsense_d435_office"
    if rs.is_dir():
        camera = {"width": 640, "height": 480, "fx": 615.0, "fy": 615.0, "cx": 320.0}
        camera |= {"cy": 240.0, "depth_scale": 1000.0}
        seqs["realsense_d435"] = {"root": rs, "rows": _tum_rows(rs), "camera": camera}
    kitchen = DATA / "7scenes_redkitchen"
    if kitchen.is_dir():
        colors = sorted((kitchen / "rgb").glob("*.color.jpg"))
        rows = []
        for i, c in enumerate(colors):
            depth = kitchen / "depth" / c.name.replace(".color.jpg", ".depth.png")
            if depth.exists():
                rows.append((f"{i / 30:.6f}", f"rgb/{c.name}", f"depth/{depth.name}"))
        camera = {"width": 640, "height": 480, "fx": 585.0, "fy": 585.0, "cx": 320.0}
        camera |= {"cy": 240.0, "depth_scale": 1000.0}
        seqs["7scenes_redkitchen"] = {"root": kitchen, "rows": rows, "camera": camera}
    if not seqs:
        sys.exit(f"no real sequences under {DATA}")
    return seqs


def make_folder(dst: Path, seq: dict[str, Any], first: int, count: int) -> Path:
    """A TUM-layout folder of ``count`` frames of ``seq`` from ``first`` (images linked)."""
    rows = seq["rows"][first : first + count]
    (dst / "rgb").mkdir(parents=True)
    (dst / "depth").mkdir()
    lines = []
    for t, color, depth in rows:
        (dst / color).symlink_to(seq["root"] / color)
        (dst / depth).symlink_to(seq["root"] / depth)
        lines.append(f"{t} {color} {t} {depth}")
    (dst / "associations.txt").write_text("\n".join(lines) + "\n")
    (dst / "rgb.txt").write_text("")
    (dst / "depth.txt").write_text("")
    (dst / "camera.json").write_text(json.dumps(seq["camera"]))
    return dst


def generate(work: Path, n: int, frames: int, fmt: str, long_factor: int = 1) -> list[Path]:
    """``n`` inputs of ``frames`` frames (times ``long_factor``) under ``work``."""
    import pcdcodec

    seqs = list(_sequences().values())
    names = list(_sequences())
    folders = work / "folders"
    made = []
    for i in range(n):
        seq = seqs[i % len(seqs)]
        count = frames * long_factor
        span = max(1, len(seq["rows"]) - count)
        first = (i // len(seqs)) * frames % span
        name = f"{names[i % len(seqs)]}_{i:03d}"
        folder = folders / name
        if not folder.exists() and count > len(seq["rows"]):
            make_long_folder(folder, seq, count)  # the sequence again and again
        elif not folder.exists():
            make_folder(folder, seq, first, count)
        if fmt == "folders":
            made.append(folder)
            continue
        bag = work / "bags" / f"{name}.bag"
        if not bag.exists():
            bag.parent.mkdir(parents=True, exist_ok=True)
            export = getattr(pcdcodec, "export_bag", None)
            if export is None:
                sys.exit("--format bags needs pcdcodec.export_bag (PointCloud2 bag writer)")
            export(folder, bag, images=False, cloud=True, camera_info=True)
        made.append(bag)
    return made


def _usage() -> tuple[int, float]:
    """This process's peak resident memory in bytes (Linux reports KiB) and CPU seconds."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_maxrss * 1024, u.ru_utime + u.ru_stime


def _task_kinds(stream: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Tasks of each kind (the key's prefix) and the seconds they computed, from Dask's task
    stream."""
    kinds: dict[str, dict[str, float]] = {}
    for task in stream:
        kind = str(task["key"]).split("-", 1)[0]
        spent = sum(
            s["stop"] - s["start"] for s in task.get("startstops", ()) if s["action"] == "compute"
        )
        entry = kinds.setdefault(kind, {"tasks": 0, "compute_s": 0.0})
        entry["tasks"] += 1
        entry["compute_s"] += spent
    return kinds


def run(inputs: list[Path], out: Path, workers: int, segment_frames: int) -> dict[str, Any]:
    import logging

    from distributed import Client, LocalCluster, get_task_stream

    from pcdcodec.archive import archive

    shutil.rmtree(out, ignore_errors=True)
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            silence_logs=logging.ERROR,
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        load_before = os.getloadavg()[0]
        start = time.perf_counter()
        with get_task_stream(client) as stream:
            summary = archive(
                inputs,
                out,
                scheduler=cluster.scheduler_address,
                segment_frames=segment_frames,
                progress=False,
            )
        wall = time.perf_counter() - start
        kinds = _task_kinds(stream.data)
        usage = list(client.run(_usage).values())
        peaks = sorted(p for p, _ in usage)
        cpu = sum(c for _, c in usage)
        load = os.getloadavg()[0]
    if not summary.ok:
        raise SystemExit(summary.to_text())
    tasks = sum(int(k["tasks"]) for k in kinds.values())
    computed = sum(k["compute_s"] for k in kinds.values())
    return {
        "workers": workers,
        "segment_frames": segment_frames,
        "segments": sum(i.segments for i in summary.items),
        "inputs": len(inputs),
        "frames": summary.frames,
        "bytes_in": summary.bytes_in,
        "bytes_out": summary.bytes_out,
        "ratio": summary.ratio,
        "seconds": wall,
        "mb_per_s": summary.bytes_in / 1e6 / wall,
        "frames_per_s": summary.frames / wall,
        "peak_rss_per_worker_mb": [p / 1e6 for p in peaks],
        # Per CPU-second of the workers: the rate of one core, whatever else runs beside.
        "worker_cpu_s": cpu,
        "mb_per_cpu_s": summary.bytes_in / 1e6 / cpu,
        "frames_per_cpu_s": summary.frames / cpu,
        "load_average_1min": load,
        "load_average_1min_before": load_before,
        "task_kinds": kinds,
        # Worker time not spent computing a task, per task: scheduling, transfers, idling.
        "overhead_ms_per_task": 1000 * max(workers * wall - computed, 0.0) / max(tasks, 1),
        "join_ms_per_segment": 1000
        * kinds.get("join", {}).get("compute_s", 0.0)
        / max(sum(i.segments for i in summary.items), 1),
    }


def _noop(i: int) -> int:
    return i


def scheduler_overhead(tasks: int = 2000) -> dict[str, Any]:
    """Seconds per task of the scheduler and workers, for tasks that do nothing."""
    import logging

    from distributed import Client, LocalCluster, wait

    with (
        LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            silence_logs=logging.ERROR,
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        wait(client.map(_noop, range(100), pure=False))  # warm up
        start = time.perf_counter()
        wait(client.map(_noop, range(tasks), pure=False))
        seconds = time.perf_counter() - start
    return {"tasks": tasks, "seconds": seconds, "ms_per_task": 1000 * seconds / tasks}


def join_rate(work: Path) -> dict[str, Any]:
    """MB/s of :func:`pcdcodec.recording.join` on the segments of the largest output."""
    from pcdcodec.recording.join import join

    outputs = sorted(work.glob("out-*/**/*.pcdc"), key=lambda p: p.stat().st_size)
    if not outputs:
        return {}
    src = outputs[-1]
    # The same frames eight times over, shifted in time, written as eight segments.
    from pcdcodec.recording import open as open_recording

    with open_recording(src) as rec:
        span = int(rec.timestamps[-1]) - int(rec.timestamps[0]) + 1_000_000
        frames = [(f.color, f.depth, f.timestamp_ns) for f in rec]
        camera, scale, codecs = rec.intrinsics, rec.depth_scale, rec.codecs
    parts = [work / f"join-part-{i}.pcdc" for i in range(8)]
    for i, part in enumerate(parts):
        with open_recording(
            part,
            "w",
            intrinsics=camera,
            depth_scale=scale,
            color=codecs["color"],
            depth=codecs["depth"],
            overwrite=True,
        ) as w:
            for color, depth, t in frames:
                w.write(color, depth, t + i * span)
    total = sum(p.stat().st_size for p in parts)
    start = time.perf_counter()
    join(parts, work / "joined.pcdc", overwrite=True)
    seconds = time.perf_counter() - start
    return {
        "parts": len(parts),
        "frames_per_part": len(frames),
        "bytes": total,
        "seconds": seconds,
        "mb_per_s": total / 1e6 / seconds,
        "ms_per_part": 1000 * seconds / len(parts),
    }


def make_long_folder(dst: Path, seq: dict[str, Any], count: int) -> Path:
    """A TUM-layout folder of ``count`` frames at 30 Hz, going through ``seq`` again and again
    (images linked under new names)."""
    rows = seq["rows"]
    (dst / "rgb").mkdir(parents=True)
    (dst / "depth").mkdir()
    lines = []
    for i in range(count):
        _, color, depth = rows[i % len(rows)]
        t = f"{1000 + i / 30:.6f}"
        c, d = f"rgb/{i:06d}{Path(color).suffix}", f"depth/{i:06d}{Path(depth).suffix}"
        (dst / c).symlink_to(seq["root"] / color)
        (dst / d).symlink_to(seq["root"] / depth)
        lines.append(f"{t} {c} {t} {d}")
    (dst / "associations.txt").write_text("\n".join(lines) + "\n")
    (dst / "rgb.txt").write_text("")
    (dst / "depth.txt").write_text("")
    (dst / "camera.json").write_text(json.dumps(seq["camera"]))
    return dst


def seek(work: Path, frames: int = 1200, segment: int = 30, cloud: bool = False) -> dict[str, Any]:
    """Seconds to open a long image (or PointCloud2) bag and read the first frame of segment k,
    for k spread
    over the bag, given the segment's frame index slice (as an archive worker is); and the
    same from the top without an index (the generic ``Source.frames``), for contrast."""
    import itertools

    import pcdcodec
    from pcdcodec.sources.rosbag import RosbagSource

    seq = _sequences().get("7scenes_redkitchen") or next(iter(_sequences().values()))
    bag = work / f"long-{frames}{'-cloud' if cloud else ''}.bag"
    if not bag.exists():
        folder = work / f"long-{frames}"
        if not folder.exists():
            make_long_folder(folder, seq, frames)
        pcdcodec.export_bag(folder, bag, images=not cloud, cloud=cloud, camera_info=True)
    size = bag.stat().st_size
    with RosbagSource(bag) as source:
        start = time.perf_counter()
        index = source.frame_index()
        index_s = time.perf_counter() - start
    with RosbagSource(bag) as source:
        start = time.perf_counter()
        n = sum(1 for _ in source)
        decode_s = time.perf_counter() - start
    segments = len(index) // segment
    picks = sorted({0, segments // 4, segments // 2, 3 * segments // 4, segments - 1})
    rows = []
    for k in picks:
        part = index.slice(k * segment, (k + 1) * segment)
        start = time.perf_counter()
        with RosbagSource(bag) as source:
            next(iter(source.frames_at(part)))
            first = time.perf_counter() - start
        start = time.perf_counter()
        with RosbagSource(bag) as source:
            next(itertools.islice(iter(source), k * segment, None))
            top = time.perf_counter() - start
        rows.append({"segment": k, "first_frame_s": first, "from_top_s": top})
    ratio = rows[-1]["first_frame_s"] / rows[0]["first_frame_s"]
    return {
        "bag": "PointCloud2" if cloud else "Image",
        "bag_mb": size / 1e6,
        "frames": n,
        "segment_frames": segment,
        "index_s": index_s,
        "decode_all_s": decode_s,
        "segments": rows,
        "last_over_first": ratio,
        "load_average_1min": os.getloadavg()[0],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="folder for inputs and outputs")
    parser.add_argument("--inputs", type=int, default=20)
    parser.add_argument("--frames", type=int, default=12, help="frames per input")
    parser.add_argument("--format", choices=["bags", "folders"], default="bags")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--segment-frames", type=int, nargs="+", default=[300])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each configuration")
    parser.add_argument("--memory", action="store_true", help="also measure the memory bound")
    parser.add_argument("--seek", action="store_true", help="also time segment k of a long bag")
    parser.add_argument("--seek-only", action="store_true", help="only time segment k")
    parser.add_argument("--seek-frames", type=int, default=1200, help="frames of the long bag")
    parser.add_argument("--seek-cloud", action="store_true", help="a PointCloud2 long bag")
    args = parser.parse_args()

    os.environ.setdefault("PYTHONPATH", str(REPO))
    results: dict[str, Any] = {"format": args.format, "runs": []}
    if args.seek or args.seek_only:
        results["seek"] = seek(args.work, args.seek_frames, cloud=args.seek_cloud)
        print(json.dumps(results["seek"]), flush=True)
        if args.seek_only:
            (args.work / "results-seek.json").write_text(json.dumps(results, indent=2))
            return
    inputs = generate(args.work / "gen", args.inputs, args.frames, args.format)
    for _ in range(args.repeat):
        for seg in args.segment_frames:
            for w in args.workers:
                r = run(inputs, args.work / f"out-{w}", w, seg)
                results["runs"].append(r)
                print(json.dumps(r), flush=True)
    if args.memory:
        results["memory"] = []
        for factor, seg in ((1, 10**6), (4, 10**6), (4, args.frames)):
            gen = args.work / f"gen-mem-{factor}"
            one = generate(gen, 1, args.frames * 2, args.format, long_factor=factor)
            r = run(one, args.work / f"out-mem-{factor}", 1, seg)
            r["input_frames"] = r["frames"]
            results["memory"].append(r)
            print(json.dumps(r), flush=True)
    results["scheduler"] = scheduler_overhead()
    print(json.dumps(results["scheduler"]), flush=True)
    results["join"] = join_rate(args.work)
    print(json.dumps(results["join"]), flush=True)
    (args.work / "results.json").write_text(json.dumps(results, indent=2))

    print()
    print(f"{args.format}: {len(inputs)} inputs, {args.frames} frames each")
    print(
        "| workers | segments | MB/s in | frames/s | ratio | seconds | MB per CPU-s "
        "| frames per CPU-s | overhead ms/task | join ms/segment | peak RSS per worker (MB) "
        "| load before, after |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results["runs"]:
        rss = ", ".join(f"{p:.0f}" for p in r["peak_rss_per_worker_mb"])
        print(
            f"| {r['workers']} | {r['segments']} | {r['mb_per_s']:.2f} | "
            f"{r['frames_per_s']:.2f} | {r['ratio']:.1f} | {r['seconds']:.1f} | "
            f"{r['mb_per_cpu_s']:.2f} | {r['frames_per_cpu_s']:.2f} | "
            f"{r['overhead_ms_per_task']:.0f} | {r['join_ms_per_segment']:.0f} | {rss} | "
            f"{r['load_average_1min_before']:.1f}, {r['load_average_1min']:.1f} |"
        )
    for r in results.get("memory", []):
        rss = r["peak_rss_per_worker_mb"][0]
        print(
            f"memory: one input of {r['input_frames']} frames in {r['segments']} segment(s) "
            f"-> peak worker RSS {rss:.0f} MB"
        )


if __name__ == "__main__":
    main()
