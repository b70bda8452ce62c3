"""ROS without a ROS runtime: what both the bag sources and the bag export use.

* :mod:`.bagfile`: telling bags from other files, and opening one with rosbags;
* :mod:`.topics`: each topic's role, and the automatic choice of depth, color, info and cloud;
* :mod:`.messages`: message payloads (stamps, images, compressed images, camera info, video);
* :mod:`.clouds`: organized PointCloud2 clouds, read and written;
* :mod:`.bagindex`: frame indexes of bags, and reading a stretch of frames back;
* :mod:`.bagwriter`: building messages and writing ROS 1 and ROS 2 bags;
* :mod:`.tf`: camera poses from /tf; :mod:`.foxglove`: the Foxglove schemas recordings carry.

The sources, the recording and the export build on this room.
"""

from __future__ import annotations

__all__: list[str] = []
