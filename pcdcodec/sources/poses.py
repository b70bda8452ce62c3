"""Camera poses that come with RGB-D folders: TUM ``groundtruth.txt`` and 7-Scenes pose files.

* **TUM RGB-D**: ``groundtruth.txt`` lists ``timestamp tx ty tz qx qy qz qw`` (seconds, metres,
  camera-to-world) from motion capture at a higher rate than the images. Each frame gets the
  pose at its depth image's time (the number in the TUM depth file name), interpolated between
  the two trajectory samples around it: translation linearly, rotation by slerp. A frame outside
  the trajectory, or in a gap longer than :data:`MAX_GAP_NS`, gets no pose.
* **7-Scenes**: ``pose/frame-NNNNNN.pose.txt`` holds the 4 × 4 camera-to-world matrix of frame
  ``NNNNNN`` as text; in the dataset as Microsoft ships it, the folder is flat and
  ``frame-NNNNNN.pose.txt`` lies beside the frame's ``frame-NNNNNN.depth.png``. Either way, a
  matrix of ``-inf`` marks a frame without tracking: it gets no pose.

Which of the two a folder's poses came in is kept in the source's metadata under
:data:`POSE_LAYOUT_KEY` (``"tum"`` or ``"7scenes"``), so a recording of the folder says it and
``pcdcodec decode`` writes the poses back the same way (:func:`write_tum_trajectory`,
:func:`write_pose_file`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..geometry.transform import (
    as_rigid,
    interpolate_poses,
    matrix_to_quaternion,
    rigid_from_quaternion,
)
from ._folder_layouts import NS_PER_S, seconds_to_ns

__all__ = [
    "DEFAULT_POSE_LAYOUT",
    "MAX_GAP_NS",
    "POSE_LAYOUTS",
    "POSE_LAYOUT_KEY",
    "flat_pose_files",
    "folder_poses",
    "read_tum_trajectory",
    "seconds_text",
    "write_pose_file",
    "write_tum_trajectory",
]

#: The longest gap between two trajectory samples that is interpolated across (0.1 s).
MAX_GAP_NS = 100_000_000
Pose = npt.NDArray[np.float64]

#: The metadata key (a source's, then a recording's) that names the layout a folder's poses
#: came in: one of :data:`POSE_LAYOUTS`.
POSE_LAYOUT_KEY = "pose_layout"
#: The layouts of poses, by name: TUM's trajectory file and 7-Scenes' file per frame.
POSE_LAYOUTS = {
    "tum": "groundtruth.txt (timestamp tx ty tz qx qy qz qw)",
    "7scenes": "pose/frame-NNNNNN.pose.txt (a 4 x 4 matrix per frame)",
}
#: How a 7-Scenes pose file's name ends (``frame-NNNNNN.pose.txt``).
POSE_SUFFIX = ".pose.txt"
#: The layout for poses whose recording does not name one (recordings of earlier versions,
#: poses from bags or handed to the writer).
DEFAULT_POSE_LAYOUT = "tum"


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


def seconds_text(ns: int) -> str:
    """A time in ns as TUM writes times: decimal seconds, 6 decimals when the time is whole
    microseconds (as TUM's own), else 9; :func:`seconds_to_ns` reads it back exactly."""
    t = int(ns)
    whole, frac = divmod(t, NS_PER_S)
    return f"{whole}.{frac // 1000:06d}" if frac % 1000 == 0 else f"{whole}.{frac:09d}"


def write_tum_trajectory(path: Path, times: Sequence[int], poses: Sequence[Pose]) -> None:
    """Write timed 4 × 4 camera-to-world poses as a TUM trajectory file (what
    :func:`read_tum_trajectory` reads): ``timestamp tx ty tz qx qy qz qw`` per line, the
    numbers in the shortest text that reads back as the same float64."""
    lines = ["# camera-to-world poses", "# timestamp tx ty tz qx qy qz qw"]
    for t, pose in zip(times, poses, strict=True):
        m = np.asarray(pose, dtype=np.float64)
        values = [*m[:3, 3].tolist(), *matrix_to_quaternion(m).tolist()]
        lines.append(" ".join([seconds_text(t), *(repr(float(v)) for v in values)]))
    path.write_text("\n".join(lines) + "\n")


def write_pose_file(path: Path, pose: Pose) -> None:
    """Write a 4 × 4 pose as a 7-Scenes pose file: four rows of four numbers, each in the
    shortest text that reads back as the same float64 (bit for bit)."""
    m = np.asarray(pose, dtype=np.float64)
    path.write_text("".join(" ".join(repr(float(v)) for v in row) + "\n" for row in m.tolist()))


def folder_poses(
    root: Path,
    pairs: Sequence[tuple[int, Path | None, Path]],
    *,
    depth_times: Sequence[int] | None = None,
) -> tuple[list[Pose | None] | None, str | None]:
    """The pose of each ``(timestamp, color, depth)`` pair, or ``None`` when the folder has no
    poses at all, and the layout they came in (a name of :data:`POSE_LAYOUTS`, or ``None``).
    Pairs without a pose of their own get ``None`` in the list.

    ``depth_times`` are the depth images' own times of TUM lists (``None`` for other
    layouts): the TUM trajectory is read only beside them, and each frame's pose is taken at
    its depth image's time.
    """
    trajectory = root / "groundtruth.txt"
    if depth_times is not None and trajectory.is_file():
        times, poses = read_tum_trajectory(trajectory)
        return interpolate_poses(times, poses, list(depth_times), max_gap=MAX_GAP_NS), "tum"
    pose_dir = root / "pose"
    if pose_dir.is_dir():
        files = [pose_dir / _pose_name(depth) for _, _, depth in pairs]
    else:
        # 7-Scenes as shipped: frame-NNNNNN.pose.txt beside frame-NNNNNN.depth.png.
        files = [depth.parent / _pose_name(depth) for _, _, depth in pairs]
        if not any(f.is_file() for f in files):
            return None, None
    return [_read_pose_file(f) if f.is_file() else None for f in files], "7scenes"


def _pose_name(depth: Path) -> str:
    """The name of the 7-Scenes pose file of a depth image (``frame-000012.depth.png`` ->
    ``frame-000012.pose.txt``)."""
    return depth.name.split(".")[0] + POSE_SUFFIX


def flat_pose_files(root: Path) -> list[str]:
    """The names of the pose files lying in ``root`` itself (7-Scenes' flat layout), sorted."""
    try:
        return sorted(
            p.name for p in root.iterdir() if p.name.endswith(POSE_SUFFIX) and p.is_file()
        )
    except OSError:
        return []


def _read_pose_file(file: Path) -> Pose | None:
    """The 4 × 4 matrix of a 7-Scenes pose file, or ``None`` for a frame without tracking."""
    try:
        matrix = np.loadtxt(file, dtype=np.float64)
    except ValueError as exc:
        raise InputError(f"{str(file)!r} is not a 4x4 matrix of numbers: {exc}") from None
    if not np.isfinite(matrix).all():
        # 7-Scenes marks frames without tracking with -inf: no pose.
        return None
    return as_rigid(matrix, f"pose {str(file)!r}")
