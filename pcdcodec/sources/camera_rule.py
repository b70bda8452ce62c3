"""The one rule for what an input says about its camera, and what a command gives for it.

An input's own intrinsics and depth scale (recorded, in its folder's files, or by its dataset's
convention) win; a camera or depth scale a command is given (:class:`CameraDefaults`) fills in
only what the input lacks; where the two disagree, the source's ``camera_notes`` say so, naming
both. Only an explicit override (``CameraDefaults(..., override=True)``: ``--override`` on the
command line, ``override=True`` in Python) replaces the input's own, and the notes say what was
replaced. :func:`settle_camera` applies the rule to an open source; :func:`~pcdcodec.sources.
open_source` (``defaults=``), ``encode``, ``info``, ``bench`` and ``archive`` go through it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InputError

if TYPE_CHECKING:
    from ..geometry.camera import CameraIntrinsics

__all__ = ["CameraDefaults", "settle_camera"]


@dataclass(frozen=True)
class CameraDefaults:
    """A camera and a depth scale given for an input, beside what the input says itself.

    Given to :func:`open_source` as ``defaults`` (or to :func:`settle_camera` for a source
    already open), they follow one rule, the same for every command and reader: the input's own
    intrinsics and depth scale (recorded, in its files, or by its dataset's convention) win, a
    given value fills in only what the input lacks, and where a given value contradicts the
    input's own, the source's ``camera_notes`` say so, naming both. With ``override=True`` the
    given values replace the input's own instead, and the notes say what was replaced.

    ``intrinsics`` is a :class:`~pcdcodec.CameraIntrinsics` or an intrinsics file (a bare 3 x 3
    matrix takes the size of the input's images). ``origin`` names the values in those notes
    and in the source's ``intrinsics_origin`` / ``depth_scale_origin`` (``"--camera tum-ros"``,
    say); ``depth_scale_origin`` names the depth scale where it came from elsewhere
    (``"--depth-scale"``).
    """

    intrinsics: CameraIntrinsics | str | os.PathLike[str] | None = None
    depth_scale: float | None = None
    origin: str = "defaults"
    #: where the depth scale came from, when not from ``origin`` (``"--depth-scale"``)
    depth_scale_origin: str | None = None
    #: replace the input's own camera and depth scale instead of filling in what it lacks
    override: bool = False
    #: how to replace the input's own, as the notes of a contradiction say it
    how_to_override: str = "override=True"

    def __post_init__(self) -> None:
        if self.depth_scale is not None:
            from .._validate import check_depth_scale

            object.__setattr__(self, "depth_scale", check_depth_scale(self.depth_scale))
        if not isinstance(self.override, bool):
            raise InputError(f"override must be True or False, got {self.override!r}")
        if isinstance(self.intrinsics, (str, os.PathLike)) and not Path(self.intrinsics).is_file():
            raise InputError(f"intrinsics file {str(self.intrinsics)!r} does not exist")

    @property
    def hint(self) -> str:
        """The end of a note of a contradiction: how to make the given value win."""
        return f" ({self.how_to_override} replaces it)" if self.how_to_override else ""

    @property
    def scale_origin(self) -> str:
        """The name of the depth scale in notes and in ``depth_scale_origin``."""
        return self.depth_scale_origin or self.origin

    def camera(self, width: int, height: int) -> CameraIntrinsics | None:
        """The given camera, a file read for images of ``width`` x ``height``."""
        if self.intrinsics is None:
            return None
        from ..geometry.camera import as_intrinsics

        return as_intrinsics(self.intrinsics, self.origin, width, height)


def _camera_text(camera: CameraIntrinsics) -> str:
    return (
        f"{camera.width}x{camera.height} fx={camera.fx:g} fy={camera.fy:g} "
        f"cx={camera.cx:g} cy={camera.cy:g}"
    )


def _from(origin: str) -> str:
    """Where an input's own value came from, as a note says it."""
    return {"input": "the input", "given": "a reader option"}.get(origin, origin)


def _scale_text(origin: str, scale: float) -> str:
    """A given depth scale and its name: ``depth_scale=1000``, ``--depth-scale 1000``, or
    ``--camera kinect-v1 depth scale 1000``."""
    if origin.endswith("="):
        return f"{origin}{scale:g}"
    if "scale" in origin:
        return f"{origin} {scale:g}"
    return f"{origin} depth scale {scale:g}"


def _first_size(source: Any) -> tuple[int, int]:
    """(width, height) of the source's images: its camera's, else its first frame's."""
    if source.intrinsics is not None:
        return source.intrinsics.width, source.intrinsics.height
    first = next(iter(source.frames(0, 1)), None)
    if first is None:
        raise InputError(f"{str(source.path)!r} gives no frames")
    h, w = first.depth.shape[:2]
    return w, h


def settle_camera(source: Any, given: CameraDefaults, *, scale_filled: bool = False) -> Any:
    """The one rule for what an input says about its camera, applied to an open ``source`` (a
    :class:`~pcdcodec.sources.Source`).

    The input's own intrinsics and depth scale win; ``given`` fills in only what the input
    lacks; a given value that contradicts the input's own is said in ``camera_notes``, naming
    both values and where each came from. With ``given.override`` the given values replace the
    input's own, and ``camera_notes`` say what was replaced. ``scale_filled`` says that the
    source was opened with ``given.depth_scale`` because the input has none.
    :func:`open_source` applies it (``defaults=``), and so does :func:`pcdcodec.encode` for a
    source handed in open. Returns ``source``, changed in place.
    """
    notes = list(source.camera_notes)
    if given.intrinsics is not None:
        from ..geometry.camera import CameraIntrinsics

        own = source.intrinsics
        value = given.intrinsics
        # A file or a mapping may leave the image size to the input's images.
        camera = value if isinstance(value, CameraIntrinsics) else None
        if camera is None:
            camera = given.camera(*_first_size(source))
        assert camera is not None
        if own is None:
            source.intrinsics = camera
            source.intrinsics_origin = given.origin
        elif own.pinhole() != camera.pinhole() or (given.override and own != camera):
            if given.override:
                notes.append(
                    f"{given.origin} camera {_camera_text(camera)} replaces the input's own "
                    f"{_camera_text(own)} (from {_from(source.intrinsics_origin)}), as asked "
                    f"({given.how_to_override})"
                )
                source.intrinsics = camera
                source.intrinsics_origin = given.origin
            else:
                notes.append(
                    f"{given.origin} camera {_camera_text(camera)} differs from the input's own "
                    f"{_camera_text(own)} (from {_from(source.intrinsics_origin)}); the input's is "
                    f"used{given.hint}"
                )
    if given.depth_scale is not None and scale_filled:
        source.depth_scale_origin = given.scale_origin
    elif given.depth_scale is not None and source.depth_scale != given.depth_scale:
        what = _scale_text(given.scale_origin, given.depth_scale)
        own_scale = f"{source.depth_scale:g} (from {_from(source.depth_scale_origin)})"
        if given.override:
            notes.append(
                f"{what} replaces the input's own {own_scale}, as asked ({given.how_to_override})"
            )
            source.depth_scale = float(given.depth_scale)
            source.depth_scale_origin = given.scale_origin
        else:
            notes.append(
                f"{what} differs from the input's own {own_scale}; the input's is used" + given.hint
            )
    source.camera_notes = tuple(notes)
    return source
