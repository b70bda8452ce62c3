"""The color camera of a bag's images: registered to the depth, or a camera apart.

realsense-ros publishes by default the depth camera's own images (``depth/image_rect_raw``) and
the color camera's (``color/image_raw``), two cameras with their own CameraInfo. Where the color
topic's CameraInfo differs from the depth's camera, the color camera is recorded apart, with the
``depth_to_color`` transform from the bag's ``/tf`` or ``/tf_static`` between the two images'
``frame_id``s; where tf does not give it, a ``depth_to_color`` given fills it in, and without
either the bag is refused, saying how to give one. Nothing is guessed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..geometry.camera import CameraIntrinsics
from ..geometry.transform import check_color_camera
from ..ros import messages as rm
from ..ros import topics
from .folder import as_transform

__all__ = ["color_camera"]

Transform = npt.NDArray[np.float64]


def _same_pinhole(a: CameraIntrinsics, b: CameraIntrinsics) -> bool:
    return a.shape == b.shape and bool(
        np.allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy], rtol=1e-9, atol=1e-9)
    )


def _text(camera: CameraIntrinsics) -> str:
    return f"fx={camera.fx:g} fy={camera.fy:g} cx={camera.cx:g} cy={camera.cy:g}"


def color_camera(
    cands: Sequence[topics.TopicCandidate],
    conns: tuple[Any, Any],
    info_topic: str | None,
    depth_camera: CameraIntrinsics | None,
    given: Any,
    first: Callable[[str], Any],
    frame_to_frame: Callable[[str, str], tuple[Transform | None, str]],
) -> tuple[CameraIntrinsics, Transform, str, str | None] | None:
    """``(color camera, depth_to_color, note, problem)`` where the color topic (``conns``: the
    depth and color connections) has a CameraInfo of its own that differs from
    ``depth_camera``; ``None`` where color is registered to depth (no CameraInfo of its own,
    or one that agrees).

    ``first(topic)`` reads a topic's first message; ``frame_to_frame(depth frame, color
    frame)`` is :func:`pcdcodec.ros.tf.frame_to_frame` over the bag. The transform is tf's,
    else ``given`` (a 4 × 4 matrix or a text file of its 16 numbers); without either,
    ``problem`` says why and how to give one (the transform is then the identity, never
    used: reading refuses). Raises :class:`~pcdcodec.InputError` for a color CameraInfo
    without a usable camera, or a transform that is not rigid or whose translation is not
    metres."""
    dconn, cconn = conns
    info = topics.choose_color_info(cands, cconn.topic, dconn.topic, info_topic)
    msg = None if info is None else first(info)
    if msg is None or depth_camera is None:
        return None
    own, model, dist = rm.camera_info(msg, str(info))
    try:
        camera = CameraIntrinsics.from_camera_info(
            {
                "width": own.width,
                "height": own.height,
                "K": own.K.ravel().tolist(),
                "D": dist,
                "distortion_model": model,
            }
        )
    except InputError as exc:
        raise InputError(f"camera info topic {info!r}: {exc}") from None
    if _same_pinhole(camera, depth_camera):
        return None
    heads = [getattr(first(c.topic), "header", None) for c in conns]
    dframe, cframe = (str(getattr(h, "frame_id", "")).strip() for h in heads)
    d2c, where = frame_to_frame(dframe, cframe)
    mine = None if given is None else as_transform(given, "depth_to_color")
    apart = (
        f"color topic {cconn.topic!r} is a camera apart from the depth: its CameraInfo {info!r} "
        f"says {_text(camera)}, the depth's {_text(depth_camera)}"
    )
    problem = None
    if d2c is not None:
        note = f"{apart}: recorded apart, depth_to_color {where}"
        if mine is not None and not np.allclose(mine, d2c, atol=1e-6):
            note += "; the depth_to_color given differs from it, and the bag's is used"
    elif mine is not None:
        d2c, note = mine, f"{apart}: recorded apart, depth_to_color as given ({where})"
    else:
        problem = note = (
            f"{apart}; its depth_to_color is not in the bag: {where} (depth frame {dframe!r}, "
            f"color frame {cframe!r}): pass depth_to_color= (the 4x4 depth-to-color transform "
            "in metres, 16 numbers row-major), or color_topic='' for depth only"
        )
    checked, d2c = check_color_camera(camera, d2c)
    assert checked is not None
    assert d2c is not None
    return checked, d2c, note, problem
