"""The whole-bag table's measures (pcdcodec/bench/bag_table.py) on the real Spot bag: what each
cell counts, and that nothing written is left behind."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from pcdcodec.bench import bag_peers, bag_table
from pcdcodec.bench.sequences import SHARED_DATA
from pcdcodec.errors import InputError

SPOT_RAW = SHARED_DATA / "bags" / "spot" / "raw.bag"
SPOT_MCAP = SHARED_DATA / "bags" / "ros2-converted" / "spot_ros2_mcap"
SPOT_CAMERA = {"width": 424, "height": 240, "fx": 200.0, "fy": 200.0, "cx": 212.0, "cy": 120.0}


def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} is not present")
    return path


def test_bag_kind() -> None:
    assert bag_table.bag_kind(_need(SPOT_RAW)) == "ros1"
    assert bag_table.bag_kind(_need(SPOT_MCAP)) == "ros2-mcap"


def test_mcap_zstd_topics_writes_those_topics_alone(tmp_path: Path) -> None:
    bag = _need(SPOT_RAW)
    out = tmp_path / "two.mcap"
    topics = {"/spot/camera/hand_color/image", "/spot/depth/frontleft/image"}
    result = bag_peers.mcap_zstd(bag, out, topics=topics)
    with out.open("rb") as f:
        got = [ch.topic for _, ch, _ in make_reader(f).iter_messages()]
    assert sorted(got) == sorted(topics)
    assert result.messages == 2
    whole = bag_peers.mcap_zstd(bag, tmp_path / "all.mcap")
    assert whole.messages == 4
    assert whole.bytes_out > result.bytes_out
    # Every chunk of the file, counted once; none of a topic that is not there.
    assert 0 < bag_table.chunk_bytes(out, lambda ch: True) < result.bytes_out
    assert bag_table.chunk_bytes(out, lambda ch: ch.topic == "/nothing") == 0


def test_chunk_bytes_refuses_a_chunk_it_cannot_share_out(tmp_path: Path) -> None:
    out = tmp_path / "all.mcap"
    bag_peers.mcap_zstd(_need(SPOT_RAW), out)  # the four images in one chunk
    with pytest.raises(InputError, match="mixes"):
        bag_table.chunk_bytes(out, lambda ch: ch.topic.endswith("/hand_color/image"))


def test_measure_bag_row(tmp_path: Path) -> None:
    bag = _need(SPOT_RAW)
    row = bag_table.measure_bag(
        bag, tmp_path, options={"intrinsics": SPOT_CAMERA}, peers=("zstd1", "lz4", "cloudini")
    )
    assert row.notes == []
    assert row.kind == "ros1"
    assert row.bytes == bag.stat().st_size
    assert row.frames == 1
    assert row.pcdc is not None
    assert row.pcdc > 0
    # The depth is the recording's camera; the bag's three other images are kept.
    assert sorted(row.kept_topics) == [
        "/spot/camera/frontleft/image",
        "/spot/camera/hand_color/image",
        "/spot/camera/hand_mono/image",
    ]
    assert row.kept_pcdc is not None
    assert 0 < row.kept_pcdc < row.pcdc
    assert row.kept_zstd1 is not None
    assert row.kept_zstd1 > 0
    assert row.peers["zstd1"]
    assert row.peers["lz4"]
    assert row.peers["cloudini"] is None  # no PointCloud2 topic: not applicable
    assert "zstd19" not in row.peers  # not asked for
    assert row.encode is not None
    assert row.encode.peak_rss_bytes > 10**7
    assert row.export is not None
    assert row.export.info["bytes"] > 0
    assert list(tmp_path.iterdir()) == []  # every file written was removed
    lines = bag_table.table([row])
    assert lines[2].startswith("| raw.bag | ros1 |")
    assert "| - |" in lines[2]


def test_measure_bag_refuses_an_unknown_peer(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="zstd3"):
        bag_table.measure_bag(_need(SPOT_RAW), tmp_path, peers=("zstd3",))


def test_a_child_peak_memory_is_its_own() -> None:
    """A process started while this one holds 400 MB reports its own peak, not this one's
    (``ru_maxrss`` of a child counts its parent's memory at the start)."""
    if not Path("/proc/self/status").exists():
        pytest.skip("the high-water mark of a process's own memory is read from /proc")
    held = np.ones(400_000_000 // 8)
    code = "from pcdcodec.bench.bag_table import peak_rss_bytes; print(peak_rss_bytes())"
    env = {**os.environ, "PYTHONPATH": str(Path(bag_table.__file__).parents[2])}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert held.sum() == held.size  # held (and touched) while the child ran
    assert 0 < int(out.stdout) < 200_000_000
