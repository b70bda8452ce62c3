"""Record two cameras of one rig into a single .pcdc file, then fuse their clouds.

A "head" camera at 30 fps and a "wrist" camera at 15 fps, the wrist mounted 20 cm to the side
and turned 30 degrees, both fed from the bundled sample (the wrist gets a crop of it, so its
intrinsics differ). Reading back: each camera's frames, the frame sets matched by time, and
each set's cloud fused in the rig frame.

Run: ``python examples/rig_recording.py [OUTPUT.pcdc]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import pcdcodec
from pcdcodec import CameraIntrinsics, CameraSpec


def wrist_pose() -> np.ndarray:
    """The wrist camera in the rig frame: 30 degrees about y, 20 cm along x."""
    a = np.deg2rad(30.0)
    pose = np.eye(4)
    pose[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    pose[:3, 3] = [0.2, 0.0, 0.0]
    return pose


def main() -> int:
    seq = pcdcodec.load_sample()
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "rig.pcdc"
    cam = seq.intrinsics
    crop = CameraIntrinsics(320, 240, cam.fx, cam.fy, cam.cx - 160, cam.cy - 120)
    cameras = [
        CameraSpec("head", cam, seq.depth_scale, fps=30.0),
        CameraSpec("wrist", crop, seq.depth_scale, fps=15.0, rig_pose=wrist_pose()),
    ]
    with pcdcodec.open(out, "w", cameras=cameras, overwrite=True) as rig:
        for k, frame in enumerate(seq):
            t = frame.timestamp_ns
            rig.write("head", frame.color, frame.depth, t)
            if k % 2 == 0:  # half the rate, 4 ms later: its own clock
                rig.write(
                    "wrist",
                    np.ascontiguousarray(frame.color[120:360, 160:480]),
                    np.ascontiguousarray(frame.depth[120:360, 160:480]),
                    t + 4_000_000,
                )
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KiB)")

    with pcdcodec.open(out) as rec:
        for name, info in rec.cameras.items():
            frames = rec.frames(name)
            print(
                f"camera {name}: {info.intrinsics.width}x{info.intrinsics.height} at "
                f"{info.fps:g} fps, {len(frames)} frames, depth codec {info.depth_codec['id']}"
            )
        sets = rec.framesets()  # one per head frame, the wrist frame within half a frame
        print(f"{len(sets)} frame sets, {sets.incomplete} without a wrist frame")
        for s in sets[:4]:
            points, _colors, parts = s.to_points()
            counts = ", ".join(f"{n} {p.stop - p.start}" for n, p in parts.items())
            missing = f" (missing: {', '.join(s.missing)})" if s.missing else ""
            when = s.timestamp_ns / 1e9
            print(f"set {s.index} at {when:.3f} s: {len(points)} points ({counts}){missing}")
        cloud = sets[0].to_point_cloud()  # open3d.geometry.PointCloud in the rig frame
        print(f"first fused cloud: {cloud}")
        print("rig verified" if rec.verify().ok else "rig has problems")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
