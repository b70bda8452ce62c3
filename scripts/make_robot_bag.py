"""Write a bag as a robot with a RealSense camera records it, from one of the real sequences in
``../shared/data`` (see :mod:`pcdcodec.bench.robot_bags`).

Run: ``python scripts/make_robot_bag.py --set realsense --kind ros2-mcap --seconds 30 -o run``.
Prints each topic's message count, the bag's size, how long writing took and the peak resident
memory. The sequence's frames are read from disk as they are written and looped when
``--seconds`` asks for more of them, so memory stays bounded however long the bag: at 640×480
and 30 fps a bag grows about 157 MB a second (color, depth twice, and the 15 Hz cloud), so
``--seconds 7`` is over 1 GB.

``--set tum`` writes TUM's depth as it is (5000 units a metre): a reader must be told
``depth_scale=5000``, as ROS reads 16UC1 as millimetres. The other two sets are in millimetres.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pcdcodec.bench.robot_bags import KINDS, SequenceFrames, write_robot_bag

SETS = {"tum": "tum_fr1_rpy", "realsense": "realsense_d435", "7scenes": "7scenes_redkitchen"}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--set", choices=sorted(SETS), default="realsense")
    parser.add_argument("--kind", choices=KINDS, default="ros1")
    parser.add_argument(
        "--seconds", type=float, default=None, help="length (default: one pass over the frames)"
    )
    parser.add_argument("--frames", type=int, default=None, help="use the first N frames only")
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--cloud-hz", type=float, default=15.0)
    parser.add_argument("--no-extras", action="store_true", help="camera topics and tf_static only")
    parser.add_argument(
        "--split-mb", type=float, default=None, help="ROS 2: a new file every this many MB"
    )
    parser.add_argument("--compression", choices=("lz4", "bz2"), default=None, help="ROS 1 chunks")
    parser.add_argument("-o", "--output", type=Path, required=True)
    args = parser.parse_args(argv)

    name = SETS[args.set]
    frames = SequenceFrames(name, args.frames)
    if not frames.sequence.present:
        print(f"error: {frames.sequence.root} is not present", file=sys.stderr)
        return 1
    output = args.output
    if args.kind == "ros1" and output.suffix != ".bag":  # rosbags' AnyReader knows it by that
        print(f"error: a ROS 1 bag's name ends in .bag, got {str(output)!r}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    summary = write_robot_bag(
        output,
        frames,
        kind=args.kind,
        intrinsics=frames.intrinsics,
        depth_scale=frames.depth_scale,
        fps=args.fps,
        seconds=args.seconds,
        cloud_hz=args.cloud_hz,
        extras=not args.no_extras,
        split_bytes=None if args.split_mb is None else round(args.split_mb * 1e6),
        compression=args.compression,
    )
    took = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    width = max(map(len, summary.topics))
    for topic, count in summary.topics.items():
        print(f"{topic:<{width}}  {count:>7}")
    mb = summary.bytes / 1e6
    print(
        f"{summary.path}: {args.kind} from {name}, {mb:.1f} MB in {len(summary.files)} file(s), "
        f"{summary.duration_s:.2f} s of messages; written in {took:.1f} s "
        f"({mb / took:.0f} MB/s), peak memory {peak:.0f} MB"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
