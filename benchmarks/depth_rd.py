"""Bounded-error depth on every sequence: the ratio table and the rate–distortion comparison.

1. Ratio table: ``depthac`` with ``max_rel_error`` 0.5 % and 1 % against raw uint16 on every
   depth test set (the sequences, their sparse variants and the Spot frame), beside lossless
   ``depthac`` and log depth quantised to the same bound and coded with JPEG XL effort 2. The
   largest relative error measured is printed too (it must stay at or below the bound).
2. Rate–distortion: :func:`pcdcodec.bench.depth_rd.depth_rd` on consecutive frames of each
   real sequence and on the Spot frame; a markdown table and one PNG per sequence.

Ratios do not depend on the machine; times in the RD table are single-core but taken on
whatever load the machine has (use ``benchmarks/test_bench_depth_sets.py``-style runs for
speed). Run: ``python benchmarks/depth_rd.py [--frames 30] [--ratio-frames 10] [--out docs]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib

from pcdcodec.bench.depth_rd import (
    _log_jpegxl,
    _ours,
    depth_rd,
    plot_depth_rd,
    rd_markdown,
)
from pcdcodec.bench.sequences import DEPTH_SETS, SEQUENCES, load_frames, read_image
from pcdcodec.depth.depthac import DepthAC


def _scale(name: str) -> float:
    return 1000.0 if name == "spot" else SEQUENCES[name.removesuffix("-sparse")].depth_scale


def _max_rel(frames: list[Any], decoded: list[Any]) -> float:
    worst = 0.0
    for ref, got in zip(frames, decoded, strict=True):
        v = ref > 0
        if v.any():
            r = ref[v].astype(np.float64)
            worst = max(worst, float(np.max(np.abs(got[v] - r) / r)))
    return worst


def ratio_table(count: int) -> None:
    print(
        "| set | lossless depthac | 0.5 %: ours | 0.5 %: log + JPEG XL e2 "
        "| 1 %: ours | 1 %: log + JPEG XL e2 | largest error, ours (0.5 % / 1 %) |"
    )
    print("|---|---|---|---|---|---|---|")
    lossless = DepthAC()
    for name in DEPTH_SETS:
        try:
            frames = load_frames(name, count)
        except BaseException:  # pytest.skip outside pytest: the set is absent
            continue
        raw = sum(f.nbytes for f in frames)
        cells = [f"{raw / sum(len(lossless.encode(f)) for f in frames):.1f}×"]
        worst = []
        for rel in (0.005, 0.01):
            sizes, decoded, _, _ = _ours(frames, _scale(name), rel)
            cells.append(f"**{raw / sum(sizes):.1f}×**")
            worst.append(f"{100 * _max_rel(frames, decoded):.3f} %")
            sizes, _, _, _ = _log_jpegxl(frames, _scale(name), rel)
            cells.append(f"{raw / sum(sizes):.1f}×")
        print(f"| {name} ({len(frames)} frames) | {' | '.join(cells)} | {' / '.join(worst)} |")


def float_table(count: int) -> None:
    """depthac's bounded ratio on float32 metres (NaN holes), against raw uint16 of the same
    frames, with the bound checked on every pixel."""
    print("| set | 0.5 % | 1 % |")
    print("|---|---|---|")
    for name in DEPTH_SETS:
        try:
            frames = load_frames(name, count)
        except BaseException:  # absent
            continue
        raw = sum(f.nbytes for f in frames)
        cells = []
        for rel in (0.005, 0.01):
            codec = DepthAC(max_rel_error=rel)
            size = 0
            for f in frames:
                metres = (f / _scale(name)).astype(np.float32)
                metres[f == 0] = np.nan
                data = codec.encode(metres)
                size += len(data)
                back = codec.decode(data)
                valid = f > 0
                assert np.array_equal(np.isnan(back), ~valid)
                want = metres[valid].astype(np.float64)
                assert np.all(np.abs(back[valid] - want) <= rel * want)
            cells.append(f"{raw / size:.1f}×")
        print(f"| {name} | {' | '.join(cells)} |")


def near_table(count: int) -> None:
    """depthac's ratio when bounded frames use near-lossless coding with tolerance N (the
    lattice table, error bounded inside the prediction loop) against N = 0 (levels fitted to
    the frame, coded exactly): what chose N = 0."""
    print("| set | bound | N = 0 (fitted levels) | N = 1 | N = 2 | N = 3 |")
    print("|---|---|---|---|---|---|")
    saved = DepthAC.bounded_near
    try:
        for name in DEPTH_SETS:
            try:
                frames = load_frames(name, count)
            except BaseException:  # absent
                continue
            raw = sum(f.nbytes for f in frames)
            for rel in (0.005, 0.01):
                cells = []
                for near in range(4):
                    DepthAC.bounded_near = near
                    codec = DepthAC(max_rel_error=rel)
                    cells.append(f"{raw / sum(len(codec.encode(f)) for f in frames):.1f}×")
                print(f"| {name} | {100 * rel:g} % | {' | '.join(cells)} |")
    finally:
        DepthAC.bounded_near = saved


def rd_tables(count: int, out: Path | None) -> None:
    sets: dict[str, tuple[list[Any], float]] = {}
    for name, seq in SEQUENCES.items():
        if name == "sample" or not seq.present:
            continue
        sets[name] = ([read_image(p) for p in seq.depth_paths()[:count]], seq.depth_scale)
    with contextlib.suppress(BaseException):
        sets["spot"] = (load_frames("spot", 1), 1000.0)
    for name, (frames, scale) in sets.items():
        points = depth_rd(
            frames, scale, sequence=name, progress=lambda m: print(f"  {m}", file=sys.stderr)
        )
        print()
        print(rd_markdown(points))
        if out is not None:
            path = plot_depth_rd(
                points, out / f"depth_rd_{name}.png", title=f"{name}, {len(frames)} frames"
            )
            print(f"\nwrote {path}", file=sys.stderr)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30, help="consecutive frames for RD")
    parser.add_argument("--ratio-frames", type=int, default=10, help="frames for the ratios")
    parser.add_argument("--out", type=Path, default=None, help="folder for the PNG plots")
    parser.add_argument("--no-rd", action="store_true", help="only the ratio table")
    parser.add_argument("--near", action="store_true", help="add the near-lossless sweep")
    parser.add_argument("--float", action="store_true", help="add float32 metres ratios")
    args = parser.parse_args()
    ratio_table(args.ratio_frames)
    if args.float:
        print()
        float_table(args.ratio_frames)
    if args.near:
        print()
        near_table(args.ratio_frames)
    if not args.no_rd:
        rd_tables(args.frames, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
