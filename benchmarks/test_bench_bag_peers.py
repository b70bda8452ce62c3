"""A whole bag under the peers a bag's ``.pcdc`` is measured against: MCAP zstd chunks at ROS 2's
default level and at 19, ROS 1 lz4 chunks, and Cloudini at 1 mm on the PointCloud2 topics.

The bags: one of organized 640×480 XYZRGB clouds at 15 Hz made from the bundled sample's real
frames (with ``/tf`` beside them), and the real Spot bag of ``../shared/data`` when present.
Each row records the peer's size and ratio; ``scripts/bag_peers.py`` prints the full table for
any bags. Cloudini runs only with ``pureini`` installed (``pcdcodec[peers]``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pcdcodec.bench import bag_peers
from pcdcodec.bench.sequences import SPOT_BAG
from pcdcodec.datasets import load_sample

FRAMES = 2

PEERS: dict[str, Callable[[Path, Path], bag_peers.BagPeerResult]] = {
    "mcap-zstd-1": lambda bag, out: bag_peers.mcap_zstd(bag, out),
    "mcap-zstd-19": lambda bag, out: bag_peers.mcap_zstd(bag, out, level=bag_peers.ZSTD_MAX_LEVEL),
    "ros1-lz4": bag_peers.ros1_lz4,
    "cloudini-1mm": bag_peers.cloudini,
}


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    sample = load_sample()
    frames = [sample[i * len(sample) // FRAMES] for i in range(FRAMES)]
    out = {
        "pointcloud2": bag_peers.write_cloud_bag(
            tmp_path_factory.mktemp("bags") / "clouds",
            [f.depth for f in frames],
            [f.color for f in frames],
            sample.intrinsics,
            sample.depth_scale,
        )
    }
    if SPOT_BAG.is_file():
        out["spot-raw"] = SPOT_BAG
    return out


@pytest.mark.parametrize("bag_name", ["pointcloud2", "spot-raw"])
@pytest.mark.parametrize("peer", list(PEERS))
def test_bag_peer(
    benchmark: Any, bags: dict[str, Path], tmp_path: Path, peer: str, bag_name: str
) -> None:
    if bag_name not in bags:
        pytest.skip(f"{SPOT_BAG} is not present")
    if peer.startswith("cloudini"):
        pytest.importorskip("pureini")
    bag = bags[bag_name]
    out = tmp_path / ("peer.bag" if peer == "ros1-lz4" else "peer.mcap")
    benchmark.group = f"bag peers: {bag_name}"

    def run() -> bag_peers.BagPeerResult:
        out.unlink(missing_ok=True)
        return PEERS[peer](bag, out)

    result = benchmark.pedantic(run, rounds=2, iterations=1, warmup_rounds=0)
    assert result.bytes_out == out.stat().st_size > 0  # written, not just timed
    assert result.messages == (2 * FRAMES if bag_name == "pointcloud2" else 4)
    benchmark.extra_info.update(
        kind="bag-peer",
        bag=bag_name,
        peer=peer,
        bytes_in=result.bytes_in,
        bytes_out=result.bytes_out,
        ratio=result.ratio,
        mb_per_s=result.bytes_in / 1e6 / result.seconds,
    )
