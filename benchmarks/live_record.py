"""``pcdcodec record`` from RealSense playback: records per second, drops, ratio, memory.

Run (needs pyrealsense2 and the shared data)::

    python benchmarks/live_record.py bags --dir /tmp/live       # three 120-frame 640x480 bags
    python benchmarks/live_record.py speed --dir /tmp/live --rounds 3
    python benchmarks/live_record.py realtime --dir /tmp/live --seconds 30 --rounds 2 [--queue N]
    python benchmarks/live_record.py memory --dir /tmp/live --seconds 600

``bags`` writes three librealsense ``.bag`` files of the real D435 office sequence (120 frames,
640×480 depth and color at 30 fps, three serial numbers and start times) with
:func:`pcdcodec.bench.realsense_bags.write_realsense_bag`. ``speed`` records 1, 2 and 3 of them
at full playback speed (the files wait for the encoder) pinned to one core (``taskset -c 0``)
and to two (``taskset -c 0,1``), and prints the RGB-D frames recorded per second, from the
capture's start to the closed file, and the ratio against PointCloud2 XYZRGB (32 bytes per
valid point, one topic per camera). ``realtime`` plays them at their recorded pace, looped, for
``--seconds``, and prints the frames dropped by the camera (librealsense could not hand them
over in time) and by the recorder (its queue to the encoder was full). ``memory`` records the
three cameras at real-time pace for ``--seconds`` and prints the peak resident memory
(``/usr/bin/time -v``) and the resident memory every 30 s. Each run is a fresh process.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SERIALS = ("101", "102", "103")


def make_bags(folder: Path, frames: int = 120) -> list[Path]:
    from pcdcodec.bench.realsense_bags import write_realsense_bag
    from pcdcodec.bench.sequences import SEQUENCES, read_image

    seq = SEQUENCES["realsense_d435"]
    depths = [read_image(p) for p in seq.depth_paths()[:frames]]
    colors = [read_image(p)[..., :3] for p in sorted(seq.root.glob(seq.color_glob))[:frames]]
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k, serial in enumerate(SERIALS):
        path = folder / f"cam{k}.bag"
        if not path.exists():
            write_realsense_bag(
                path,
                depths,
                colors,
                serial=serial,
                intrinsics=seq.camera,
                start_ns=10**10 + k * 7_000_000,
            )
        out.append(path)
    return out


def record(cores: str | None, bags: list[Path], out: Path, *extra: str) -> tuple[str, float]:
    """Run ``pcdcodec record`` on ``bags``; its summary and the process's wall time."""
    cmd = [sys.executable, "-m", "pcdcodec", "record", "-o", str(out), "--overwrite", "-q"]
    for bag in bags:
        cmd += ["--playback", str(bag)]
    if cores is not None:
        cmd = ["taskset", "-c", cores, *cmd]
    start = time.perf_counter()
    done = subprocess.run([*cmd, *extra], capture_output=True, text=True, check=True, cwd=ROOT)
    return done.stdout, time.perf_counter() - start


def parse(summary: str) -> dict[str, float]:
    head = re.search(r"wrote (\d+) frames of (\d+) camera.*\) in ([\d.]+) s", summary)
    ratio = re.search(r"ratio\s+([\d.]+)x", summary)
    assert head is not None, summary
    assert ratio is not None, summary
    cams = re.findall(
        r"dropped by the camera: (\d+) depth / (\d+) color, dropped by us: (\d+)", summary
    )
    return {
        "frames": float(head.group(1)),
        "seconds": float(head.group(3)),
        "ratio": float(ratio.group(1)),
        "camera_drops": float(sum(int(d) for d, _, _ in cams)),
        "our_drops": float(sum(int(u) for _, _, u in cams)),
    }


def speed(bags: list[Path], rounds: int, out: Path) -> None:
    print("cameras  cores  frames/s (all cameras), each round     ratio vs PointCloud2")
    for cores in ("0", "0,1"):
        for n in (1, 2, 3):
            rates, ratios = [], []
            for _ in range(rounds):
                got = parse(record(cores, bags[:n], out)[0])
                rates.append(got["frames"] / got["seconds"])
                ratios.append(got["ratio"])
            print(
                f"{n:7}  {cores:5}  {min(rates):5.1f} - {max(rates):5.1f}  "
                f"({', '.join(f'{r:.1f}' for r in rates)})    {min(ratios):.1f}x"
                + (f" - {max(ratios):.1f}x" if max(ratios) != min(ratios) else "")
            )


def realtime(bags: list[Path], seconds: float, rounds: int, out: Path, *extra: str) -> None:
    print("cameras  frames offered  written  dropped by camera  dropped by us (each round)")
    for n in (1, 2, 3):
        for _ in range(rounds):
            got = parse(
                record(
                    None, bags[:n], out, "--real-time", "--loop", "--duration", str(seconds), *extra
                )[0]
            )
            offered = got["frames"] + got["camera_drops"] + got["our_drops"]
            print(
                f"{n:7}  {offered:14.0f}  {got['frames']:7.0f}  {got['camera_drops']:17.0f}  "
                f"{got['our_drops']:13.0f}"
            )


def memory(bags: list[Path], seconds: float, out: Path, *extra: str) -> None:
    cmd = [sys.executable, "-m", "pcdcodec", "record", "-o", str(out), "--overwrite"]
    for bag in bags:
        cmd += ["--playback", str(bag)]
    cmd = ["/usr/bin/time", "-v", *cmd, "--real-time", "--loop", "--duration", str(seconds)]
    cmd += extra
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT
    )
    samples: list[tuple[float, int]] = []

    def poll() -> None:
        start = time.monotonic()
        child = None
        while proc.poll() is None:
            try:
                if child is None:
                    kids = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
                    child = int(kids[0]) if kids else None
                if child is not None:
                    status = Path(f"/proc/{child}/status").read_text()
                    found = re.search(r"VmRSS:\s+(\d+)", status)
                    if found:
                        samples.append((time.monotonic() - start, int(found.group(1))))
            except (OSError, ValueError):
                pass
            time.sleep(30)

    watcher = threading.Thread(target=poll, daemon=True)
    watcher.start()
    stdout, stderr = proc.communicate()
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", stderr)
    print(stdout)
    status = [line for line in stderr.splitlines() if " s " in line and "fps" in line]
    print("\n".join(status[-3:]))
    print("RSS every 30 s (MiB):", ", ".join(f"{t:.0f}s {r / 1024:.0f}" for t, r in samples))
    if peak:
        print(f"peak RSS {int(peak.group(1)) / 1024:.0f} MiB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=("bags", "speed", "realtime", "memory"))
    parser.add_argument("--dir", type=Path, default=Path("/tmp/pcdcodec-live"))
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--queue", type=int, help="pcdcodec record --queue (default: its own)")
    args = parser.parse_args()
    extra = () if args.queue is None else ("--queue", str(args.queue))
    bags = make_bags(args.dir)
    out = args.dir / "out.pcdc"
    if args.what == "speed":
        speed(bags, args.rounds, out)
    elif args.what == "realtime":
        realtime(bags, args.seconds, args.rounds, out, *extra)
    elif args.what == "memory":
        memory(bags, args.seconds, args.dir / "memory.pcdc", *extra)


if __name__ == "__main__":
    main()
