"""Camera poses that come with RGB-D folders: TUM ``groundtruth.txt`` and 7-Scenes pose files.

* **TUM RGB-D**: ``groundtruth.txt`` lists ``timestamp tx ty tz qx qy qz qw`` (seconds, metres,
  camera-to-world) from motion capture at a higher rate than the images. Each frame gets the
  pose at its depth image's time (the number in the TUM depth file name), interpolated between
  the two trajectory samples around it: translation linearly, rotation by slerp. A frame outside
  the trajectory, or in a gap longer than :data:`MAX_GAP_NS`, gets no pose.
* **7-Scenes**: ``pose/frame-NNNNNN.pose.txt`` holds the 4 × 4 camera-to-world matrix of frame
  ``NNNNNN`` as text.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..geometry.transform import as_rigid, interpolate_poses, rigid_from_quaternion
from ._folder_layouts import seconds_to_ns

__all__ = ["MAX_GAP_NS", "folder_poses", "read_tum_trajectory"]

#: The longest gap between two trajectory samples that is interpolated across (0.1 s).
MAX_GAP_NS = 100_000_000
Pose = npt.NDArray[np.float64]


def read_tum_trajectory(path: Path) -> tuple[list[int], list[Pose]]:
    """Times (ns) and 4 × 4 camera-to-world poses of a TUM trajectory file, sorted by time.

    Raises :class:`~pcdcodec.InputError` naming the line for a malformed one.
    """
    times: list[int] = []
    poses: list[Pose] = []
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        if len(parts) != 8:
            raise InputError(
                f"{path}:{lineno}: expected 'timestamp tx ty tz qx qy qz qw', got {line!r}"
            )
        try:
            t = seconds_to_ns(parts[0])
            values = [float(v) for v in parts[1:]]
            poses.append(rigid_from_quaternion(values[:3], values[3:]))
        except (ValueError, InputError) as exc:
            raise InputError(f"{path}:{lineno}: {exc} in {line!r}") from None
        times.append(t)
    order = np.argsort(times, kind="stable")
    sorted_times = [times[i] for i in order]
    keep = [k for k in range(len(order)) if k == 0 or sorted_times[k] != sorted_times[k - 1]]
    return [sorted_times[k] for k in keep], [poses[order[k]] for k in keep]


def _depth_time(path: Path, fallback: int) -> int:
    try:
        return seconds_to_ns(path.name.rsplit(".", 1)[0])
    except ValueError:
        return fallback


def folder_poses(
    root: Path, pairs: Sequence[tuple[int, Path | None, Path]], *, tum: bool
) -> list[Pose | None] | None:
    """The pose of each ``(timestamp, color, depth)`` pair, or ``None`` when the folder has no
    poses at all. Pairs without a pose of their own get ``None`` in the list."""
    trajectory = root / "groundtruth.txt"
    if tum and trajectory.is_file():
        times, poses = read_tum_trajectory(trajectory)
        query = [_depth_time(d, t) for t, _, d in pairs]
        return interpolate_poses(times, poses, query, max_gap=MAX_GAP_NS)
    pose_dir = root / "pose"
    if pose_dir.is_dir():
        out: list[Pose | None] = []
        for _, _, depth in pairs:
            file = pose_dir / f"{depth.name.split('.')[0]}.pose.txt"
            if not file.is_file():
                out.append(None)
                continue
            try:
                matrix = np.loadtxt(file, dtype=np.float64)
            except ValueError as exc:
                raise InputError(f"{str(file)!r} is not a 4x4 matrix of numbers: {exc}") from None
            if not np.isfinite(matrix).all():
                # 7-Scenes marks frames without tracking with -inf: no pose.
                out.append(None)
                continue
            out.append(as_rigid(matrix, f"pose {str(file)!r}"))
        return out
    return None
