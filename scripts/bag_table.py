"""The whole-bag table: each bag as a ``.pcdc`` and under the tools people keep bags small with.

Run: ``python scripts/bag_table.py [BAG...] [--robot SET:KIND:SECONDS[:SPLIT_MB]]... [--fx ...]``.
With neither BAG nor ``--robot``, the real bags in ``../shared/data/bags`` are measured (the
Spot bags with the Spot depth camera's intrinsics, which they lack). ``--robot`` writes a bag as
a robot with a RealSense records it (:func:`pcdcodec.bench.robot_bags.write_robot_bag`; SET is
tum, realsense or 7scenes, KIND ros1, ros2-sqlite3 or ros2-mcap, SPLIT_MB splits a ROS 2 bag),
measures it and removes it. ``--fx --fy --cx --cy --depth-scale`` fill in what the given BAGs
lack; ``--exclude-topic PATTERN`` keeps those topics out of the ``.pcdc`` (``'*'``: the camera
alone, to time the encode of one camera).

For each bag, one row (see :mod:`pcdcodec.bench.bag_table`): its size; the ``.pcdc`` of
``pcdcodec.encode`` at the defaults (every other topic kept) and the bag's size over it; the bag
under MCAP zstd at ROS 2's default level (1) and at 19, as ROS 1 with lz4 chunks (ROS 1 bags),
and with Cloudini at 1 mm on its PointCloud2 topics (bags that have some); MCAP zstd 1's size
over the ``.pcdc``'s; the kept topics' chunks in the ``.pcdc`` against the same topics alone
under MCAP zstd 1; encode and export (``pcdcodec export --to`` the bag's own kind) throughput in
MB of the original bag a second, the encode's frames a second against the bag's frame rate, and
each one's peak resident memory (each runs in a process of its own). Files are written under
``--work`` (default: a temporary folder) and removed once measured.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pcdcodec.bench import bag_table
from pcdcodec.bench.robot_bags import KINDS, SequenceFrames, write_robot_bag
from pcdcodec.bench.sequences import SHARED_DATA

SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}
BAGS = SHARED_DATA / "bags"
#: The real bags, each with what pcdcodec must be told about it.
REAL_BAGS: list[tuple[Path, dict[str, Any]]] = [
    # Its color frame is further from its depth frames than the default pairing tolerance.
    (BAGS / "realsense" / "single_depth_color_640x480.bag", {"max_difference": 150_000_000}),
    (BAGS / "spot" / "raw.bag", {"intrinsics": SPOT_CAMERA}),
    (BAGS / "spot" / "compressed.bag", {"intrinsics": SPOT_CAMERA}),
    (BAGS / "spot" / "compressedDepth.bag", {"intrinsics": SPOT_CAMERA}),
    # Its color camera's pose is not in the bag (no tf): depth only, the color topic kept.
    (BAGS / "ros2-converted" / "rs_ros2_mcap", {"color_topic": ""}),
    (BAGS / "ros2-converted" / "spot_ros2_mcap", {"intrinsics": SPOT_CAMERA}),
    (BAGS / "ros2-converted" / "spot_ros2_sqlite", {"intrinsics": SPOT_CAMERA}),
    (BAGS / "pyk4a_recording.mkv", {}),
]
SETS = {"tum": "tum_fr1_rpy", "realsense": "realsense_d435", "7scenes": "7scenes_redkitchen"}


def _robot(spec: str) -> tuple[str, str, float, float | None]:
    parts = spec.split(":")
    if len(parts) not in (3, 4) or parts[0] not in SETS or parts[1] not in KINDS:
        raise argparse.ArgumentTypeError(
            f"--robot {spec!r}: expected SET:KIND:SECONDS[:SPLIT_MB], SET one of "
            f"{', '.join(SETS)}, KIND one of {', '.join(KINDS)}"
        )
    return parts[0], parts[1], float(parts[2]), float(parts[3]) if len(parts) == 4 else None


def _commit() -> str:
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run(
        ["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        check=False,
    )
    return out.stdout.strip() or "unknown"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("bags", nargs="*", type=Path, help="bags (default: the shared real bags)")
    parser.add_argument(
        "--robot", action="append", type=_robot, default=[], help="SET:KIND:SECONDS[:SPLIT_MB]"
    )
    parser.add_argument("--work", type=Path, help="folder for the files written (temporary)")
    parser.add_argument(
        "--peers",
        default=",".join(bag_table.PEERS),
        help=f"comma-separated, among {','.join(bag_table.PEERS)} (default: all)",
    )
    parser.add_argument("--no-export", action="store_true", help="skip the export")
    parser.add_argument(
        "--exclude-topic",
        action="append",
        default=[],
        metavar="PATTERN",
        help="topics the encode does not keep (every bag; the peers still write them all)",
    )
    for name in ("fx", "fy", "cx", "cy", "depth-scale"):
        parser.add_argument(f"--{name}", type=float, help="for the given BAGs")
    args = parser.parse_args()
    peers = [p for p in args.peers.split(",") if p]
    given: dict[str, Any] = {}
    if args.fx is not None:
        given["intrinsics"] = {
            "fx": args.fx,
            "fy": args.fy or args.fx,
            "cx": args.cx,
            "cy": args.cy,
        }
    if args.depth_scale is not None:
        given["depth_scale"] = args.depth_scale
    if args.exclude_topic:
        given["exclude_topics"] = args.exclude_topic
    if args.bags or args.robot:
        todo: list[tuple[Path, dict[str, Any]]] = [(b, given) for b in args.bags]
    else:
        todo = [(b, o) for b, o in REAL_BAGS if b.exists()]

    def log(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    rows = []
    with tempfile.TemporaryDirectory(prefix="bag-table-", dir=args.work) as tmp:
        work = Path(tmp)
        for bag, options in todo:
            rows.append(
                bag_table.measure_bag(
                    bag, work, options=options, peers=peers, export=not args.no_export, log=log
                )
            )
        for set_name, kind, seconds, split_mb in args.robot:
            frames = SequenceFrames(SETS[set_name])
            if not frames.sequence.present:
                log(f"{frames.sequence.root} is not present: --robot {set_name} skipped")
                continue
            label = f"robot {set_name} {seconds:g} s" + (
                f" split {split_mb:g} MB" if split_mb else ""
            )
            path = work / (f"robot-{set_name}.bag" if kind == "ros1" else f"robot-{set_name}")
            log(f"{label}: writing {kind}")
            write_robot_bag(
                path,
                frames,
                kind=kind,
                intrinsics=frames.intrinsics,
                depth_scale=frames.depth_scale,
                seconds=seconds,
                split_bytes=None if split_mb is None else round(split_mb * 1e6),
            )
            # TUM's depth is in its own units (5000 a metre): the bag cannot say so.
            options = {"depth_scale": 5000.0, "override": True} if set_name == "tum" else {}
            if args.exclude_topic:
                options["exclude_topics"] = args.exclude_topic
                label += " (" + ", ".join(f"-{p}" for p in args.exclude_topic) + ")"
            try:
                rows.append(
                    bag_table.measure_bag(
                        path,
                        work,
                        name=label,
                        options=options,
                        peers=peers,
                        export=not args.no_export,
                        log=log,
                    )
                )
            finally:
                bag_table.remove_output(path)
            print("\n".join(bag_table.table(rows[-1:])[2:]), file=sys.stderr, flush=True)
    print(
        f"pcdcodec at commit {_commit()}; sizes in MB (1e6 bytes), throughput in MB of the "
        "original a second"
    )
    print("\n".join(bag_table.table(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
