"""Scaling of ``pcdcodec archive``: 1 against 2 (or more) workers on a generated archive.

Generates an archive of ``--inputs`` inputs (default 20) from the real RGB-D sequences in
``../shared/data`` (TUM fr1_rpy, RealSense D435 office, 7-Scenes redkitchen), each
``--frames`` consecutive frames, as organized PointCloud2 XYZRGB ROS 1 bags (``--format bags``,
through :func:`pcdcodec.export_bag`) or as TUM-layout folders (``--format folders``, images
linked, not copied). Then archives it with each worker count on a fresh local cluster and
prints input MB/s, frames/s, the compression ratio and each worker's peak memory (RSS).
``--memory`` adds the memory bound: one worker encoding one input of N frames and one of 4N.

    python benchmarks/archive_scaling.py --work /tmp/archive-bench --workers 1 2 --memory

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
        if not folder.exists():
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


def run(inputs: list[Path], out: Path, workers: int, segment_frames: int) -> dict[str, Any]:
    import logging

    from distributed import Client, LocalCluster

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
        start = time.perf_counter()
        summary = archive(
            inputs,
            out,
            scheduler=cluster.scheduler_address,
            segment_frames=segment_frames,
            progress=False,
        )
        wall = time.perf_counter() - start
        usage = list(client.run(_usage).values())
        peaks = sorted(p for p, _ in usage)
        cpu = sum(c for _, c in usage)
        load = os.getloadavg()[0]
    if not summary.ok:
        raise SystemExit(summary.to_text())
    return {
        "workers": workers,
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
        span = int(rec.timestamps[-1]) + 1_000_000
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
        "bytes": total,
        "seconds": seconds,
        "mb_per_s": total / 1e6 / seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="folder for inputs and outputs")
    parser.add_argument("--inputs", type=int, default=20)
    parser.add_argument("--frames", type=int, default=12, help="frames per input")
    parser.add_argument("--format", choices=["bags", "folders"], default="bags")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--segment-frames", type=int, default=300)
    parser.add_argument("--memory", action="store_true", help="also measure the memory bound")
    args = parser.parse_args()

    os.environ.setdefault("PYTHONPATH", str(REPO))
    inputs = generate(args.work / "gen", args.inputs, args.frames, args.format)
    results: dict[str, Any] = {"format": args.format, "runs": []}
    for w in args.workers:
        r = run(inputs, args.work / f"out-{w}", w, args.segment_frames)
        results["runs"].append(r)
        print(json.dumps(r), flush=True)
    if args.memory:
        results["memory"] = []
        for factor in (1, 4):
            gen = args.work / f"gen-mem-{factor}"
            one = generate(gen, 1, args.frames * 2, args.format, long_factor=factor)
            r = run(one, args.work / f"out-mem-{factor}", 1, 10**6)
            r["input_frames"] = args.frames * 2 * factor
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
        "| workers | MB/s in | frames/s | ratio | seconds | MB per CPU-s | frames per CPU-s "
        "| peak RSS per worker (MB) | load |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results["runs"]:
        rss = ", ".join(f"{p:.0f}" for p in r["peak_rss_per_worker_mb"])
        print(
            f"| {r['workers']} | {r['mb_per_s']:.2f} | {r['frames_per_s']:.2f} | "
            f"{r['ratio']:.1f} | {r['seconds']:.1f} | {r['mb_per_cpu_s']:.2f} | "
            f"{r['frames_per_cpu_s']:.2f} | {rss} | {r['load_average_1min']:.1f} |"
        )
    for r in results.get("memory", []):
        rss = r["peak_rss_per_worker_mb"][0]
        print(f"memory: one input of {r['input_frames']} frames -> peak worker RSS {rss:.0f} MB")


if __name__ == "__main__":
    main()
