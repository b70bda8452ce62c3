"""ROS without a ROS runtime: message encodings (:mod:`.messages`, :mod:`.foxglove`), the ROS 1
bag index reader (:mod:`.bagindex`) and tf poses (:mod:`.tf`). Both the bag sources and the bag
export use this room; it imports neither."""

from __future__ import annotations

__all__: list[str] = []
