"""Conversions between a recording and other layouts: ROS bags (:mod:`.rosbag`) and the original
method's two-file layout (:mod:`.paper`)."""

from __future__ import annotations

__all__: list[str] = []
