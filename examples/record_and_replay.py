"""Record the bundled sample into a .pcdc file, then read it back three ways.

1. iterate every frame and rebuild its point cloud;
2. jump straight to a frame by index and by timestamp (decoding starts at its keyframe);
3. replay at the recorded pace, twice as fast.

Run: ``python examples/record_and_replay.py [OUTPUT.pcdc]``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import pcdcodec


def main() -> int:
    seq = pcdcodec.load_sample()
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp()) / "sample.pcdc"

    with pcdcodec.open(
        out,
        "w",
        intrinsics=seq.intrinsics,
        depth_scale=seq.depth_scale,
        color="h264",  # lossy video, visually lossless at the default crf 18
        depth="depthac",  # lossless, checksummed (the default)
        metadata={"sensor": "Kinect v1", "sequence": "TUM fr1_rpy"},
        overwrite=True,
    ) as rec:
        rec.write_frames(seq)
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KiB for {len(seq)} frames)")

    with pcdcodec.open(out) as rec:
        print(f"{len(rec)} frames over {rec.duration:.2f} s, codecs {rec.codecs}")
        points = 0
        for frame, original in zip(rec, seq, strict=True):
            assert np.array_equal(frame.depth, original.depth)  # lossless depth
            points += len(frame.to_points()[0])
        print(f"rebuilt {points:,} points; depth bit-exact in every frame")

        cloud = rec[10].to_point_cloud()  # random access through the file's index
        print(f"frame 10: {cloud}")
        middle = seq[7].timestamp_ns + 5_000_000
        print(f"frame nearest t={middle} ns: index {rec.nearest(middle).index}")

        start = time.perf_counter()
        for _frame in rec.play(rate=2.0):
            pass
        print(
            f"replayed {rec.duration:.2f} s of frames at 2x in {time.perf_counter() - start:.2f} s"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
