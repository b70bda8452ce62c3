"""Record a sequence, read it back, and measure it: what ``pcdcodec demo`` prints."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..color import DEFAULT_COLOR_CODEC
from ..depth import DEFAULT_DEPTH_CODEC
from ..recording import open as open_recording

__all__ = ["RoundTrip", "measure_roundtrip"]


@dataclass(frozen=True)
class RoundTrip:
    """Sizes (bytes), speeds (frames per second) and exactness of one recording round trip."""

    frames: int
    width: int
    height: int
    color_codec: str
    depth_codec: str
    bytes_color: int
    bytes_depth: int
    bytes_file: int
    encode_fps: float
    decode_fps: float
    decode_cloud_fps: float
    points_per_frame: float
    depth_exact: bool

    @property
    def bytes_raw(self) -> int:
        """Raw RGB-D: RGB24 plus uint16 depth per pixel."""
        return self.frames * self.width * self.height * (3 + 2)

    @property
    def bytes_pointcloud2(self) -> int:
        """An organized PointCloud2 XYZRGB (32 bytes per point), as ROS publishes it."""
        return self.frames * self.width * self.height * 32

    @property
    def bytes_pointcloud2_points(self) -> int:
        """A PointCloud2 XYZRGB (32 bytes per point) of the pixels with depth only."""
        return round(self.frames * self.points_per_frame * 32)

    @property
    def ratio_raw(self) -> float:
        return self.bytes_raw / self.bytes_file

    @property
    def ratio_pointcloud2(self) -> float:
        return self.bytes_pointcloud2 / self.bytes_file

    @property
    def ratio_pointcloud2_points(self) -> float:
        return self.bytes_pointcloud2_points / self.bytes_file


def measure_roundtrip(
    sequence: Any,
    path: str | os.PathLike[str],
    *,
    color: Any = None,
    depth: Any = None,
    warmup: bool = True,
) -> RoundTrip:
    """Write ``sequence`` (an :class:`~pcdcodec.RGBDSequence` with intrinsics) to ``path`` with
    the given codecs (the defaults when ``None``), read it back and measure it.

    Rates are steady-state: a short warm-up recording loads the codec libraries first, and the
    decode rates count from the second frame on (the first pays the decoders' start-up).
    ``depth_exact`` says whether every depth frame came back bit-exact.
    """
    color = DEFAULT_COLOR_CODEC if color is None else color
    depth = DEFAULT_DEPTH_CODEC if depth is None else depth
    target = Path(path)
    options = {
        "intrinsics": sequence.intrinsics,
        "depth_scale": sequence.depth_scale,
        "color": color,
        "depth": depth,
        "overwrite": True,
    }
    if warmup:
        warm = target.with_name(f".{target.name}.warmup")
        try:
            with open_recording(warm, "w", **options) as w:
                w.write_frames(sequence.frames[:2])
        finally:
            warm.unlink(missing_ok=True)
    start = time.perf_counter()
    with open_recording(target, "w", **options) as writer:
        writer.write_frames(sequence)
    t_encode = time.perf_counter() - start
    n = len(sequence)
    exact = True
    with open_recording(target) as rec:
        codecs = rec.codecs
        for frame, original in zip(rec, sequence, strict=True):
            exact &= bool(np.array_equal(frame.depth, original.depth))
    with open_recording(target) as rec:
        rec[0]
        start = time.perf_counter()
        for i in range(1, n):
            rec[i]
        t_decode = time.perf_counter() - start
    with open_recording(target) as rec:
        # Decoding and the tensor point cloud, as a training loop or a viewer reads frames.
        points = rec[0].to_point_cloud(tensor=True).point.positions.shape[0]
        start = time.perf_counter()
        for i in range(1, n):
            points += rec[i].to_point_cloud(tensor=True).point.positions.shape[0]
        t_cloud = time.perf_counter() - start
    h, w = sequence[0].depth.shape
    steady = max(n - 1, 1)
    return RoundTrip(
        frames=n,
        width=w,
        height=h,
        color_codec=str((codecs["color"] or {}).get("id", "none")),
        depth_codec=str((codecs["depth"] or {}).get("id")),
        bytes_color=writer.bytes_color,
        bytes_depth=writer.bytes_depth,
        bytes_file=target.stat().st_size,
        encode_fps=n / t_encode,
        decode_fps=steady / t_decode if t_decode > 0 else float("inf"),
        decode_cloud_fps=steady / t_cloud if t_cloud > 0 else float("inf"),
        points_per_frame=points / n,
        depth_exact=exact,
    )
