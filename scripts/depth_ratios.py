"""Depth codec ratios over every sequence present, including sparse depth (Spot, 64 % valid).

Prints one markdown row per codec: the ratio against raw uint16 on each sequence and the range.
Ratios do not depend on the machine, so this runs anywhere; it reads the real sequences in
``../shared/data`` (skipping those absent) and the bundled sample.

Run: ``python scripts/depth_ratios.py [--frames 10]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import PRESENT, SHARED_DATA, load_depths

SPOT = SHARED_DATA / "bags" / "spot" / "raw.bag"


def spot_depth() -> list[np.ndarray[Any, Any]]:
    """The Spot front-left depth frame (424x240 mm, 64 % valid), read with rosbags."""
    from rosbags.highlevel import AnyReader

    if not SPOT.exists():
        return []
    with AnyReader([SPOT]) as reader:
        for conn, _, raw in reader.messages():
            if conn.topic == "/spot/depth/frontleft/image":
                msg = reader.deserialize(raw, conn.msgtype)
                data = np.frombuffer(bytes(msg.data), "<u2").reshape(msg.height, msg.width)
                return [data.copy()]
    return []


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()
    data = {name: load_depths(name, args.frames) for name in PRESENT}
    spot = spot_depth()
    if spot:
        data["spot (sparse)"] = spot
    # Scattered holes, as far-range or shiny scenes give: the sample with pixels dropped at
    # random (a fixed seed), keeping half and a fifth of the valid ones.
    rng = np.random.default_rng(0)
    for keep in (0.5, 0.2):
        holed = []
        for d in load_depths("sample", min(args.frames, 15)):
            d = d.copy()
            d[rng.random(d.shape) > keep] = 0
            holed.append(d)
        valid = np.mean([np.count_nonzero(d) / d.size for d in holed])
        data[f"sample, {100 * valid:.0f} % valid (random holes)"] = holed
    codecs = pcdcodec.list_codecs("depth", available_only=True)
    names = list(data)
    print("| codec | " + " | ".join(names) + " | range |")
    print("|---|" + "---|" * (len(names) + 1))
    for name in codecs:
        codec = pcdcodec.get_codec(name)
        ratios = []
        for frames in data.values():
            size = sum(len(codec.encode(d)) for d in frames)
            ratios.append(sum(d.nbytes for d in frames) / size)
        cells = " | ".join(f"{r:.2f}" for r in ratios)
        print(f"| {name} | {cells} | {min(ratios):.1f}–{max(ratios):.1f}× |")
    valid = {n: float(np.mean([np.count_nonzero(d) / d.size for d in f])) for n, f in data.items()}
    print()
    print("valid depth pixels: " + ", ".join(f"{n} {100 * v:.0f} %" for n, v in valid.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
