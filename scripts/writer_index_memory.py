"""Memory a recording writer holds per frame as a recording grows (the summary's index).

Run: ``python scripts/writer_index_memory.py [--frames 6000]``.

Writes ``--frames`` small depth-only frames (160x120, zstd) and reports the Python memory
(tracemalloc) still held after 1,000 frames and at the end, per frame in between: what a long
recording adds, with the writer's packed chunk index and with mcap's own list of records.
"""

from __future__ import annotations

import argparse
import tempfile
import tracemalloc
from pathlib import Path

import numpy as np

import pcdcodec
from pcdcodec.recording import _header


def grow(frames: int, packed: bool) -> float:
    """Bytes held per frame between frame 1,000 and the last."""
    saved = _header._CHUNK_INDEXES
    if not packed:
        _header._CHUNK_INDEXES = "_left_as_mcap_keeps_it"
    try:
        cam = pcdcodec.CameraIntrinsics(160, 120, 130.0, 130.0, 80.0, 60.0)
        depth = (np.arange(160 * 120, dtype=np.uint16) % 4000).reshape(120, 160)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "grow.pcdc"
            tracemalloc.start()
            with pcdcodec.open(path, "w", intrinsics=cam, color=None, depth="zstd") as w:
                for k in range(frames):
                    w.write(None, depth, k * 33_000_000)
                    if k == 1000:
                        w.flush()
                        base = tracemalloc.get_traced_memory()[0]
                w.flush()
                end = tracemalloc.get_traced_memory()[0]
            tracemalloc.stop()
        return (end - base) / (frames - 1001)
    finally:
        _header._CHUNK_INDEXES = saved


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=6000)
    args = parser.parse_args()
    for packed in (False, True):
        per_frame = grow(args.frames, packed)
        what = "packed chunk index" if packed else "mcap's ChunkIndex records"
        ten_minutes = per_frame * 30 * 600 / 2**20
        print(
            f"{what}: {per_frame:,.0f} bytes held per frame ({ten_minutes:,.1f} MiB per 10 "
            "minutes of one camera at 30 fps)"
        )


if __name__ == "__main__":
    main()
