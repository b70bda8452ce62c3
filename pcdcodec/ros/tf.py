"""Camera poses from a bag's ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``).

The camera frame is the ``frame_id`` of the depth (or cloud) messages. Its chain of parents in
the transform tree is followed up to the root, which is taken as the world: a frame's pose is
the product of the transforms along that chain (each ``TransformStamped`` is the child frame's
pose in its parent frame), at the frame's stamp.

* Dynamic transforms (``/tf``) are looked up at the frame's stamp: the sample at that stamp, or
  the two samples around it blended (translation linearly, rotation by slerp) when they are at
  most :data:`MAX_GAP_NS` apart. A stamp outside an edge's samples, or in a longer gap, gives
  the frame no pose: nothing is extrapolated.
* Static transforms (``/tf_static``) hold at every time; the last one of each edge counts.
* A chain made only of static transforms is the sensor's mounting, not a trajectory: no poses.
* A frame with two parents, or a loop, is ambiguous: no poses, and a note says why.

Only the chain's samples are kept (the transforms are read twice: once for the tree, once for
the chain's samples), so memory grows with the chain's messages, not with the whole tree.

A rig's mountings are read apart (:func:`static_placements`): each camera frame's chain of
``/tf_static`` transforms up to the root of its tree, as one fixed transform into that root.
The extrinsics of a color camera apart from the depth camera are read apart too
(:func:`frame_to_frame`): the fixed transform between two frames of one tree.
"""

from __future__ import annotations

import itertools
from array import array
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import DecodeError
from ..geometry.transform import quaternion_to_matrix, slerp
from . import messages as rm

__all__ = [
    "MAX_GAP_NS",
    "TF_TOPICS",
    "TF_TYPES",
    "StaticPlacement",
    "TfPoses",
    "frame_to_frame",
    "is_tf",
    "read_tf_poses",
    "static_placements",
]

#: The longest gap between two samples of a transform that is interpolated across (0.5 s).
MAX_GAP_NS = 500_000_000
#: Topics read for transforms, and the message types they must have.
TF_TOPICS = ("/tf", "/tf_static")
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")

Messages = Callable[[list[Any]], Iterator[tuple[Any, int, Any]]]


def is_tf(conn: Any) -> bool:
    """Whether a bag connection is ``/tf`` or ``/tf_static`` holding transform messages."""
    return "/" + str(conn.topic).lstrip("/") in TF_TOPICS and conn.msgtype in TF_TYPES


def _name(frame_id: Any) -> str:
    # ROS 1 frame ids may start with "/" (tf's old convention); tf2 drops it.
    return str(frame_id).strip().lstrip("/")


def _static(conn: Any) -> bool:
    return str(conn.topic).rstrip("/").endswith("tf_static")


def _ros1(conn: Any) -> bool:
    return type(getattr(conn, "ext", None)).__name__.endswith("Rosbag1")


def _transforms(messages: Messages, conns: list[Any]) -> Iterator[tuple[bool, bool, Any]]:
    """(static, ROS 1, transform) for every transform in ``conns``."""
    for conn, _, msg in messages(conns):
        static, ros1 = _static(conn), _ros1(conn)
        for tf in msg.transforms:
            yield static, ros1, tf


@dataclass
class _Edge:
    """The samples of one parent-to-child transform: stamps (ns) and x y z qx qy qz qw."""

    static: npt.NDArray[np.float64] | None = None
    stamps: array[int] = field(default_factory=lambda: array("q"))
    values: array[float] = field(default_factory=lambda: array("d"))
    bad: int = 0

    def add(self, static: bool, ros1: bool, tf: Any) -> None:
        t, q = tf.transform.translation, tf.transform.rotation
        row = [float(t.x), float(t.y), float(t.z), float(q.x), float(q.y), float(q.z), float(q.w)]
        if not (np.isfinite(row).all() and sum(v * v for v in row[3:]) > 1e-12):
            self.bad += 1  # not a transform: counted in a note, never used
            return
        if static:
            self.static = np.asarray(row)
            return
        try:  # the same reading of stamps as the images' (ROS 1 seconds unsigned)
            stamp = rm.stamp_ns(tf, "/tf", ros1=ros1)
        except DecodeError:
            self.bad += 1  # a damaged stamp: counted in the same note
            return
        self.stamps.append(stamp)
        self.values.extend(row)


class TfPoses:
    """Camera-to-world poses of one camera frame, looked up by stamp (see the module)."""

    def __init__(self, camera: str, root: str, chain: list[tuple[str, str]], edges: list[Any]):
        self.camera = camera
        self.root = root
        self.chain = chain  # (parent, child) from the root down to the camera
        self._edges: list[Any] = []
        for edge in edges:
            if len(edge.stamps) == 0:
                assert edge.static is not None
                self._edges.append(_matrix(edge.static))
                continue
            stamps = np.frombuffer(edge.stamps, np.int64)
            values = np.frombuffer(edge.values, np.float64).reshape(-1, 7)
            # Sorted by stamp; of samples at one stamp the last one written counts.
            order = np.argsort(stamps, kind="stable")
            stamps, values = stamps[order], values[order]
            keep = np.ones(stamps.size, bool)
            keep[:-1] = stamps[1:] != stamps[:-1]
            self._edges.append((stamps[keep], values[keep]))

    def at(self, ns: int) -> npt.NDArray[np.float64] | None:
        """The 4 × 4 camera-to-world pose at stamp ``ns``, or ``None`` where tf has none."""
        pose = np.eye(4)
        for edge in self._edges:
            m = edge if isinstance(edge, np.ndarray) else _lookup(edge[0], edge[1], ns)
            if m is None:
                return None
            pose = pose @ m
        return pose


def _matrix(row: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    m = np.eye(4)
    m[:3, :3] = quaternion_to_matrix(row[3:])
    m[:3, 3] = row[:3]
    return m


def _lookup(
    stamps: npt.NDArray[np.int64], values: npt.NDArray[np.float64], ns: int
) -> npt.NDArray[np.float64] | None:
    i = int(np.searchsorted(stamps, ns, side="left"))
    if i < stamps.size and int(stamps[i]) == ns:
        return _matrix(values[i])
    if i == 0 or i == stamps.size:
        return None
    t0, t1 = int(stamps[i - 1]), int(stamps[i])
    if t1 - t0 > MAX_GAP_NS:
        return None
    a = (ns - t0) / (t1 - t0)
    v0, v1 = values[i - 1], values[i]
    m = np.eye(4)
    m[:3, :3] = quaternion_to_matrix(slerp(v0[3:], v1[3:], a))
    m[:3, 3] = (1 - a) * v0[:3] + a * v1[:3]
    return m


def read_tf_poses(
    messages: Messages, conns: Iterable[Any], camera_frame: str, notes: list[str]
) -> TfPoses | None:
    """The poses of ``camera_frame`` from the tf connections ``conns`` read through
    ``messages``, or ``None`` (with a line in ``notes`` saying why) when tf does not place the
    camera in a world."""
    tf_conns = [c for c in conns if is_tf(c)]
    camera = _name(camera_frame)
    if not tf_conns:
        return None
    if not camera:
        notes.append("the bag has /tf, but the depth messages name no frame_id: no poses")
        return None
    parents: dict[str, set[str]] = {}
    for _, _, tf in _transforms(messages, tf_conns):
        child, parent = _name(tf.child_frame_id), _name(tf.header.frame_id)
        if child and parent and child != parent:
            parents.setdefault(child, set()).add(parent)
    chain: list[tuple[str, str]] = []
    frame, seen = camera, {camera}
    while frame in parents:
        options = parents[frame]
        if len(options) > 1:
            notes.append(
                f"tf gives frame {frame!r} several parents ({', '.join(sorted(options))}): no poses"
            )
            return None
        (parent,) = options
        if parent in seen:
            notes.append(f"tf has a loop through frame {parent!r}: no poses")
            return None
        seen.add(parent)
        chain.append((parent, frame))
        frame = parent
    if not chain:
        notes.append(f"tf has no transform to the camera frame {camera!r}: no poses")
        return None
    chain.reverse()
    edges = {pc: _Edge() for pc in chain}
    for static, ros1, tf in _transforms(messages, tf_conns):
        edge = edges.get((_name(tf.header.frame_id), _name(tf.child_frame_id)))
        if edge is not None:
            edge.add(static, ros1, tf)
    for (parent, child), edge in edges.items():
        if edge.bad:
            notes.append(
                f"tf: {edge.bad} transforms from {parent!r} to {child!r} with non-finite values, "
                "a zero quaternion or a damaged stamp were ignored"
            )
        if edge.static is None and len(edge.stamps) == 0:
            notes.append(f"tf has no usable transform from {parent!r} to {child!r}: no poses")
            return None
    if all(len(e.stamps) == 0 for e in edges.values()):
        notes.append(
            f"tf places the camera frame {camera!r} in {frame!r} by static transforms only (a "
            "mounting, not a trajectory): no poses"
        )
        return None
    path = " -> ".join([frame, *(child for _, child in chain)])
    notes.append(f"poses from tf: the camera frame {camera!r} in {frame!r} ({path})")
    return TfPoses(camera, frame, chain, [edges[pc] for pc in chain])


@dataclass(frozen=True)
class StaticPlacement:
    """Where ``/tf_static`` places one frame: the root of its chain of static transforms and
    the 4 × 4 transform taking a point of the frame into the root frame."""

    frame: str
    root: str
    pose: npt.NDArray[np.float64]
    path: tuple[str, ...]


def static_placements(
    messages: Messages, conns: Iterable[Any], frames: Iterable[str], notes: list[str]
) -> dict[str, StaticPlacement]:
    """Where the static transforms of ``conns`` (``/tf_static``; ``/tf`` is not read: a rig's
    cameras are mounted, not moving) place each of ``frames``: its chain of parents up to the
    root of the tree, and the product of the transforms along it. Frames that the static tree
    does not hold, or holds ambiguously (two parents, a loop), are left out with a line in
    ``notes``."""
    static = [c for c in conns if is_tf(c) and _static(c)]
    wanted = [_name(f) for f in frames]
    if not static:
        return {}
    rows: dict[tuple[str, str], npt.NDArray[np.float64]] = {}
    parents: dict[str, set[str]] = {}
    for _, _, tf in _transforms(messages, static):
        child, parent = _name(tf.child_frame_id), _name(tf.header.frame_id)
        if not child or not parent or child == parent:
            continue
        edge = _Edge()
        edge.add(True, False, tf)
        if edge.static is None:
            notes.append(f"tf_static: a transform from {parent!r} to {child!r} is not rigid")
            continue
        parents.setdefault(child, set()).add(parent)
        rows[(parent, child)] = edge.static  # the last one of each edge counts
    found: dict[str, StaticPlacement] = {}
    for camera in wanted:
        pose, frame, seen, path = np.eye(4), camera, {camera}, [camera]
        while frame in parents:
            options = parents[frame]
            if len(options) > 1:
                notes.append(
                    f"tf_static gives frame {frame!r} several parents "
                    f"({', '.join(sorted(options))}): {camera!r} is not placed"
                )
                break
            (parent,) = options
            if parent in seen:
                notes.append(f"tf_static has a loop through frame {parent!r}")
                break
            pose = _matrix(rows[(parent, frame)]) @ pose
            seen.add(parent)
            path.append(parent)
            frame = parent
        else:
            if frame != camera:
                found[camera] = StaticPlacement(camera, frame, pose, tuple(reversed(path)))
                continue
            notes.append(f"tf_static has no transform to the frame {camera!r}")
    return found


#: How much the samples of one transform may differ and still be one fixed transform (metres,
#: and quaternion components).
FIXED_TOLERANCE = 1e-6


def frame_to_frame(
    messages: Messages, conns: Iterable[Any], source: str, target: str
) -> tuple[npt.NDArray[np.float64] | None, str]:
    """The fixed rigid transform taking points of frame ``source`` into frame ``target`` (for
    a depth and a color camera: ``depth_to_color``), from the transforms of ``conns``
    (``/tf_static`` and ``/tf``), and a line saying where it came from; or ``None`` and a line
    saying why there is none.

    Both frames' chains of parents are followed up to their nearest common frame; only the
    transforms below it count, so a camera moving in the world still has fixed extrinsics.
    A transform on ``/tf`` counts when all its samples agree (within
    :data:`FIXED_TOLERANCE`); one that changes over time, a frame with two parents, a loop,
    or frames in two trees give ``None``."""
    tf_conns = [c for c in conns if is_tf(c)]
    a, b = _name(source), _name(target)
    if not tf_conns:
        return None, "the bag has no /tf or /tf_static"
    if not (a and b):
        return None, "the images name no frame_id"
    if a == b:
        return None, f"both images name the frame {a!r}, so tf cannot place one in the other"
    parents: dict[str, set[str]] = {}
    rows: dict[tuple[str, str], npt.NDArray[np.float64]] = {}
    static_edges: set[tuple[str, str]] = set()
    moving: set[tuple[str, str]] = set()
    for static, _, tf in _transforms(messages, tf_conns):
        child, parent = _name(tf.child_frame_id), _name(tf.header.frame_id)
        edge = _Edge()
        edge.add(True, False, tf)
        if not child or not parent or child == parent or edge.static is None:
            continue
        key = (parent, child)
        parents.setdefault(child, set()).add(parent)
        if static:  # the last static transform of an edge counts, over any on /tf
            rows[key] = edge.static
            static_edges.add(key)
            moving.discard(key)
        elif key not in static_edges:
            old = rows.setdefault(key, edge.static)
            if float(np.abs(old - edge.static).max()) > FIXED_TOLERANCE:
                moving.add(key)
    chains = []
    for frame in (a, b):
        chain, seen = [frame], {frame}
        while chain[-1] in parents:
            options = parents[chain[-1]]
            if len(options) > 1:
                return None, (
                    f"tf gives frame {chain[-1]!r} several parents ({', '.join(sorted(options))})"
                )
            (parent,) = options
            if parent in seen:
                return None, f"tf has a loop through frame {parent!r}"
            seen.add(parent)
            chain.append(parent)
        chains.append(chain)
    common = next((f for f in chains[0] if f in chains[1]), None)
    if common is None:
        return None, (
            f"tf has no transform between {a!r} and {b!r} (their trees have the roots "
            f"{chains[0][-1]!r} and {chains[1][-1]!r})"
        )
    poses, used = [], []
    for chain in chains:
        pose = np.eye(4)
        for child, parent in itertools.pairwise(chain[: chain.index(common) + 1]):
            if (parent, child) in moving:
                return None, f"tf moves {child!r} in {parent!r} over time"
            pose = _matrix(rows[(parent, child)]) @ pose
            used.append((parent, child))
        poses.append(pose)
    up = chains[0][: chains[0].index(common) + 1]
    down = chains[1][: chains[1].index(common)][::-1]
    where = "/tf_static" if all(e in static_edges for e in used) else "/tf"
    return np.linalg.inv(poses[1]) @ poses[0], f"from {where} ({' -> '.join(up + down)})"
