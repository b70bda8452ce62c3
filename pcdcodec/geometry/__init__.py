"""Camera geometry: pinhole intrinsics (:mod:`.camera`), rigid transforms (:mod:`.transform`)
and the :class:`~pcdcodec.geometry.projector.Projector` between RGB-D images and point clouds.

Loaded on first use, not by ``import pcdcodec``: :mod:`.open3d` (Open3D RGBDImages to and from
arrays) and :mod:`.dataset_cameras` (the intrinsics files and presets datasets publish, as
plain data). Nothing here imports :mod:`pcdcodec.frame`; frames use the geometry.
"""

from __future__ import annotations

from .camera import CameraIntrinsics
from .projector import Projector, Reprojection

__all__ = ["CameraIntrinsics", "Projector", "Reprojection"]
