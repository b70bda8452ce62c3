"""The paper's two-file layout: the color stream as a video, the depth as LZ4 frames.

The published compressed point cloud streams method kept an RGB-D stream as two files side by
side, the color as an ordinary video (written with OpenCV's ``VideoWriter``) and the depth as
LZ4 frames, held in step by timestamps. :func:`export_paper` writes a recording in that layout
and :func:`import_paper` turns such a folder back into a recording, so results can be compared
with the paper's tools. The folder holds::

    color.mkv    the recording's color packets, muxed as they are (Matroska; HuffYUV and
                 FFVHuff, which Matroska does not list, go into color.avi instead)
    depth.lz4    one standard LZ4 frame per depth frame, concatenated, each the raw
                 little-endian uint16 (or float32) pixels row by row with its size stored:
                 ``lz4 -d depth.lz4`` gives the images one after another
    frames.json  the camera, the depth scale, the codecs and, per frame, its timestamp, where
                 its LZ4 frame lies in depth.lz4 and the pts of its color frame in the video;
                 and what else the recording holds, which import gives back: the user's
                 metadata, the frame id, a color camera apart with its depth_to_color, and
                 per frame its pose and the images' own times where they were stamped apart

Color is never re-encoded, either way: a lossless recording stays lossless, a lossy one loses
nothing more. Depth is exact both ways.

The work is done in three modules beside this one: :mod:`.paper_layout` (frames.json, written
and read), :mod:`.paper_export` and :mod:`.paper_import`.
"""

from __future__ import annotations

from .paper_export import export_paper
from .paper_import import import_paper
from .paper_layout import CODEC_IDS as CODEC_IDS
from .paper_layout import DEPTH_FILE as DEPTH_FILE
from .paper_layout import FORMAT_NAME, LAYOUT_VERSION
from .paper_layout import FRAMES_FILE as FRAMES_FILE
from .paper_layout import VIDEO_FILES as VIDEO_FILES

__all__ = ["FORMAT_NAME", "LAYOUT_VERSION", "export_paper", "import_paper"]
