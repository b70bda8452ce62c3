"""Ingest from a PointCloud2 bag: frames per second from bag to ``.pcdc`` with the defaults.

Target: a 640×480 organized XYZRGB cloud stream (32 bytes per point, as ROS drivers publish it)
records at ≥ 30 fps on two cores, reading and decoding the clouds included. The bag is written
once per sequence from the real frames (ROS 1, uncompressed, with CameraInfo), then timed.
``benchmarks/bag_tables.py`` prints the full table (sizes, ratios, rebuild errors) of
``docs/ingest.md``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.datasets import open_folder

FRAMES = 10
CAMERAS = {
    "tum_fr1_rpy": pcdcodec.CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "realsense_d435": pcdcodec.CameraIntrinsics(640, 480, 615.0, 615.0, 320.0, 240.0),
}
PRESENT = [name for name in ("sample", "realsense_d435") if SEQUENCES[name].present]


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bags")
    out = {}
    for name in PRESENT:
        info = SEQUENCES[name]
        source = open_folder(
            info.root,
            max_frames=FRAMES,
            depth_scale=info.depth_scale,
            intrinsics=CAMERAS.get(name),
            layout="folders" if name == "realsense_d435" else "auto",
        )
        out[name] = root / f"{name}.bag"
        pcdcodec.export_bag(source, out[name], images=False, cloud=True)
    return out


@pytest.mark.parametrize("name", PRESENT)
def test_ingest_pointcloud2_bag(
    benchmark: Any, bags: dict[str, Path], tmp_path: Path, name: str
) -> None:
    bag = bags[name]
    out = tmp_path / "ingest.pcdc"
    with pcdcodec.open_source(bag) as src:
        frames = sum(1 for _ in src)
    benchmark.group = "ingest: PointCloud2 bag -> .pcdc, defaults (h264 + depthac)"
    benchmark.extra_info.update(kind="ingest", sequence=name, frames=frames)

    def run() -> Any:
        return pcdcodec.encode(bag, out, overwrite=True)

    summary = benchmark.pedantic(run, rounds=2, iterations=1, warmup_rounds=0)
    assert summary.frames == frames  # correct, not just fast
    if benchmark.stats is not None:
        benchmark.extra_info["fps"] = frames / benchmark.stats.stats.median
