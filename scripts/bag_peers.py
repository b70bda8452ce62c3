"""What whole bags cost under the tools people keep bags small with: the peers a bag's ``.pcdc``
is measured against.

Run: ``python scripts/bag_peers.py [--as-shipped] [--clouds N] [--keep DIR] BAG...`` (ROS 1
``.bag`` files, ROS 2 bag folders or their ``.db3``/``.mcap`` files). With no BAG, the real bags
in ``../shared/data/bags`` are measured. ``--clouds N`` adds a ROS 2 mcap bag of N organized
640×480 XYZRGB PointCloud2 clouds at 15 Hz made from the bundled sample's real frames (none of
the real bags holds a PointCloud2).

For each bag it prints the bag's size and, in bytes and as the bag's size over theirs: every
message in one MCAP file with zstd chunks at ROS 2's default level (1) and at level 19, the bag
as ROS 1 with lz4 chunks, and Cloudini (``pureini``) at its default 1 mm on the PointCloud2
topics with every other topic kept (packed colour kept exact; ``--as-shipped`` adds a column
where it is quantized too, as ``cloudini_rosbag_converter`` does). The files are written to a
temporary folder (``--keep DIR`` keeps them there) and removed.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pcdcodec.bench import bag_peers
from pcdcodec.bench.sequences import SHARED_DATA
from pcdcodec.datasets import load_sample
from pcdcodec.errors import CodecUnavailableError

REAL_BAGS = [
    SHARED_DATA / "bags" / "realsense" / "single_depth_color_640x480.bag",
    SHARED_DATA / "bags" / "spot" / "raw.bag",
    SHARED_DATA / "bags" / "spot" / "compressed.bag",
    SHARED_DATA / "bags" / "spot" / "compressedDepth.bag",
    SHARED_DATA / "bags" / "ros2-converted" / "rs_ros2_mcap",
    SHARED_DATA / "bags" / "ros2-converted" / "spot_ros2_mcap",
    SHARED_DATA / "bags" / "ros2-converted" / "spot_ros2_sqlite",
]


def _cell(result: bag_peers.BagPeerResult | None) -> str:
    if result is None:
        return f"{'-':>18}"
    return f"{result.bytes_out:>11,} {result.ratio:5.2f}×"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("bags", nargs="*", type=Path, help="bags (default: the shared real bags)")
    parser.add_argument("--keep", type=Path, help="write the peers' files here and keep them")
    parser.add_argument(
        "--clouds", type=int, default=0, help="add a bag of this many PointCloud2 clouds"
    )
    parser.add_argument(
        "--as-shipped", action="store_true", help="add Cloudini quantizing packed colour too"
    )
    args = parser.parse_args()
    bags = args.bags or [b for b in REAL_BAGS if b.exists()]
    if not bags and not args.clouds:
        parser.error(f"no bags given and none in {SHARED_DATA / 'bags'}")
    columns = ["mcap zstd 1", "mcap zstd 19", "ros1 lz4", "cloudini 1 mm"]
    if args.as_shipped:
        columns.append("cloudini, rgb lost")
    notes: list[str] = []
    with tempfile.TemporaryDirectory(prefix="bag-peers-") as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        if args.clouds:
            sample = load_sample()  # real TUM frames, color paired with depth
            frames = [sample[i % len(sample)] for i in range(args.clouds)]
            bags.append(
                bag_peers.write_cloud_bag(
                    root / f"pointcloud2_x{args.clouds}",
                    [f.depth for f in frames],
                    [f.color for f in frames],
                    sample.intrinsics,
                    sample.depth_scale,
                )
            )
        print(f"| {'bag':36} | {'bytes':>11} | " + " | ".join(f"{c:>18}" for c in columns) + " |")
        print(f"|{'-' * 38}|{'-' * 13}|" + "|".join("-" * 20 for _ in columns) + "|")
        for i, bag in enumerate(bags):
            stem = f"{i}-{bag.name.removesuffix('.bag')}"
            row: list[bag_peers.BagPeerResult | None] = [
                bag_peers.mcap_zstd(bag, root / f"{stem}.zstd1.mcap"),
                bag_peers.mcap_zstd(
                    bag, root / f"{stem}.zstd19.mcap", level=bag_peers.ZSTD_MAX_LEVEL
                ),
                bag_peers.ros1_lz4(bag, root / f"{stem}.lz4.bag"),
            ]
            variants = [bag_peers.PACKED_COLOR] + ([()] if args.as_shipped else [])
            for n, exact in enumerate(variants):
                try:
                    row.append(
                        bag_peers.cloudini(
                            bag, root / f"{stem}.cloudini{n}.mcap", exact_fields=exact
                        )
                    )
                except CodecUnavailableError as exc:
                    row.append(None)
                    if str(exc) not in notes:
                        notes.append(str(exc))
            size = bag_peers.bag_bytes(bag)
            print(f"| {bag.name:36} | {size:>11,} | " + " | ".join(_cell(r) for r in row) + " |")
    print(
        "(bytes, and the bag's size over them; MCAP chunks of 768 KiB as ROS 2 records them, "
        "ROS 1 chunks of 768 KiB as rosbag record; Cloudini in 2 MiB zstd-1 chunks as its "
        "converter writes)"
    )
    for note in notes:
        print(f"note: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
