"""Reading a bag of three cameras into one recording, against reading three one-camera bags.

Run: ``python scripts/rig_ingest.py [--frames 60] [--ros2] [--json OUT]``.

Builds, from the dense sequences of ``../shared/data`` (TUM fr1_rpy, RealSense D435 office,
7-Scenes redkitchen; the bundled sample where one is absent), a ROS bag holding the three
cameras under ``/cam_<name>/`` (rgb8 color, 16UC1 depth, CameraInfo) with their mountings in
``/tf_static``, and the same frames as three one-camera bags. Then, each in a process of its
own: ``pcdcodec encode rig.bag`` (one recording of the rig) and ``pcdcodec encode`` of each
one-camera bag. Prints the wall time, frames per second and peak resident memory of each.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from pcdcodec.bench.sequences import SEQUENCES, load_colors, load_depths
from pcdcodec.ros.bagwriter import BagWriter, MessageBuilder

_MS = 1_000_000
_T0 = 1_700_000_000 * 1_000_000_000


def _cameras(frames: int) -> list[dict[str, Any]]:
    out = []
    for k, (name, seq, period) in enumerate(
        (("head", "tum_fr1_rpy", 33_333_333), ("wrist", "realsense_d435", 33_333_333),
         ("side", "7scenes_redkitchen", 66_666_667))
    ):  # fmt: skip
        use = seq if SEQUENCES[seq].present else "sample"
        n = frames if period < 50_000_000 else frames // 2
        depths, colors = load_depths(use, n), load_colors(use, n)
        pose = np.eye(4)
        pose[:3, 3] = [0.1 * k, -0.05 * k, 0.2]
        times = [_T0 + 11 * k * _MS + i * period for i in range(len(depths))]
        out.append({"name": name, "seq": use, "depths": depths, "colors": colors,
                    "camera": SEQUENCES[use].camera, "times": times, "pose": pose})  # fmt: skip
    return out


def _write_bag(path: Path, cams: list[dict[str, Any]], ros2: bool) -> None:
    builders = {
        c["name"]: MessageBuilder(ros2, f"cam_{c['name']}_depth_optical_frame") for c in cams
    }
    writer = BagWriter(path, "rosbag2" if ros2 else "rosbag1", "mcap", builders[cams[0]["name"]])
    messages = []
    writer.add("/tf_static", "tf2_msgs/msg/TFMessage")
    for cam in cams:
        ns, b = f"/cam_{cam['name']}", builders[cam["name"]]
        writer.add(f"{ns}/depth/image_raw", "sensor_msgs/msg/Image")
        writer.add(f"{ns}/color/image_raw", "sensor_msgs/msg/Image")
        writer.add(f"{ns}/depth/camera_info", "sensor_msgs/msg/CameraInfo")
        messages.append(
            (cam["times"][0], "/tf_static", b.tf(cam["times"][0], cam["pose"], "base_link"))
        )
        for t, d, c in zip(cam["times"], cam["depths"], cam["colors"], strict=True):
            messages.append((t, f"{ns}/depth/image_raw", b.image(t, d, "16UC1")))
            messages.append((t, f"{ns}/color/image_raw", b.image(t, c, "rgb8")))
            messages.append(
                (
                    t,
                    f"{ns}/depth/camera_info",
                    b.camera_info(t, cam["camera"], "plumb_bob", [0.0] * 5),
                )
            )
    for t, topic, data in sorted(messages, key=lambda m: m[0]):
        writer.write(topic, t, data)
    writer.close()


#: Runs the command line and prints the process's peak resident memory (VmHWM: that of its own
#: memory since exec, unlike ru_maxrss, which also counts the parent's at fork).
_CHILD = """
import sys
from pcdcodec.cli import main
code = main(sys.argv[1:])
hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1]
print(hwm, file=sys.stderr)
sys.exit(code)
"""


def _run(args: list[str]) -> tuple[float, float]:
    """Wall seconds and peak resident MiB of ``pcdcodec ARGS`` in a process of its own."""
    start = time.perf_counter()
    cmd = [sys.executable, "-c", _CHILD, *args, "-q"]
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        raise SystemExit(f"pcdcodec {' '.join(args)} failed: {done.stderr}")
    return time.perf_counter() - start, int(done.stderr.split()[-1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60, help="frames of the 30 fps cameras")
    parser.add_argument("--ros2", action="store_true", help="ROS 2 (mcap) bags, not ROS 1")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args()
    cams = _cameras(args.frames)
    total = sum(len(c["times"]) for c in cams)
    results: dict[str, Any] = {"frames": total, "ros2": args.ros2,
                               "sequences": [c["seq"] for c in cams]}  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        suffix = "" if args.ros2 else ".bag"
        _write_bag(d / f"rig{suffix}", cams, args.ros2)
        for cam in cams:
            _write_bag(d / f"{cam['name']}{suffix}", [cam], args.ros2)
        secs, mib = _run(["encode", str(d / f"rig{suffix}"), "-o", str(d / "rig.pcdc")])
        results["rig"] = {"seconds": secs, "fps": total / secs, "peak_mib": mib,
                          "bytes": (d / "rig.pcdc").stat().st_size}  # fmt: skip
        one: dict[str, Any] = {"seconds": 0.0, "peak_mib": 0.0, "bytes": 0, "peaks_mib": []}
        for cam in cams:
            out = d / f"{cam['name']}.pcdc"
            secs, mib = _run(["encode", str(d / f"{cam['name']}{suffix}"), "-o", str(out)])
            one["seconds"] += secs
            one["peak_mib"] = max(one["peak_mib"], mib)
            one["peaks_mib"].append(round(mib, 1))
            one["bytes"] += out.stat().st_size
        one["fps"] = total / one["seconds"]
        results["three_one_camera"] = one
    for key in ("rig", "three_one_camera"):
        r = results[key]
        print(
            f"{key:17} {r['seconds']:6.1f} s  {r['fps']:6.1f} frames/s  peak "
            f"{r['peak_mib']:6.0f} MiB  {r['bytes'] / 2**20:6.2f} MiB out"
        )
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
