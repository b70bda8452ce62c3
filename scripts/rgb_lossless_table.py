"""Lossless colour, per set: pcdcodec's camera-aware coder (``pcdcodec.color.rgb_lossless``)
against lossless JPEG XL (effort 1, what kept colours took before) and JPEG-LS on the RGB
pixels, on every ``--step``-th frame of each set in ``../shared/data`` (and the bundled TUM
sample). Prints, per set, the model found, the mean bytes a frame, the range over the frames of
the coder's bytes over JPEG XL's, and the median encode and decode times (one thread; the
coders interleaved frame by frame, so the times compare within a row).

Run: ``python scripts/rgb_lossless_table.py [--frames 60] [--step 6]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from pcdcodec.bench.sequences import SEQUENCES, load_colors
from pcdcodec.color import rgb_lossless

MODELS = {0: "planar", 1: "Bayer", 2: "YUY2"}


def _timed(fn, *args):  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    import imagecodecs

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--step", type=int, default=6)
    args = parser.parse_args(argv)
    print(
        "| set | model | ours (kB) | JPEG XL e1 (kB) | JPEG-LS RGB (kB) | ours / JPEG XL, "
        "range | ours enc / dec (ms) | JPEG XL enc / dec (ms) |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name, seq in SEQUENCES.items():
        if not seq.present:
            continue
        frames = load_colors(name, args.frames)[:: args.step]
        rows = []
        models = set()
        for rgb in frames:
            rgb = np.ascontiguousarray(rgb)
            ours, t_enc = _timed(rgb_lossless.encode, rgb)
            back, t_dec = _timed(rgb_lossless.decode, ours, rgb.shape[:2])
            if not np.array_equal(back, rgb):
                raise SystemExit(f"{name}: a frame did not come back bit-exact")
            jxl, j_enc = _timed(
                lambda x: imagecodecs.jpegxl_encode(x, lossless=True, effort=1), rgb
            )
            _, j_dec = _timed(imagecodecs.jpegxl_decode, jxl)
            jls = imagecodecs.jpegls_encode(rgb)
            models.add(MODELS[rgb_lossless.model_of(rgb)[0]])
            rows.append((len(ours), len(jxl), len(jls), t_enc, t_dec, j_enc, j_dec))
        a = np.array(rows, dtype=np.float64)
        share = a[:, 0] / a[:, 1]
        med = np.median(a[:, 3:], axis=0) * 1e3
        print(
            f"| {name} ({len(frames)} frames) | {', '.join(sorted(models))} | "
            f"{a[:, 0].mean() / 1e3:.1f} | {a[:, 1].mean() / 1e3:.1f} | "
            f"{a[:, 2].mean() / 1e3:.1f} | {share.min():.2f}-{share.max():.2f} | "
            f"{med[0]:.1f} / {med[1]:.1f} | {med[2]:.1f} / {med[3]:.1f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
