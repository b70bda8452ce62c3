"""What the low-delay encoder defaults cost: color stream size and PSNR, low_delay on vs off.

Run: ``python benchmarks/low_delay_cost.py [--frames 120] [--codecs h264,h265,av1,vp9]``.

With ``low_delay`` (the default of every codec that has it) the video encoder holds no frame
back, so a crash loses at most the writer's ``in_flight`` queue; without it x264, x265, libvpx
and SVT-AV1 hold up to dozens of frames for their lookahead. This prints, for every sequence
present (the bundled sample and ``../shared/data``), the stream size and PSNR of each codec
both ways, the largest number of frames the encoder held back, and the size change of the
color stream and of a whole recording with the default depth codec.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.color import StreamCodec, decode_packets
from pcdcodec.datasets import open_folder
from pcdcodec.metrics import psnr


def measure(codec: StreamCodec, frames: list[np.ndarray]) -> tuple[int, float, int]:
    """Stream bytes, mean PSNR (dB) and the most frames the encoder held back at once."""
    h, w = frames[0].shape[:2]
    encoder = codec.encoder(w, h, 30.0)
    packets = []
    held = 0
    for i, rgb in enumerate(frames):
        packets += encoder.encode(rgb, i * 33_333_333)
        held = max(held, i + 1 - len(packets))
    packets += encoder.flush()
    decoded = decode_packets(codec, packets, w, h, encoder.extradata)
    scores = [psnr(a, d.rgb) for a, d in zip(frames, decoded, strict=True)]
    return sum(len(p.data) for p in packets), float(np.mean(scores)), held


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=120, help="frames per sequence")
    parser.add_argument("--codecs", default="h264,h265,av1,vp9,h264-lossless")
    args = parser.parse_args()
    names = [n for n in args.codecs.split(",") if pcdcodec.codec_class(n).is_available()]
    print(
        "| sequence | codec | frames | held on/off | color KiB/frame on | off | color size "
        "| recording size | PSNR on | off |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    depth_codec = pcdcodec.get_codec(pcdcodec.DEFAULT_DEPTH_CODEC, kind="depth")
    assert isinstance(depth_codec, pcdcodec.FrameCodec)
    for name, info in SEQUENCES.items():
        if not info.present:
            continue
        source = open_folder(info.root, max_frames=args.frames, depth_scale=info.depth_scale)
        frames = []
        depth_bytes = 0
        for f in source:
            frames.append(f.color)
            depth_bytes += len(depth_codec.encode(f.depth))
        for codec_name in names:
            on = measure(pcdcodec.get_codec({"id": codec_name, "low_delay": True}), frames)
            off = measure(pcdcodec.get_codec({"id": codec_name, "low_delay": False}), frames)
            n = len(frames)
            change = 100.0 * (on[0] / off[0] - 1.0)
            whole = 100.0 * ((on[0] + depth_bytes) / (off[0] + depth_bytes) - 1.0)
            lossless = on[1] == float("inf")
            print(
                f"| {name} | {codec_name} | {n} | {on[2]}/{off[2]} | {on[0] / n / 1024:.1f} | "
                f"{off[0] / n / 1024:.1f} | {change:+.1f} % | {whole:+.1f} % | "
                f"{'lossless' if lossless else f'{on[1]:.2f}'} | "
                f"{'lossless' if lossless else f'{off[1]:.2f}'} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
