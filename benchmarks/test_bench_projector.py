"""Depth to point cloud on real 640×480 frames: pcdcodec's Projector against Open3D.

Each path runs on the first frame of every sequence present (the bundled sample always).

Run with ``pytest benchmarks/test_bench_projector.py --benchmark-only``; with
``--benchmark-disable`` each path runs once and is still checked.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
import open3d as o3d
import pytest

from pcdcodec.bench.sequences import SEQUENCES, load_colors, load_depths
from pcdcodec.geometry.camera import CameraIntrinsics
from pcdcodec.geometry.projector import Projector

#: Intrinsics per sequence (TUM's recommended values; typical D435 and 7-Scenes values).
CAMERAS = {
    "sample": CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "tum_fr1_rpy": CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "realsense_d435": CameraIntrinsics(640, 480, 615.0, 615.0, 320.0, 240.0),
    "7scenes_redkitchen": CameraIntrinsics(640, 480, 585.0, 585.0, 320.0, 240.0),
}
PRESENT = [name for name in CAMERAS if SEQUENCES[name].present]


class Frame:
    """A sequence's first frame and every input the benchmarked paths need, made untimed."""

    def __init__(self, name: str) -> None:
        cam = CAMERAS[name]
        self.name = name
        self.scale = SEQUENCES[name].depth_scale
        self.color: npt.NDArray[np.uint8] = load_colors(name, 1)[0]
        self.depth: npt.NDArray[np.uint16] = load_depths(name, 1)[0]
        self.valid = int(np.count_nonzero(self.depth))
        self.projector = Projector(cam, depth_scale=self.scale)
        self.pinhole = cam.to_open3d()
        self.rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(self.color),
            o3d.geometry.Image(self.depth),
            depth_scale=self.scale,
            depth_trunc=1000.0,  # keep everything, as the Projector does
            convert_rgb_to_intensity=False,
        )
        self.t_rgbd = o3d.t.geometry.RGBDImage(
            o3d.t.geometry.Image(self.color), o3d.t.geometry.Image(self.depth)
        )
        self.t_K = o3d.core.Tensor(cam.K)


@pytest.fixture(scope="module", params=PRESENT)
def frame(request: pytest.FixtureRequest) -> Frame:
    return Frame(request.param)


def _ours_to_points(f: Frame) -> tuple[Callable[[], Any], Callable[[Any], tuple[int, bool]]]:
    def count(result: Any) -> tuple[int, bool]:
        points, colors = result
        return len(points), colors is not None and len(colors) == len(points)

    return (lambda: f.projector.to_points(f.depth, f.color)), count


def _ours_legacy(f: Frame) -> tuple[Callable[[], Any], Callable[[Any], tuple[int, bool]]]:
    return (lambda: f.projector.to_point_cloud(f.depth, f.color)), _legacy_count


def _ours_tensor(f: Frame) -> tuple[Callable[[], Any], Callable[[Any], tuple[int, bool]]]:
    return (lambda: f.projector.to_point_cloud(f.depth, f.color, tensor=True)), _tensor_count


def _open3d_legacy(f: Frame) -> tuple[Callable[[], Any], Callable[[Any], tuple[int, bool]]]:
    return (
        lambda: o3d.geometry.PointCloud.create_from_rgbd_image(f.rgbd, f.pinhole)
    ), _legacy_count


def _open3d_tensor(f: Frame) -> tuple[Callable[[], Any], Callable[[Any], tuple[int, bool]]]:
    def run() -> Any:
        return o3d.t.geometry.PointCloud.create_from_rgbd_image(
            f.t_rgbd, f.t_K, depth_scale=f.scale, depth_max=1000.0
        )

    return run, _tensor_count


def _legacy_count(pcd: Any) -> tuple[int, bool]:
    return len(pcd.points), len(pcd.colors) == len(pcd.points)


def _tensor_count(pcd: Any) -> tuple[int, bool]:
    n = pcd.point.positions.shape[0]
    return n, "colors" in pcd.point and pcd.point.colors.shape[0] == n


PATHS = {
    "pcdcodec-to_points": _ours_to_points,
    "pcdcodec-to_point_cloud-legacy": _ours_legacy,
    "pcdcodec-to_point_cloud-tensor": _ours_tensor,
    "open3d-legacy-create_from_rgbd_image": _open3d_legacy,
    "open3d-tensor-create_from_rgbd_image": _open3d_tensor,
}


# Warm-up matters: the first calls of a path in a process page-fault fresh memory until the
# allocator settles, which would penalise whichever path runs first.
@pytest.mark.benchmark(warmup=True)
@pytest.mark.parametrize("path", list(PATHS), ids=list(PATHS))
def test_depth_to_points_640x480(benchmark: Any, frame: Frame, path: str) -> None:
    run, count = PATHS[path](frame)
    assert count(run()) == (frame.valid, True)
    benchmark.group = f"depth to colored points, {frame.name} 640x480"
    benchmark.extra_info.update(
        points=frame.valid, kind="projector", path=path, sequence=frame.name
    )
    result = benchmark(run)
    assert count(result) == (frame.valid, True)
