"""Several cameras as sources: the cameras of one bag (a camera per namespace), where the bag's
``/tf_static`` mounts them, the cameras of other inputs of several (a recording of a rig, opened
by its reader's ``cameras``), and the frames of several sources merged in time order.

A bag holds several cameras when its depth topics (or, without depth images, its organized
clouds) lie in several namespaces (:func:`pcdcodec.ros.topics.camera_namespaces`):
``/cam_head/depth/image_raw`` and ``/cam_wrist/depth/image_raw`` are cameras ``cam_head`` and
``cam_wrist``. Each is read by its own :class:`~pcdcodec.sources.rosbag.RosbagSource` limited to
its namespace's topics, so each camera streams on its own and memory stays bounded. Its rig
pose is where ``/tf_static`` places the frame its depth messages name.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, PcdcodecError
from ..ros import bagfile, tf, topics
from .base import InputStream, Source

__all__ = [
    "BagCameras",
    "CameraInput",
    "bag_cameras",
    "camera_name",
    "close_inputs",
    "left_out_of",
    "merge_by_time",
    "open_bag_cameras",
    "open_inputs",
    "reads_as_rig",
]


@dataclass
class CameraInput:
    """One camera of a rig being recorded: its name, the open source of its frames, and where
    it sits on the rig.

    ``rig_pose`` takes a point of the camera's depth frame into the rig frame (``None``: not
    known). ``pose_from`` says where it came from (``"/tf_static"``, the rig file, ...).
    ``frame_id`` is the camera's frame name (a bag's depth ``frame_id``). ``overrides`` holds
    what replaces the recording's settings for this camera (``color``, ``depth``: codecs as
    :func:`pcdcodec.encode` takes them, ``None`` for no color; ``fps``). ``rig_metadata`` is
    metadata of the whole rig the input carried (a rig recording's own), kept as it is rather
    than under the camera's name.
    """

    name: str
    source: Source
    rig_pose: npt.NDArray[np.float64] | None = None
    pose_from: str = ""
    frame_id: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    owned: bool = True
    rig_metadata: dict[str, str] = field(default_factory=dict)


def camera_name(text: str, taken: Iterable[str] = ()) -> str:
    """A camera name (a letter, then letters, digits or ``_``) made from a namespace or a file
    name, different from those ``taken``: ``/robot/cam_head`` gives ``cam_head``,
    ``2024-05 run.bag`` gives ``cam_2024_05_run``."""
    parts = [p for p in re.split(r"[/\\]", text) if p]
    base = parts[-1] if parts else "camera"
    base = re.sub(r"\.(bag|db3|mcap|mkv|pcdc)$", "", base, flags=re.IGNORECASE)
    name = re.sub(r"[^A-Za-z0-9_]+", "_", base).strip("_") or "camera"
    if not name[0].isalpha():
        name = "cam_" + name
    name = name[:60]
    used = set(taken)
    out, k = name, 2
    while out in used:
        out, k = f"{name}_{k}", k + 1
    return out


@dataclass
class BagCameras:
    """The cameras of a bag: per namespace, the topics its source reads, the frame its depth
    messages name, and where ``/tf_static`` places that frame (``None`` where it does not).
    ``root`` is the frame the placements share (``None`` without any)."""

    path: Path
    namespaces: list[str]
    topics: dict[str, dict[str, str | None]]
    frames: dict[str, str]
    placements: dict[str, tf.StaticPlacement]
    root: str | None
    notes: list[str]

    def __len__(self) -> int:
        return len(self.namespaces)


def _first(reader: Any, conn: Any, path: Path) -> Any:
    try:
        for c, _, raw in reader.messages(connections=[conn]):
            return reader.deserialize(raw, c.msgtype)
    except PcdcodecError:
        raise
    except Exception as exc:
        raise bagfile.bag_error(exc, path) from exc
    return None


def bag_cameras(path: str | os.PathLike[str]) -> BagCameras:
    """Find the cameras of the bag at ``path`` (see the module), without reading any image.

    For each namespace: its depth (or cloud), color and camera info topics, chosen by the rules
    of a one-camera bag among that namespace's topics only. Raises
    :class:`~pcdcodec.InputError` when the bag has no depth topic, and
    :class:`~pcdcodec.InputError` naming the bag when ``/tf_static`` places the cameras in
    trees with different roots."""
    bag = Path(path)
    reader, tmp = bagfile.open_reader(bag)
    try:
        conns = list(reader.connections)
        by_topic = {c.topic: c for c in conns}

        def first(conn: Any) -> Any:
            return _first(reader, conn, bag)

        cands = [topics.classify(c.topic, c.msgtype, c.msgcount, partial(first, c)) for c in conns]
        mode = topics.choose_mode(cands, None, None, str(bag))
        namespaces = topics.camera_namespaces(cands)
        chosen: dict[str, dict[str, str | None]] = {}
        frames: dict[str, str] = {}
        for ns in namespaces:
            mine = [c for c in cands if topics.in_namespace(c.topic, ns)]
            if mode == "cloud":
                anchor = topics.choose_cloud(mine)
                picked: dict[str, str | None] = {"cloud_topic": anchor}
            else:
                anchor = topics.choose_depth(mine)
                cand = {c.topic: c for c in mine}[anchor]
                color = topics.choose_color(mine, anchor, cand.width, cand.height)
                picked = {"depth_topic": anchor, "color_topic": color or ""}
            picked["info_topic"] = topics.choose_info(mine, anchor)
            chosen[ns] = picked
            msg = first(by_topic[anchor])
            frames[ns] = str(msg.header.frame_id).strip().lstrip("/") if msg is not None else ""
        notes: list[str] = []
        messages = _messages(reader, bag)
        named = [f for f in frames.values() if f]
        placements = tf.static_placements(messages, conns, named, notes) if named else {}
    finally:
        with contextlib.suppress(Exception):
            reader.close()
        if tmp is not None:
            tmp.cleanup()
    roots = sorted({p.root for p in placements.values()})
    if len(roots) > 1:
        where = ", ".join(f"{f!r} in {p.root!r}" for f, p in placements.items())
        raise InputError(
            f"bag {str(bag)!r}: /tf_static places the cameras in trees with different roots "
            f"({where}); give their extrinsics in a rig file (--rig)"
        )
    return BagCameras(
        bag, namespaces, chosen, frames, placements, roots[0] if roots else None, notes
    )


def _messages(reader: Any, bag: Path) -> Any:
    def read(conns: list[Any]) -> Iterator[tuple[Any, int, Any]]:
        try:
            for c, t, raw in reader.messages(connections=conns):
                yield c, t, reader.deserialize(raw, c.msgtype)
        except PcdcodecError:
            raise
        except Exception as exc:
            raise bagfile.bag_error(exc, bag) from exc

    return read


def open_bag_cameras(
    found: BagCameras, namespaces: Sequence[str] | None = None, **options: Any
) -> list[CameraInput]:
    """A :class:`CameraInput` per namespace of ``found`` (or of ``namespaces``), each read by a
    :class:`~pcdcodec.sources.rosbag.RosbagSource` of its own topics; ``options`` go to each
    (``max_frames``, ``max_difference``, ...). Rig poses are ``/tf_static``'s, in
    ``found.root``."""
    from .rosbag import RosbagSource

    wanted = list(found.namespaces if namespaces is None else namespaces)
    out: list[CameraInput] = []
    try:
        for ns in wanted:
            if ns not in found.topics:
                raise InputError(
                    f"bag {str(found.path)!r} has no camera in namespace {ns!r}; its cameras "
                    f"are in {found.namespaces}"
                )
            # A bag of one camera is read exactly as on its own.
            chosen = found.topics[ns] if len(found.namespaces) > 1 else {}
            # A camera of a rig keeps no topics: what no camera reads is named as left out.
            source = RosbagSource(found.path, **{**chosen, "keep_topics": False, **options})
            frame = found.frames[ns] or None
            placed = found.placements.get(frame or "")
            cam = CameraInput(
                camera_name(ns, [c.name for c in out]),
                source,
                rig_pose=None if placed is None else placed.pose,
                pose_from="" if placed is None else "/tf_static: " + " -> ".join(placed.path),
                frame_id=frame,
            )
            out.append(cam)
    except BaseException:
        close_inputs(out)
        raise
    return out


def merge_by_time(
    cameras: Sequence[CameraInput], frames: Sequence[Iterable[Any]] | None = None
) -> Iterator[tuple[int, Any]]:
    """The frames of every camera as ``(camera index, frame)``, in timestamp order across
    cameras (ties in the cameras' order), each camera read one frame ahead: memory is one frame
    per camera, however long the inputs. ``frames`` gives each camera's frames (default: its
    whole source)."""
    streams_in = [cam.source for cam in cameras] if frames is None else list(frames)

    def tagged(k: int, stream: Iterable[Any]) -> Iterator[tuple[int, int, Any]]:
        for frame in stream:
            yield int(frame.timestamp_ns), k, frame

    streams = [tagged(k, stream) for k, stream in enumerate(streams_in)]
    for _, k, frame in heapq.merge(*streams, key=lambda item: (item[0], item[1])):
        yield k, frame


def open_inputs(
    inputs: Sequence[str | os.PathLike[str] | Source], **options: Any
) -> tuple[list[CameraInput], str | None]:
    """A :class:`CameraInput` per camera of ``inputs``: each camera of a bag of several
    cameras (named by namespace, placed by ``/tf_static``), each camera of another input of
    several (a recording of a rig: its names and rig poses), and one per other input (named by
    its file, placed where its bag's ``/tf_static`` says, else not placed). ``options`` go to
    every source opened. Returns the cameras and the root frame their placements share
    (``None`` without any). Raises :class:`~pcdcodec.InputError` when two inputs place their
    cameras in frames with different roots."""
    from .base import detect_kind, open_source

    cams: list[CameraInput] = []
    roots: dict[str, str] = {}
    try:
        for item in inputs:
            taken = [c.name for c in cams]
            if isinstance(item, Source):
                name = camera_name(Path(str(item.path)).name, taken)
                cams.append(CameraInput(name, item, owned=False))
                continue
            path = Path(item)
            kind = detect_kind(path)
            if kind != "rosbag":
                several = _input_cameras(path, kind, options)
                if several is None:
                    name = camera_name(path.name, taken)
                    # A rig keeps no other topics: those of a camera file are left out, named.
                    keeps = kind in ("realsense", "azure_kinect")
                    opts = {"keep_topics": False, **options} if keeps else options
                    cams.append(CameraInput(name, open_source(path, **opts)))
                    continue
                opened, root = several
                if root is not None:
                    roots[str(path)] = root
                for cam in opened:
                    # Kept as named unless an earlier input took the name.
                    if cam.name in taken:
                        cam.name = camera_name(cam.name, taken)
                    taken.append(cam.name)
                    cams.append(cam)
                continue
            found = bag_cameras(path)
            if found.root is not None:
                roots[str(path)] = found.root
            for cam in open_bag_cameras(found, **options):
                label = path.name if len(found) == 1 else cam.name
                cam.name = camera_name(label, [c.name for c in cams])
                cams.append(cam)
    except BaseException:
        close_inputs(cams)
        raise
    if len(set(roots.values())) > 1:
        close_inputs(cams)
        where = ", ".join(f"{p!r}: {r!r}" for p, r in roots.items())
        raise InputError(
            f"the inputs place their cameras in frames with different roots ({where}: "
            "/tf_static trees or recorded rigs); give the cameras' extrinsics in a rig file "
            "(--rig)"
        )
    return cams, next(iter(roots.values()), None)


def _input_cameras(
    path: Path, kind: str | None, options: dict[str, Any]
) -> tuple[list[CameraInput], str | None] | None:
    """The cameras of an input of several whose reader opens them (its ``cameras``), or
    ``None`` for an input read as one camera."""
    from .base import source_kind

    found = source_kind(kind) if kind is not None else None
    if found is None or found.cameras is None:
        return None
    result: tuple[list[CameraInput], str | None] | None = found.cameras(path, **options)
    return result


def reads_as_rig(path: str | os.PathLike[str]) -> bool:
    """Whether the input at ``path`` is read as a rig: a bag of cameras in several
    namespaces, or an input whose reader opens several (a recording of a rig). An input that
    cannot be read is not: read as one camera, its reader says what is wrong."""
    from .base import detect_kind

    p = Path(path)
    try:
        kind = detect_kind(p)
        if kind == "rosbag":
            return len(bag_cameras(p)) > 1
        found = _input_cameras(p, kind, {})
    except PcdcodecError:
        return False
    if found is None:
        return False
    close_inputs(found[0])
    return True


def left_out_of(cameras: Iterable[CameraInput]) -> dict[str, list[InputStream]]:
    """What a recording of these cameras leaves out of each input: per input path, the
    topics, tracks or cameras that no camera read from it records (the cameras of one bag each
    read their own namespace's topics; what none of them reads is left out). Inputs that
    leave nothing out are not listed. A bag's ``/tf_static`` that placed a camera on the rig
    is recorded (as its rig pose)."""
    found: dict[str, list[InputStream]] = {}
    for cam in cameras:
        key = str(cam.source.path)
        placed = cam.pose_from.startswith("/tf_static")
        mine = [s for s in cam.source.left_out if not (placed and s.name == "/tf_static")]
        if key in found:
            names = {s.name for s in mine}
            mine = [s for s in found[key] if s.name in names]
        found[key] = mine
    return {k: v for k, v in found.items() if v}


def close_inputs(cameras: Iterable[CameraInput]) -> None:
    """Close the sources opened for ``cameras`` (those handed in open stay open)."""
    for cam in cameras:
        if cam.owned:
            with contextlib.suppress(Exception):
                cam.source.close()
