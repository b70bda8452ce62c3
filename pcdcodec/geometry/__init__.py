"""Camera geometry: pinhole intrinsics (:mod:`.camera`), rigid transforms (:mod:`.transform`)
and the :class:`~pcdcodec.geometry.projector.Projector` between RGB-D images and point clouds."""

from __future__ import annotations

from .camera import CameraIntrinsics
from .projector import Projector, Reprojection

__all__ = ["CameraIntrinsics", "Projector", "Reprojection"]
