"""What keeping a bag's camera messages exactly costs: the bytes the envelopes add to a
recording, per camera message (``docs/format.md``, "Format version 4: kept topics").

Run: ``python scripts/envelope_overhead.py --kind ros1 --seconds 2``. Writes a robot bag
(:mod:`pcdcodec.bench.robot_bags`, camera topics and ``/tf_static`` only) from the RealSense
sequence, encodes it twice, with the camera topics' envelopes and without them (the camera
topics left out with ``exclude_topics``), and prints both sizes, the camera messages kept
and the difference per message, as the envelopes sit in the file (zstd chunks).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench import robot_bags as rb
from pcdcodec.bench.sequences import SEQUENCES


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kind", choices=rb.KINDS, default="ros1")
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--color", default=None, help="color codec (default: the default)")
    args = parser.parse_args(argv)
    seq = SEQUENCES["realsense_d435"]
    if not seq.present:
        print(f"{seq.root} is not present", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / ("robot.bag" if args.kind == "ros1" else "robot")
        summary = rb.write_robot_bag(
            bag, rb.SequenceFrames("realsense_d435", 30), kind=args.kind,
            intrinsics=seq.camera, depth_scale=seq.depth_scale, seconds=args.seconds,
            extras=False,
        )  # fmt: skip
        options = {"color": args.color} if args.color else {}
        leave_out = [rb.CLOUD, rb.DEPTH]  # not read into frames: kept as they are either way
        sizes = {}
        for name, extra in (("with", []), ("without", [rb.ALIGNED, rb.COLOR])):
            out = Path(tmp) / f"{name}.pcdc"
            pcdcodec.encode(summary.path, out, exclude_topics=leave_out + extra, **options)
            sizes[name] = out.stat().st_size
        with pcdcodec.open(Path(tmp) / "with.pcdc") as rec:
            messages = sum(1 for _ in rec.camera_messages())
    added = sizes["with"] - sizes["without"]
    print(f"bag kind {args.kind}, {args.seconds:g} s, {messages} camera messages")
    print(f"recording with envelopes {sizes['with']} B, without {sizes['without']} B")
    print(f"envelopes add {added} B: {added / messages:.1f} B per camera message")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
