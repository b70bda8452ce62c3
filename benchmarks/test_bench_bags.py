"""A whole robot bag recorded into a ``.pcdc``: ``pcdcodec.encode`` at the defaults on one
second of a ROS 1 bag as a robot with a RealSense records it (color, depth twice, the 15 Hz
organized cloud, their CameraInfo, tf, IMU, odometry, joint states, diagnostics), made from the
bundled sample's real frames. The camera topics are compressed and every other topic kept.

Its row joins the bag peers' table (``test_bench_bag_peers.py``) as the peer ``.pcdc``;
``scripts/bag_table.py`` prints the full table (peers, kept topics, memory) for any bags.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from pcdcodec.bench.robot_bags import SequenceFrames, write_robot_bag

SECONDS = 1.0
FPS = 30.0


@pytest.fixture(scope="module")
def robot_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    frames = SequenceFrames("sample")
    path = tmp_path_factory.mktemp("robot") / "robot.bag"
    write_robot_bag(
        path,
        frames,
        kind="ros1",
        intrinsics=frames.intrinsics,
        depth_scale=frames.depth_scale,
        fps=FPS,
        seconds=SECONDS,
    )
    return path


def test_encode_robot_bag(benchmark: Any, robot_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "robot.pcdc"
    benchmark.group = "bag peers: robot bag"

    def run() -> pcdcodec.EncodeSummary:
        # The sample is TUM's: 5000 depth units a metre, which a 16UC1 topic cannot say.
        return pcdcodec.encode(robot_bag, out, overwrite=True, depth_scale=5000.0, override=True)

    summary = benchmark.pedantic(run, rounds=1, iterations=1, warmup_rounds=0)
    bag_bytes = robot_bag.stat().st_size
    assert summary.frames == round(SECONDS * FPS)
    kept = {k["name"]: k["messages"] for k in summary.kept}
    assert kept["/camera/imu"] == round(SECONDS * 200)  # the other topics are kept, not dropped
    assert kept["/tf_static"] == 1
    assert summary.left_out == []
    assert 0 < out.stat().st_size == summary.bytes < bag_bytes
    benchmark.extra_info.update(
        kind="bag-peer",
        bag="robot-1s",
        peer=".pcdc",
        bytes_in=bag_bytes,
        bytes_out=summary.bytes,
        ratio=bag_bytes / summary.bytes,
        mb_per_s=bag_bytes / 1e6 / summary.seconds,
    )
