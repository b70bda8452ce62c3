"""Encode and decode the bundled sample's depth with every depth codec.

Prints, per codec: the mean size of one encoded frame, the ratio against raw uint16 depth,
encode and decode milliseconds per frame, and whether every frame came back bit-exact.

Run: ``python examples/roundtrip_sample.py`` (or ``scripts/run demo``).
"""

from __future__ import annotations

import sys
import time

import numpy as np

import pcdcodec
from pcdcodec.datasets import load_sample


def main() -> int:
    sample = load_sample()
    depths = sample.depths
    raw = sum(d.nbytes for d in depths)
    h, w = depths[0].shape
    print(f"bundled sample: {len(depths)} frames of {w}x{h} uint16 depth (TUM fr1_rpy, CC BY 4.0)")
    print(f"raw depth: {raw / len(depths) / 1024:.0f} KiB per frame\n")
    header = f"{'codec':8} {'KiB/frame':>9} {'ratio':>7} {'enc ms':>7} {'dec ms':>7}  bit-exact"
    print(header)
    print("-" * len(header))
    all_exact = True
    for name in pcdcodec.list_codecs("depth", available_only=True):
        codec = pcdcodec.get_codec(name)
        t0 = time.perf_counter()
        encoded = [codec.encode(d) for d in depths]
        t1 = time.perf_counter()
        decoded = [codec.decode(b) for b in encoded]
        t2 = time.perf_counter()
        exact = all(
            np.array_equal(a, b) and a.dtype == b.dtype
            for a, b in zip(depths, decoded, strict=True)
        )
        all_exact &= exact
        size = sum(len(b) for b in encoded)
        mark = " (default)" if name == pcdcodec.DEFAULT_DEPTH_CODEC else ""
        print(
            f"{name:8} {size / len(depths) / 1024:9.1f} {raw / size:6.1f}x "
            f"{1000 * (t1 - t0) / len(depths):7.2f} {1000 * (t2 - t1) / len(depths):7.2f}  "
            f"{'yes' if exact else 'NO'}{mark}"
        )
    return 0 if all_exact else 1


if __name__ == "__main__":
    sys.exit(main())
