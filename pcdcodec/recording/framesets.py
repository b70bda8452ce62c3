"""Frames of several cameras matched by time, and their clouds fused in the rig frame.

What every recording offers about its cameras: a rig's file (format version 3) has several,
a one-camera file one, whose rig frame is its camera frame. :class:`FrameSets` matches each
camera's frames to a reference camera's by timestamp; each :class:`FrameSet` fuses its
cameras' clouds (numpy, legacy and tensor Open3D) in the rig frame.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from itertools import accumulate
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..frame import Frame
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import Projector

__all__ = ["FrameSet", "FrameSets", "OneCamera", "RigCamera", "match_times"]

_NS = 1_000_000_000


class _Frames(Protocol):
    """What matching needs of one camera's frames (a :class:`~pcdcodec.Recording`)."""

    fps: float

    @property
    def timestamps(self) -> npt.NDArray[np.int64]: ...

    def __getitem__(self, i: Any) -> Any: ...


class _Rig(Protocol):
    """What matching needs of a recording: its cameras' names, frames and rig poses."""

    @property
    def rig_poses(self) -> dict[str, npt.NDArray[np.float64]]: ...

    @property
    def camera_names(self) -> list[str]: ...

    def frames(self, camera: str | None = None) -> Any: ...


@dataclass(frozen=True)
class RigCamera:
    """A camera of a rig as its recording describes it."""

    name: str
    intrinsics: CameraIntrinsics
    depth_scale: float
    fps: float
    #: rigid 4 × 4 transform from the camera's depth frame to the rig frame (metres)
    rig_pose: npt.NDArray[np.float64] = field(repr=False)
    frame_id: str
    color_intrinsics: CameraIntrinsics | None = None
    depth_to_color: npt.NDArray[np.float64] | None = field(default=None, repr=False)
    depth_codec: dict[str, Any] | None = None
    color_codec: dict[str, Any] | None = None

    @property
    def projector(self) -> Projector:
        """The camera's projector (depth pixels to points in its own frame)."""
        return Projector(
            self.intrinsics,
            self.depth_scale,
            color_intrinsics=self.color_intrinsics,
            depth_to_color=self.depth_to_color,
        )


def _rig_points(
    frames: dict[str, Frame | None], poses: dict[str, npt.NDArray[np.float64]]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8] | None, dict[str, slice]]:
    parts: list[tuple[str, npt.NDArray[np.float64], npt.NDArray[np.uint8] | None]] = []
    for name, frame in frames.items():
        if frame is None:
            continue
        points, colors = frame.to_points()
        pose = poses[name]
        # float64: a rig frame far from the cameras keeps its points within 1e-6 m.
        rig = points.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
        parts.append((name, rig, colors))
    slices: dict[str, slice] = {}
    start = 0
    for name, part, _ in parts:
        slices[name] = slice(start, start + len(part))
        start += len(part)
    xyz = np.concatenate([p for _, p, _ in parts]) if parts else np.zeros((0, 3), np.float64)
    if not any(c is not None for _, _, c in parts):
        return xyz, None, slices
    rgb = np.concatenate(
        [c if c is not None else np.zeros((len(p), 3), np.uint8) for _, p, c in parts]
    )
    return xyz, rgb, slices


@dataclass(eq=False)
class FrameSet:
    """One frame per camera, matched by time (``None`` for a camera without a frame near
    enough: listed in :attr:`missing`)."""

    index: int
    #: the reference camera's frame time (ns)
    timestamp_ns: int
    frames: dict[str, Frame | None]
    rig_poses: dict[str, npt.NDArray[np.float64]] = field(repr=False)

    @property
    def missing(self) -> list[str]:
        """The cameras without a frame in this set."""
        return [name for name, frame in self.frames.items() if frame is None]

    @property
    def complete(self) -> bool:
        """Whether every camera has a frame in this set."""
        return not self.missing

    def to_points(
        self,
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8] | None, dict[str, slice]]:
        """The fused cloud in the rig frame: N × 3 float64 points (metres), N × 3 uint8 colors
        (``None`` when no camera has color; black for a camera without), and where each
        camera's points are in them (camera name → slice), cameras in the rig's order."""
        return _rig_points(self.frames, self.rig_poses)

    def to_point_cloud(self, tensor: bool = False) -> Any:
        """The fused cloud in the rig frame as an Open3D point cloud (legacy
        ``open3d.geometry.PointCloud``, or ``open3d.t.geometry.PointCloud`` if ``tensor``)."""
        from ..geometry.open3d import tensor_point_cloud

        points, colors, _ = self.to_points()
        if tensor:  # Float64 positions, as the numpy points; Float32 colors in 0..1
            scaled = None if colors is None else colors.astype(np.float32) / np.float32(255.0)
            return tensor_point_cloud(points, scaled)  # type: ignore[arg-type]
        import open3d as o3d

        cloud = o3d.geometry.PointCloud()
        cloud.points = o3d.utility.Vector3dVector(points)
        if colors is not None:
            cloud.colors = o3d.utility.Vector3dVector(colors.astype(np.float64) / 255.0)
        return cloud


class FrameSets(Sequence[FrameSet]):
    """The frame sets of a rig recording: ``len()``, indexing and iteration decode the frames
    of a set; :attr:`matches` and :attr:`timestamps` say which frames were matched without
    decoding any."""

    def __init__(
        self,
        rig: _Rig,
        reference: str,
        tolerance_ns: int,
        matches: npt.NDArray[np.int64],
    ) -> None:
        self._rig = rig
        #: the camera whose frames the sets are built around
        self.reference = reference
        #: how far (ns) a frame may be from the reference frame's time to join its set
        self.tolerance_ns = tolerance_ns
        #: sets × cameras: the frame index of each camera in each set, -1 where missing
        self.matches = matches

    @property
    def timestamps(self) -> npt.NDArray[np.int64]:
        """The reference camera's frame time of each set (ns)."""
        times: npt.NDArray[np.int64] = self._rig.frames(self.reference).timestamps
        col = self._rig.camera_names.index(self.reference)
        return times[self.matches[:, col]]

    @property
    def incomplete(self) -> int:
        """How many sets lack a camera."""
        return int(np.count_nonzero((self.matches < 0).any(axis=1)))

    def __len__(self) -> int:
        return len(self.matches)

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        n = len(self)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not -n <= i < n:
            raise IndexError(f"frame set {i!r} is out of range (there are {n})")
        k = int(i) % n
        row = self.matches[k]
        frames = {
            name: (self._rig.frames(name)[int(j)] if j >= 0 else None)
            for name, j in zip(self._rig.camera_names, row, strict=True)
        }
        ts = int(self.timestamps[k])
        return FrameSet(k, ts, frames, self._rig.rig_poses)

    def __iter__(self) -> Iterator[FrameSet]:
        for k in range(len(self)):
            yield self[k]


def match_times(
    reference: npt.NDArray[np.int64], other: npt.NDArray[np.int64], tolerance_ns: int
) -> npt.NDArray[np.int64]:
    """For each reference time, the index of the ``other`` frame matched to it (-1 where
    none is): each frame joins at most one set, only within ``tolerance_ns`` of the set's
    time, and of all such matchings the one that fills the most sets, then the one nearest in
    time (summed distance), ties broken the same way every time.

    Both lists are sorted, so some best matching never crosses (a later set never takes an
    earlier frame than an earlier set). It is found in one pass over the frames of both lists
    in time order, in time linear in their number (:func:`_match_in_order`).
    """
    n, m = len(reference), len(other)
    out = np.full(n, -1, np.int64)
    if not n or not m:
        return out
    for k, j in _match_in_order(reference.tolist(), other.tolist(), int(tolerance_ns)):
        out[k] = j
    return out


# A state of the pass: frames of one list taken but not yet matched (a frame of the other list
# closes the oldest); [oldest frame's index - the list's closes so far, sets filled, summed
# distance (negated), each less the list's offsets; the pass's best before, first own index,
# first index of the other list].
_State = list[Any]


def _match_in_order(ref: list[int], oth: list[int], tol: int) -> Iterator[tuple[int, int]]:
    """The pairs (reference index, other index) of a best non-crossing matching.

    The frames are walked in time order. In a best matching, the frames taken and not yet
    matched are all of one list (else two pairs would cross), are that list's newest frames
    (a skipped newer frame could take the place of an older one, nearer to every later frame),
    and a frame of the other list that arrives while some wait is matched to the oldest of them
    (shifting each waiting frame one frame earlier only brings it nearer). So a state is one
    list's frames from an index on, and one arrival moves every state of a list alike: the
    states of a list are kept in a deque with offsets added to all of them at once, each
    state's value counted as if its waiting frames cost nothing yet. A waiting frame may be
    dropped at no cost, so along a deque the values grow towards its newest state, and the
    state with nothing waiting is the best of all: states whose oldest frame is out of
    tolerance fall off the front, and only the newest state can become the best."""
    times = (ref, oth)
    sums = (list(accumulate(ref, initial=0)), list(accumulate(oth, initial=0)))
    chains: tuple[deque[_State], deque[_State]] = (deque(), deque())
    closes = [0, 0]
    off_filled = [0, 0]
    off_dist = [0, 0]
    arrived = [0, 0]
    best: tuple[int, int] = (0, 0)
    # The best matching as a linked list of runs: (rest, side, first own, first other, count).
    best_runs: Any = None
    n = len(ref)
    i = j = 0
    while i < n or j < len(oth):
        side = 0 if j == len(oth) or (i < n and ref[i] <= oth[j]) else 1
        t = ref[i] if side == 0 else oth[j]
        opp = 1 - side
        chain, own = chains[opp], times[opp]
        # States of the other list whose oldest waiting frame is too far back to be matched.
        while chain and t - own[chain[0][0] + closes[opp]] > tol:
            chain.popleft()
        before, before_runs = best, best_runs
        if chain:  # every state of the other list matches its oldest waiting frame to t
            closes[opp] += 1
            off_filled[opp] += 1
            off_dist[opp] -= t
            top = chain[-1]
            start = top[0] + closes[opp]
            value = (top[1] + off_filled[opp], top[2] + sums[opp][start] + off_dist[opp])
            if value > best:
                best = value
                best_runs = (top[3], opp, top[4], top[5], start - top[4])
            if start == arrived[opp]:
                chain.pop()
        # The state that takes this frame to wait, from the best before it.
        k = arrived[side]
        chains[side].append(
            [
                k - closes[side],
                before[0] - off_filled[side],
                before[1] - sums[side][k] - off_dist[side],
                before_runs,
                k,
                arrived[opp],
            ]
        )
        arrived[side] += 1
        if side == 0:
            i += 1
        else:
            j += 1
    runs = best_runs
    while runs is not None:
        runs, side, first, first_other, count = runs
        for c in range(count):
            yield (first + c, first_other + c) if side == 0 else (first_other + c, first + c)


#: The widest tolerance framesets() takes, in seconds (about 11.6 days).
_MAX_TOLERANCE_S = 1e6


def framesets(rig: _Rig, tolerance: float | None, reference: str | None) -> FrameSets:
    """:meth:`RigRecording.framesets <pcdcodec.recording.rig_reader.RigRecording.framesets>`
    of ``rig``."""
    ref = rig.camera_names[0] if reference is None else reference
    ref_rec = rig.frames(ref)
    if tolerance is None:
        tolerance = 0.5 / ref_rec.fps
        if not tolerance < _MAX_TOLERANCE_S:
            raise InputError(
                f"the default tolerance, half a frame of camera {ref!r} at its fps "
                f"{ref_rec.fps:g}, is {tolerance:g} s, more than framesets() takes (under "
                f"{_MAX_TOLERANCE_S:g} s); pass tolerance= in seconds"
            )
    if (
        isinstance(tolerance, bool)
        or not isinstance(tolerance, (int, float))
        or not (0 <= tolerance < _MAX_TOLERANCE_S)
    ):
        raise InputError(
            f"tolerance must be a number of seconds from 0 to under {_MAX_TOLERANCE_S:g}, "
            f"got {tolerance!r}"
        )
    tol = round(tolerance * _NS)
    ref_times = ref_rec.timestamps
    columns = [
        np.arange(len(ref_times), dtype=np.int64)
        if cam == ref
        else match_times(ref_times, rig.frames(cam).timestamps, tol)
        for cam in rig.camera_names
    ]
    return FrameSets(rig, ref, tol, np.stack(columns, axis=1))


class OneCamera:
    """The camera API of a one-camera recording, as a rig's: one camera, named by its
    ``frame_id``, whose frame is the rig frame. Code written for rigs reads these as well."""

    intrinsics: CameraIntrinsics
    depth_scale: float
    fps: float
    frame_id: str
    color_intrinsics: CameraIntrinsics | None
    depth_to_color: npt.NDArray[np.float64] | None

    @property
    def codecs(self) -> dict[str, dict[str, Any] | None]:
        raise NotImplementedError

    @property
    def camera_names(self) -> list[str]:
        """The one camera's name (its ``frame_id``)."""
        return [self.frame_id]

    @property
    def rig_poses(self) -> dict[str, npt.NDArray[np.float64]]:
        """Where the camera sits in the rig frame: the identity."""
        return {self.frame_id: np.eye(4)}

    @property
    def cameras(self) -> dict[str, RigCamera]:
        """The one camera, described as a rig's cameras are."""
        return {
            self.frame_id: RigCamera(
                self.frame_id,
                self.intrinsics,
                self.depth_scale,
                self.fps,
                np.eye(4),
                self.frame_id,
                self.color_intrinsics,
                self.depth_to_color,
                self.codecs.get("depth"),
                self.codecs.get("color"),
            )
        }

    def frames(self, camera: str | None = None) -> Any:
        """This recording (its one camera's frames); ``camera``, if given, must name it."""
        if camera is not None and camera != self.frame_id:
            raise InputError(f"no camera {camera!r} here; the one camera is {self.frame_id!r}")
        return self

    def framesets(
        self, tolerance: float | None = None, *, reference: str | None = None
    ) -> FrameSets:
        """Each frame as a set of one (see ``RigRecording.framesets``)."""
        return framesets(self, tolerance, reference)
