"""What writing a recording again with another color codec costs in color, against writing the
camera's frames with that codec directly; depth is checked bit for bit.

Run: ``python scripts/recode_loss.py [--frames 15]``.

The bundled sample is recorded with the default codecs (h264, depthac), then that recording is
written again (``pcdcodec.encode(recording, ...)``) with each color codec below. Each line
gives the color PSNR (dB; mean and range over frames) against the sample's own color, of the
file written again and of the sample written straight with the same codec, and whether every
depth frame is the sample's, bit for bit, and the file's bytes.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

import pcdcodec

CODECS: dict[str, Any] = {
    "av1 gop=1 crf=52 (TRAINING_COLOR)": {
        "id": "av1",
        "gop": 1,
        "crf": 52,
        "preset": 8,
        "low_delay": True,
    },
    "h264 (default)": "h264",
    "ffv1 (lossless)": "ffv1",
}


def _psnr(a: Any, b: Any) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else float(10 * np.log10(255.0**2 / mse))


def _compare(path: Path, seq: Any) -> tuple[list[float], bool]:
    with pcdcodec.open(path) as rec:
        frames = list(rec)
    psnr = [_psnr(s.color, f.color) for s, f in zip(seq, frames, strict=True)]
    exact = all(np.array_equal(s.depth, f.depth) for s, f in zip(seq, frames, strict=True))
    return psnr, exact


def _line(name: str, path: Path, seq: Any) -> str:
    psnr, exact = _compare(path, seq)
    return (
        f"  {name:28} PSNR {np.mean(psnr):6.2f} dB ({min(psnr):.2f}-{max(psnr):.2f}), "
        f"depth bit-exact {exact}, {path.stat().st_size} bytes"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=15, help="frames of the sample")
    args = parser.parse_args(argv)
    seq = pcdcodec.load_sample(max_frames=args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        first = out / "run.pcdc"
        with pcdcodec.open(first, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale) as w:
            w.write_frames(seq)
        print(f"{len(seq)} frames of the sample; color PSNR against the sample's own color")
        print(_line("recorded (h264, depthac)", first, seq))
        for k, (name, color) in enumerate(CODECS.items()):
            print(name)
            again = out / f"again{k}.pcdc"
            pcdcodec.encode(first, again, color=color)
            print(_line("written again from it", again, seq))
            direct = out / f"direct{k}.pcdc"
            with pcdcodec.open(
                direct, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, color=color
            ) as w:
                w.write_frames(seq)
            print(_line("straight from the sample", direct, seq))
    return 0


if __name__ == "__main__":
    sys.exit(main())
