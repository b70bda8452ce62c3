"""A recording of three cameras going out: bags, folders, join, recover, verify, measured.

Run: ``python benchmarks/rig_out.py [--frames N] [--keep DIR]``. Builds a rig of the three real
sequences in ``../shared/data`` (tum_fr1_rpy at 30 fps, realsense_d435 at 15 fps,
7scenes_redkitchen at 10 fps; 640×480 each, N frames each, with rig poses), records it with the
defaults (h264 + depthac), and prints, for each way out, its size and how long it took: the
export to a ROS 1 bag of images and to a ROS 1 bag of three organized PointCloud2 XYZRGB topics
(the ratio of the recording against them), ``decode`` to a folder per camera, ``join`` of its
two halves, ``recover`` of the file cut 4 KiB short (its index gone), and ``verify``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES, load_colors, load_depths
from pcdcodec.recording import CameraSpec, RigWriter
from pcdcodec.recording.join import join

RIG = (
    ("head", "tum_fr1_rpy", 30.0),
    ("wrist", "realsense_d435", 15.0),
    ("side", "7scenes_redkitchen", 10.0),
)


def _size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*")) if path.is_dir() else path.stat().st_size


def _timed(step: Callable[[], Any]) -> tuple[Any, float]:
    start = time.perf_counter()
    out = step()
    return out, time.perf_counter() - start


def _write(path: Path, cams: list[tuple[CameraSpec, list[Any], list[Any], list[int]]]) -> None:
    events = sorted(
        (t, c, k) for c, (_, _, _, times) in enumerate(cams) for k, t in enumerate(times)
    )
    with RigWriter(path, [c[0] for c in cams], overwrite=True) as w:
        for t, c, k in events:
            spec, depths, colors, _ = cams[c]
            w.write(spec.name, colors[k], depths[k], t)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=60, help="frames per camera")
    parser.add_argument("--keep", type=Path, help="write the outputs here and keep them")
    args = parser.parse_args()
    missing = [seq for _, seq, _ in RIG if not SEQUENCES[seq].present]
    if missing:
        sys.exit(f"needs the real sequences in ../shared/data; missing {missing}")
    cams = []
    for k, (name, seq_name, fps) in enumerate(RIG):
        seq = SEQUENCES[seq_name]
        pose = np.eye(4)
        pose[:3, 3] = [0.3 * k, -0.1 * k, 0.05 * k]
        spec = CameraSpec(name, seq.camera, seq.depth_scale, fps=fps, rig_pose=pose)
        depths = load_depths(seq_name, args.frames)
        colors = load_colors(seq_name, len(depths))
        step = round(1e9 / fps)
        times = [10**9 + 7_000_000 * k + i * step for i in range(len(depths))]
        cams.append((spec, depths, colors, times))
    frames = sum(len(c[3]) for c in cams)
    out = args.keep or Path(tempfile.mkdtemp(prefix="rig_out_"))
    out.mkdir(parents=True, exist_ok=True)
    try:
        rig = out / "rig.pcdc"
        _, took = _timed(lambda: _write(rig, cams))
        size = _size(rig)
        print(f"rig: 3 cameras, {frames} frames, 640x480, {size / 2**20:.2f} MiB")
        print(f"  write (encode)        {took:7.2f} s  {frames / took:6.1f} frames/s")
        rows = []
        bag = out / "images.bag"
        _, took = _timed(lambda: pcdcodec.export_bag(rig, bag, overwrite=True))
        rows.append(("export rosbag1 images", took, _size(bag)))
        clouds = out / "clouds.bag"
        _, took = _timed(
            lambda: pcdcodec.export_bag(rig, clouds, images=False, cloud=True, overwrite=True)
        )
        rows.append(("export rosbag1 clouds", took, _size(clouds)))
        folders = out / "folders"
        shutil.rmtree(folders, ignore_errors=True)

        def decode() -> None:
            from pcdcodec.datasets import write_rig_folder

            with pcdcodec.open(rig) as rec:
                write_rig_folder(rec, folders)

        _, took = _timed(decode)
        rows.append(("decode to folders", took, _size(folders)))
        halves = []
        for h in range(2):
            part = []
            for spec, depths, colors, times in cams:
                n = len(times) // 2
                pick = slice(0, n) if h == 0 else slice(n, None)
                part.append((spec, depths[pick], colors[pick], times[pick]))
            path = out / f"half{h}.pcdc"
            _write(path, part)
            halves.append(path)
        joined = out / "joined.pcdc"
        _, took = _timed(lambda: join(halves, joined, overwrite=True))
        rows.append(("join two halves", took, _size(joined)))
        cut = out / "cut.pcdc"
        cut.write_bytes(rig.read_bytes()[:-4096])  # the index and the last records gone
        recovered = out / "recovered.pcdc"
        count, took = _timed(lambda: pcdcodec.recover(cut, recovered, overwrite=True))
        rows.append((f"recover ({count} frames)", took, _size(recovered)))

        def verify() -> bool:
            with pcdcodec.open(rig) as rec:
                return rec.verify().ok

        ok, took = _timed(verify)
        rows.append((f"verify ({'OK' if ok else 'problems'})", took, size))
        for what, seconds, nbytes in rows:
            print(
                f"  {what:21} {seconds:7.2f} s  {frames / seconds:6.1f} frames/s  "
                f"{nbytes / 2**20:9.2f} MiB  ({nbytes / size:6.1f}x the recording)"
            )
    finally:
        if args.keep is None:
            shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
