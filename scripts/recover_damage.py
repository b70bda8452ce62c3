"""What ``pcdcodec recover`` keeps of recordings damaged at many points, against what the
digests say is intact.

Each present sequence of ``../shared/data`` (TUM fr1_rpy, RealSense D435, 7-Scenes) is
recorded with the default codecs; then, per number of points and seed, that many bytes spread
over the frames' chunks are flipped, the file is recovered, and the outcome is compared with
what the undamaged file says must come back (:mod:`pcdcodec.bench.damage`): frames left out,
frames kept without color. Every kept frame's depth is compared with the original, byte for
byte. Prints, per sequence and number of points, the ranges over the seeds.

    python scripts/recover_damage.py [--points 20 50] [--seeds 5] [--sets tum_fr1_rpy ...]
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Any

import pcdcodec
from pcdcodec.bench.damage import Layout, expected, flip
from pcdcodec.bench.sequences import SEQUENCES

SETS = ["tum_fr1_rpy", "realsense_d435", "7scenes_redkitchen"]


def trial(layout: Layout, depth: dict[int, bytes], points: int, seed: int, tmp: Path) -> Any:
    rng = random.Random(seed)
    first, last = layout.frames_span
    flips = sorted(rng.randrange(first, last) for _ in range(points))
    src = flip(layout, tmp / "damaged.pcdc", flips)
    out = tmp / "recovered.pcdc"
    dropped, no_color = expected(layout, flips)
    try:
        got = pcdcodec.recover(src, out, overwrite=True)
    except pcdcodec.PcdcodecError as exc:
        return {"refused": str(exc)}
    lost = {
        stream: {t for loss in got.lost if loss.stream == stream for t in loss.timestamps}
        for stream in ("frame", "color")
    }
    with pcdcodec.open(out) as rec:
        same = all(
            rec.depth_bytes(i) == depth[int(t)] for i, t in enumerate(rec.timestamps.tolist())
        )
        ok = rec.verify().ok
    return {
        "kept": int(got),
        "with_color": int(got) - got.color_missing,
        "depth_only": got.color_missing,
        "dropped": got.dropped,
        "intact": len(layout.times) - len(dropped),
        "intact_color": len(layout.times) - len(dropped) - len(no_color),
        "agrees": lost["frame"] == dropped and lost["color"] == no_color and same and ok,
    }


def span(values: list[int]) -> str:
    return f"{min(values)}" if min(values) == max(values) else f"{min(values)}-{max(values)}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="+", default=[20, 50])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--sets", nargs="+", default=SETS, choices=SETS)
    args = parser.parse_args()
    warnings.simplefilter("ignore", pcdcodec.errors.IncompleteRecordingWarning)
    print(
        "| set | points | frames | kept with color | depth only | left out | digests say intact "
        "(with color) | agrees | refused |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        for set_name in args.sets:
            seq = SEQUENCES[set_name]
            if not seq.present:
                print(f"({set_name}: not present, skipped)", file=sys.stderr)
                continue
            path = tmp / f"{set_name}.pcdc"
            with pcdcodec.open_source(seq.root, **seq.reader_options()) as source:
                pcdcodec.encode(source, path)
            layout = Layout.of(path)
            with pcdcodec.open(path) as rec:
                depth = {int(t): rec.depth_bytes(i) for i, t in enumerate(rec.timestamps.tolist())}
            for points in args.points:
                rows = [trial(layout, depth, points, seed, tmp) for seed in range(args.seeds)]
                done = [r for r in rows if "refused" not in r]
                refused = len(rows) - len(done)
                if not done:
                    print(
                        f"| {set_name} | {points} | {len(layout.times)} | - | - | - | - | - | "
                        f"{refused} |"
                    )
                    continue
                print(
                    f"| {set_name} | {points} | {len(layout.times)} "
                    f"| {span([r['with_color'] for r in done])} "
                    f"| {span([r['depth_only'] for r in done])} "
                    f"| {span([r['dropped'] for r in done])} "
                    f"| {span([r['intact'] for r in done])} "
                    f"({span([r['intact_color'] for r in done])}) "
                    f"| {sum(r['agrees'] for r in done)}/{len(done)} | {refused} |"
                )
                for r in rows:
                    if "refused" in r:
                        print(f"  refused: {r['refused']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
