"""librealsense's own view of a RealSense .bag, saved for comparison with pcdcodec.

Plays the bag with pyrealsense2 (not a pcdcodec dependency: install it in a separate
environment) and saves, for each frameset, the depth and color as librealsense decodes them,
the depth aligned to color by ``rs2::align``, and the depth-to-color extrinsic, to an ``.npz``
that ``scripts/measure_ingest.py --rs-reference`` reads.

Run: ``python scripts/realsense_align_reference.py BAG OUT.npz``.
"""

from __future__ import annotations

import sys

import numpy as np


def main() -> int:
    import pyrealsense2 as rs

    bag, out = sys.argv[1], sys.argv[2]
    pipe = rs.pipeline()
    cfg = rs.config()
    cfg.enable_device_from_file(bag, repeat_playback=False)
    profile = pipe.start(cfg)
    profile.get_device().as_playback().set_real_time(False)
    depth_profile = profile.get_stream(rs.stream.depth).as_video_stream_profile()
    color_profile = profile.get_stream(rs.stream.color).as_video_stream_profile()
    extrinsics = depth_profile.get_extrinsics_to(color_profile)
    align = rs.align(rs.stream.color)
    arrays: dict[str, np.ndarray] = {}
    n = 0
    while True:
        try:
            frames = pipe.wait_for_frames(2000)
        except RuntimeError:
            break
        depth, color = frames.get_depth_frame(), frames.get_color_frame()
        if not depth or not color:
            continue
        aligned = align.process(frames).get_depth_frame()
        arrays[f"depth{n}"] = np.asanyarray(depth.get_data()).copy()
        arrays[f"color{n}"] = np.asanyarray(color.get_data()).copy()
        arrays[f"aligned{n}"] = np.asanyarray(aligned.get_data()).copy()
        arrays[f"stamp{n}"] = np.array([depth.get_timestamp(), color.get_timestamp()])
        n += 1
    pipe.stop()
    np.savez(
        out,
        rot=np.array(extrinsics.rotation),
        t=np.array(extrinsics.translation),
        count=np.array(n),
        **arrays,
    )
    print(f"saved {n} framesets to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
