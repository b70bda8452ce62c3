"""Write a small format-version-1 recording, as pcdcodec wrote them before metadata digests.

``tests/test_integrity.py`` opens it on every run, so files written by earlier versions stay
readable. Existing goldens are never rewritten.
Run: ``python tests/golden/make_recording_golden.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
GOLDEN = HERE / "recording" / "v1-ffv1-zstd.pcdc"
WIDTH, HEIGHT, FRAMES = 64, 48, 4


def golden_frames() -> list[tuple[np.ndarray[Any, Any], np.ndarray[Any, Any], int]]:
    """The (color, depth, timestamp) frames the golden recording holds, rebuilt exactly."""
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    frames = []
    for i in range(FRAMES):
        color = np.stack(
            [(xx * 4 + i * 8) % 256, (yy * 5 + i * 3) % 256, ((xx + yy) * 2) % 256], axis=-1
        ).astype(np.uint8)
        depth = (1000 + xx * 7 + yy * 11 + i * 13).astype(np.uint16)
        depth[:4, :4] = 0
        frames.append((color, depth, 1_000_000_000 + i * 33_333_333))
    return frames


def main() -> int:
    import pcdcodec

    if GOLDEN.exists():
        print(f"{GOLDEN} exists; goldens are never rewritten")
        return 1
    cam = pcdcodec.CameraIntrinsics(WIDTH, HEIGHT, 52.5, 52.5, 31.5, 23.5)
    with pcdcodec.open(
        GOLDEN,
        "w",
        intrinsics=cam,
        depth_scale=5000.0,
        color="ffv1",
        depth="zstd",
        metadata={"site": "lab"},
    ) as rec:
        for color, depth, ts in golden_frames():
            rec.write(color, depth, ts)
    print(f"wrote {GOLDEN} ({GOLDEN.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
