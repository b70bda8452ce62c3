"""Which topics of a bag feed a recording: each topic's role, read from its first message, and
the automatic choice of the depth (or cloud), color and camera info topics.

The rules (also in ``docs/ingest.md``, "How topics are chosen"):

1. **depth**: raw ``Image`` topics before compressed ones, then the busiest topic, then depth
   registered to the color camera (realsense-ros's ``aligned_depth_to_color``) before the depth
   camera's own images (:func:`depth_choice_note` says which was chosen and why); with no depth
   image but an organized ``PointCloud2``, the cloud is read instead;
2. **color**: among color topics of the depth's size, the one whose name looks most like the same
   camera (:func:`affinity`), colour before mono8, raw before compressed;
3. **camera info**: the ``CameraInfo`` topic closest in name to the depth (or cloud) topic; the
   color camera's own, where the bag has one (:func:`choose_color_info`), tells whether color is
   registered to depth or a camera apart.

A bag whose depth topics lie in several namespaces holds several cameras
(:func:`camera_namespaces`); each camera's topics are then chosen by these rules among its own
namespace's topics (``docs/rig.md``).

Nothing here reads a bag: the bag source hands in each connection and a way to read its first
message, and gets roles and choices back, so the rules can be read (and tested) on their own.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import DecodeError, InputError, PcdcodecError
from . import messages as rm

__all__ = [
    "CAMERA_INFO",
    "COMPRESSED",
    "IMAGE",
    "POINT_CLOUD",
    "VIDEO_TYPES",
    "TopicCandidate",
    "affinity",
    "camera_namespaces",
    "check_color",
    "check_depth",
    "choose_cloud",
    "choose_color",
    "choose_color_info",
    "choose_depth",
    "choose_info",
    "choose_mode",
    "classify",
    "depth_choice_note",
    "in_namespace",
    "is_registered_depth",
    "topic_namespace",
]

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
POINT_CLOUD = "sensor_msgs/msg/PointCloud2"
VIDEO_TYPES = ("foxglove_msgs/msg/CompressedVideo", "ffmpeg_image_transport_msgs/msg/FFMPEGPacket")

#: topic name parts that say nothing about which camera a topic belongs to
_GENERIC = frozenset(
    {"image", "image_raw", "image_rect", "image_rect_raw", "data", "compressed", "compresseddepth",
     "camera_info", "info", "points", "raw", ""}
)  # fmt: skip


@dataclass
class TopicCandidate:
    """A topic that could feed a recording, with what its first message says."""

    topic: str
    msgtype: str
    count: int
    role: str | None  # "depth", "color", "info", "cloud", "video" or None (unusable)
    encoding: str = ""
    width: int = 0
    height: int = 0
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "topic": self.topic,
            "type": self.msgtype,
            "messages": self.count,
            "role": self.role,
            "encoding": self.encoding,
            "size": f"{self.width}x{self.height}" if self.width else "",
            "note": self.note,
        }


def classify(topic: str, msgtype: str, count: int, first: Callable[[], Any]) -> TopicCandidate:
    """A topic's role from its type and first message (``first()`` reads it, or gives ``None``
    for an empty topic; it is called only for the types whose role depends on the message).
    Compressed images are not decoded: their size comes from the image's header."""
    cand = TopicCandidate(topic, msgtype, count, None)
    if msgtype == IMAGE:
        msg = first()
        if msg is not None:
            cand.encoding = str(msg.encoding)
            cand.width, cand.height = int(msg.width), int(msg.height)
            cand.role = rm.image_kind(cand.encoding)
            if cand.role is None:
                cand.note = "unsupported encoding"
    elif msgtype == COMPRESSED:
        msg = first()
        if msg is not None:
            cand.encoding = str(msg.format)
            cand.role = rm.compressed_kind(cand.encoding)
            if cand.role is not None:
                try:
                    cand.width, cand.height = rm.compressed_size(msg, cand.role, topic)
                except PcdcodecError as exc:
                    cand.role, cand.note = None, str(exc)
    elif msgtype == CAMERA_INFO:
        msg = first()
        cand.role = "info"
        if msg is not None:
            cand.width, cand.height = int(msg.width), int(msg.height)
            cand.encoding = str(msg.distortion_model)
    elif msgtype == POINT_CLOUD:
        msg = first()
        if msg is not None:
            cand.width, cand.height = int(msg.width), int(msg.height)
            cand.encoding = ",".join(str(f.name) for f in msg.fields)
            cand.role = "cloud" if cand.height > 1 else None
            if cand.height <= 1:
                cand.note = "unorganized (height 1)"
    elif msgtype in VIDEO_TYPES:
        cand.role = "video"
    return cand


def _parts(topic: str) -> list[str]:
    return [p for p in topic.lower().split("/") if p]


def affinity(a: str, b: str) -> tuple[int, int]:
    """How much two topics look like one camera: shared parts that name something (not
    ``image_raw``, ``camera_info``, ...), then shared leading parts."""
    pa, pb = _parts(a), _parts(b)
    lead = 0
    for x, y in zip(pa, pb, strict=False):
        if x != y:
            break
        lead += 1
    common = len({p for p in pa if p not in _GENERIC} & {p for p in pb if p not in _GENERIC})
    return common, lead


def choose_mode(
    cands: Sequence[TopicCandidate], depth_topic: str | None, cloud_topic: str | None, bag: str
) -> str:
    """``"cloud"`` when a cloud topic is given, or when there is no depth image but an organized
    cloud; else ``"images"``. Raises :class:`~pcdcodec.InputError` naming ``bag`` when the bag
    has neither."""
    if cloud_topic is not None:
        return "cloud"
    if depth_topic is not None or any(c.role == "depth" for c in cands):
        return "images"
    if any(c.role == "cloud" for c in cands):
        return "cloud"
    found = ", ".join(f"{c.topic} ({c.msgtype})" for c in cands) or "no topics"
    raise InputError(
        f"bag {bag!r} has no depth topic (an Image in "
        f"{'/'.join(rm.DEPTH_ENCODINGS)}, a compressedDepth CompressedImage or an "
        f"organized PointCloud2); it has {found}"
    )


def choose_cloud(cands: Sequence[TopicCandidate]) -> str:
    """The first organized cloud topic."""
    return next(c.topic for c in cands if c.role == "cloud")


def is_registered_depth(topic: str) -> bool:
    """Whether a depth topic's name says it is registered to the color camera (realsense-ros's
    ``aligned_depth_to_color``, openni's ``depth_registered``)."""
    return any(p.startswith("aligned_depth_to") or p == "depth_registered" for p in _parts(topic))


def choose_depth(cands: Sequence[TopicCandidate]) -> str:
    """Raw images before compressed ones, then the busiest topic, then depth registered to the
    color camera before the depth camera's own (then by name)."""
    depth = [c for c in cands if c.role == "depth"]
    return sorted(
        depth,
        key=lambda c: (c.msgtype != IMAGE, -c.count, not is_registered_depth(c.topic), c.topic),
    )[0].topic


def depth_choice_note(
    cands: Sequence[TopicCandidate], depth_topic: str, given: bool = False
) -> str | None:
    """Where a camera's namespace holds both depth registered to the color camera and the depth
    camera's own images, which of them ``depth_topic`` is and why it was chosen; else ``None``."""
    ns = topic_namespace(depth_topic)
    mine = {c.topic: c for c in cands if c.role == "depth" and in_namespace(c.topic, ns)}
    chosen = mine.get(depth_topic)
    registered = is_registered_depth(depth_topic)
    others = [
        c for t, c in mine.items() if t != depth_topic and is_registered_depth(t) != registered
    ]
    if chosen is None or not others:
        return None
    other = others[0]
    if given:
        why = "as given"
    elif (chosen.msgtype == IMAGE) != (other.msgtype == IMAGE):
        why = "raw images before compressed ones"
    elif chosen.count != other.count:
        why = f"it has more messages ({chosen.count} against {other.count})"
    else:
        why = "registered depth needs no extrinsics for its color"
    if registered:
        return (
            f"depth topic {depth_topic!r} is registered to the color camera, chosen over "
            f"{other.topic!r}, the depth camera's own images ({why}); pass "
            f"depth_topic={other.topic!r} to record those, with the color camera apart"
        )
    return (
        f"depth topic {depth_topic!r} is the depth camera's own images, chosen over "
        f"{other.topic!r}, registered to the color camera ({why}); the color camera is "
        "recorded apart where its CameraInfo differs"
    )


def check_depth(cand: TopicCandidate) -> None:
    """Raise unless ``cand`` holds depth: :class:`~pcdcodec.DecodeError` when its first image
    is compressed depth that cannot be read, else :class:`~pcdcodec.InputError`."""
    if cand.role == "depth":
        return
    if cand.note and rm.compressed_kind(cand.encoding) == "depth":
        raise DecodeError(cand.note)
    raise InputError(
        f"depth topic {cand.topic!r} has encoding {cand.encoding!r}; expected one of "
        f"{', '.join(rm.DEPTH_ENCODINGS)} or a compressedDepth format"
    )


def choose_color(
    cands: Sequence[TopicCandidate], depth_topic: str, width: int, height: int
) -> str | None:
    """The color topic of the depth's size that looks most like the depth's camera, colour
    before mono8 and raw before compressed; else a color topic of another size with a
    CameraInfo of its own (a color camera apart, :func:`choose_color_info`); else ``None``.

    Raises :class:`~pcdcodec.DecodeError` when there is none but a compressed color topic's first
    image is damaged or oversized: that is not a camera of another size, and recording depth
    only would lose its color unseen.
    """
    colors = [c for c in cands if c.role == "color" and (c.width, c.height) == (width, height)]
    colors.sort(
        key=lambda c: (
            affinity(c.topic, depth_topic),
            c.encoding != "mono8" and not c.encoding.startswith("mono8"),
            c.msgtype == IMAGE,
        ),
        reverse=True,
    )
    if colors:
        return colors[0].topic
    # A color camera apart, of its own size: a color topic with a CameraInfo of its own.
    apart = [
        c
        for c in cands
        if c.role == "color" and choose_color_info(cands, c.topic, depth_topic, None)
    ]
    apart.sort(key=lambda c: (affinity(c.topic, depth_topic), c.msgtype == IMAGE), reverse=True)
    if apart:
        return apart[0].topic
    damaged = [
        c
        for c in cands
        if c.msgtype == COMPRESSED and c.note and rm.compressed_kind(c.encoding) == "color"
    ]
    if damaged:
        raise DecodeError(
            f"{damaged[0].note}; its first image cannot be read, so its color "
            "cannot be recorded (pass color_topic='' to record depth only)"
        )
    return None


def check_color(
    cand: TopicCandidate, depth_topic: str, width: int, height: int, apart: bool = False
) -> None:
    """Raise unless ``cand`` holds color of the depth's size (registered depth and color), or
    of any size where it has a CameraInfo of its own (``apart``: a color camera apart)."""
    if cand.role != "color":
        if cand.note and rm.compressed_kind(cand.encoding) == "color":
            raise DecodeError(cand.note)
        raise InputError(
            f"color topic {cand.topic!r} has encoding {cand.encoding!r}; expected "
            f"one of {', '.join(rm.COLOR_ENCODINGS)} or a JPEG/PNG CompressedImage"
        )
    if (cand.width, cand.height) != (width, height) and not apart:
        raise InputError(
            f"color topic {cand.topic!r} is {cand.width}x{cand.height} but depth "
            f"topic {depth_topic!r} is {width}x{height}, and it has no CameraInfo of its own; "
            "pcdcodec needs registered depth and color of one size, or the color camera's "
            "CameraInfo (pass color_topic='' for depth only)"
        )


def choose_info(cands: Sequence[TopicCandidate], anchor: str) -> str | None:
    """The CameraInfo topic closest in name to ``anchor`` (the depth or cloud topic): the only
    one, or the closest when it shares something with ``anchor``; else ``None``."""
    infos = [c for c in cands if c.role == "info"]
    infos.sort(key=lambda c: affinity(c.topic, anchor), reverse=True)
    if infos and (len(infos) == 1 or affinity(infos[0].topic, anchor) > (0, 0)):
        return infos[0].topic
    return None


def choose_color_info(
    cands: Sequence[TopicCandidate], color_topic: str, depth_topic: str, info_topic: str | None
) -> str | None:
    """The color camera's own CameraInfo topic: of the color images' size, other than the
    depth's ``info_topic``, and closer in name to ``color_topic`` than to ``depth_topic``
    (the closest such); ``None`` where the bag has none."""
    color = next((c for c in cands if c.topic == color_topic), None)
    size = (color.width, color.height) if color is not None else None
    infos = [
        c
        for c in cands
        if c.role == "info"
        and c.topic != info_topic
        and (size is None or (c.width, c.height) == size)
        and affinity(c.topic, color_topic) > affinity(c.topic, depth_topic)
    ]
    infos.sort(key=lambda c: affinity(c.topic, color_topic), reverse=True)
    return infos[0].topic if infos else None


def topic_namespace(topic: str) -> str:
    """The camera namespace of a depth (or cloud) topic: its parts before the first part that
    names depth or points (``/cam_head/depth/image_raw`` and
    ``/cam_head/aligned_depth_to_color/image_raw``: ``/cam_head``), else all but its last part
    (``/cam_wrist/cloud``: ``/cam_wrist``). A topic that starts by naming depth
    (``/depth/image_raw``) is in the root namespace ``/``."""
    parts = _parts(topic)
    for k, part in enumerate(parts):
        if "depth" in part or part in ("points", "point_cloud", "cloud"):
            return "/" + "/".join(parts[:k])
    return "/" + "/".join(parts[:-1])


def in_namespace(topic: str, namespace: str) -> bool:
    """Whether ``topic`` lies under ``namespace`` (``"/"``: every topic)."""
    prefix = namespace.rstrip("/").lower() + "/"
    return ("/" + "/".join(_parts(topic)) + "/").startswith(prefix)


def camera_namespaces(cands: Sequence[TopicCandidate]) -> list[str]:
    """The namespaces holding a camera, in name order: one per namespace of a depth topic (or,
    for a bag without depth images, of an organized cloud topic). A bag of one camera gives one
    namespace, whatever depth topics it holds there."""
    role = "depth" if any(c.role == "depth" for c in cands) else "cloud"
    return sorted({topic_namespace(c.topic) for c in cands if c.role == role})
