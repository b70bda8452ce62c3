"""The ways frames come into a writer besides :meth:`~pcdcodec.RecordingWriter.write`: Open3D
RGBD images, iterables of frames, whole sources, and color and depth that arrive apart. Each
ends in ``write`` (or its checks), so every frame is checked once, there.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import check_depth_scale
from ..color.base import StreamCodec
from ..errors import InputError, InputTypeError
from ..frame import OPEN3D_DEPTH_SCALE, Frame
from ..geometry.camera import CameraIntrinsics
from ..ros.kept import KeptMessage, KeptTopic
from ..sources.base import Source


class FrameInputs:
    """What :class:`~pcdcodec.RecordingWriter` takes besides single frames."""

    path: Path
    intrinsics: CameraIntrinsics
    color_intrinsics: CameraIntrinsics | None
    depth_to_color: npt.NDArray[np.float64] | None
    depth_scale: float
    color_codec: StreamCodec | None
    _sync: Any

    def write(
        self,
        color: Any,
        depth: Any,
        timestamp: int | None = None,
        *,
        pose: Any = None,
        color_timestamp: int | None = None,
        depth_timestamp: int | None = None,
    ) -> None:
        raise NotImplementedError

    def _take(
        self,
        color: Any,
        depth: Any,
        timestamp: int | None,
        pose: Any,
        stamps: tuple[int | None, int | None] = (None, None),
    ) -> None:
        raise NotImplementedError

    def _check_open(self) -> None:
        raise NotImplementedError

    @property
    def kept_topics(self) -> list[KeptTopic]:
        raise NotImplementedError

    def write_message(self, message: KeptMessage) -> None:
        raise NotImplementedError

    def _raise_background_error(self) -> None:
        raise NotImplementedError

    def write_rgbd(
        self,
        rgbd: Any,
        timestamp: int | None = None,
        *,
        depth_scale: float = OPEN3D_DEPTH_SCALE,
    ) -> None:
        """Add an Open3D RGBDImage, legacy (``open3d.geometry``) or tensor (``open3d.t.geometry``).

        ``depth_scale`` is the one the image was made with, in Open3D's convention (the
        ``depth_scale`` given to ``create_from_color_and_depth``, or used with a tensor image;
        Open3D's default is 1000). Depth in depth units must be at this recording's own depth
        scale: a different one raises :class:`~pcdcodec.InputError` instead of storing depth
        rescaled. Tensor images with float32 depth are metres after division by
        ``depth_scale`` and need a depth codec that takes float32. Color must be 8-bit RGB
        (``convert_rgb_to_intensity=False``). Note that a legacy image has already lost the
        depth beyond its ``depth_trunc`` (Open3D's default 3 m).
        """
        self._write_rgbd(rgbd, timestamp, depth_scale, "depth_scale")

    def _write_rgbd(
        self, rgbd: Any, timestamp: int | None, depth_scale: float, keyword: str
    ) -> None:
        """:meth:`write_rgbd`, its errors naming the caller's keyword for the scale."""
        from ..frame import from_open3d_rgbd, open3d_rgbd_kind

        kind = open3d_rgbd_kind(rgbd)
        tensor_float = kind == "tensor" and str(rgbd.depth.dtype) == "Float32"
        scale = check_depth_scale(depth_scale, keyword)
        if kind is not None and not tensor_float and scale != self.depth_scale:
            raise InputError(
                f"this {kind} RGBDImage holds depth at {keyword}={float(depth_scale):g} "
                f"(Open3D's default is {OPEN3D_DEPTH_SCALE:g} unless another was passed), but "
                f"recording {str(self.path)!r} stores {self.depth_scale:g} units per metre; "
                f"pass {keyword}= with the scale the image was made with, or open the "
                f"recording with depth_scale={float(depth_scale):g}"
            )
        color, depth = from_open3d_rgbd(rgbd, depth_scale=depth_scale)
        # An RGBDImage always carries color; a depth-only recording keeps its depth only.
        self.write(color if self.color_codec is not None else None, depth, timestamp)

    def write_frames(
        self,
        frames: Iterable[Any],
        *,
        progress: Callable[[int], None] | None = None,
        rgbd_depth_scale: float = OPEN3D_DEPTH_SCALE,
    ) -> int:
        """Write every frame of an iterable and return how many were written.

        Items may be :class:`~pcdcodec.Frame` objects (from a source, :func:`pcdcodec.load_folder`
        or another recording), ``(color, depth)`` or ``(color, depth, timestamp)`` tuples, or
        Open3D RGBDImages, legacy or tensor, alone or as ``(rgbd, timestamp)`` tuples.
        ``rgbd_depth_scale`` is the depth scale the RGBDImages were made with (see
        :meth:`write_rgbd`). ``progress`` is called with the number of frames written so far.
        To record a whole source with its camera, use :meth:`write_source` (or
        :func:`pcdcodec.encode`). A source (a reader that pairs color and depth) that gave no
        frame because every image was dropped for lack of a partner raises
        :class:`~pcdcodec.InputError` saying so, as :func:`pcdcodec.encode` does.
        """
        from ..frame import open3d_rgbd_kind

        count = 0
        source = frames
        if isinstance(frames, Source):
            frames = self._items_of(frames)  # its other topics kept, or refused
        for item in frames:
            if isinstance(item, KeptMessage):
                self.write_message(item)
                continue
            if isinstance(item, Frame):
                self.write(
                    item.color,
                    item.depth,
                    item.timestamp_ns,
                    pose=item.pose,
                    color_timestamp=item.color_timestamp_ns,
                    depth_timestamp=item.depth_timestamp_ns,
                )
            elif open3d_rgbd_kind(item) is not None:
                self._write_rgbd(item, None, rgbd_depth_scale, "rgbd_depth_scale")
            elif (
                isinstance(item, tuple) and len(item) == 2 and open3d_rgbd_kind(item[0]) is not None
            ):
                self._write_rgbd(item[0], item[1], rgbd_depth_scale, "rgbd_depth_scale")
            elif isinstance(item, tuple) and len(item) in (2, 3):
                self.write(*item)
            else:
                raise InputTypeError(
                    f"frame {count} is a {type(item).__name__}; expected a pcdcodec.Frame, an "
                    "Open3D RGBDImage, an (rgbd, timestamp) or a (color, depth[, timestamp]) "
                    "tuple"
                )
            count += 1
            if progress is not None:
                progress(count)
        _check_not_all_dropped(source, count)
        return count

    def write_source(self, source: Source, *, progress: Callable[[int], None] | None = None) -> int:
        """Write every frame of a :class:`~pcdcodec.Source` and return how many were written.

        The source's camera and depth scale must be this recording's (:func:`pcdcodec.encode`
        opens the writer from the source, so they are). A source without color
        (``source.has_color`` false) needs a writer opened with ``color=None``. Raises
        :class:`~pcdcodec.InputError` when they disagree; frames already written stay intact.
        """
        if not isinstance(source, Source):
            raise InputTypeError(
                f"write_source takes a pcdcodec.Source, got {type(source).__name__}; use "
                "write_frames for other iterables"
            )
        if source.intrinsics is not None and source.intrinsics != self.intrinsics:
            raise InputError(
                f"source {str(source.path)!r} has camera {source.intrinsics.to_dict()}, this "
                f"recording {self.intrinsics.to_dict()}"
            )
        if source.color_intrinsics != self.color_intrinsics or (
            source.depth_to_color is not None
            and self.depth_to_color is not None
            and not np.allclose(source.depth_to_color, self.depth_to_color, rtol=0, atol=1e-12)
        ):

            def show(cam: CameraIntrinsics | None, d2c: Any) -> str:
                t = None if d2c is None else np.round(np.asarray(d2c), 6).tolist()
                return f"color camera {cam.to_dict() if cam else None}, depth_to_color {t}"

            raise InputError(
                f"source {str(source.path)!r} has "
                f"{show(source.color_intrinsics, source.depth_to_color)}; this recording has "
                f"{show(self.color_intrinsics, self.depth_to_color)} "
                "(open the recording with the source's color_intrinsics and depth_to_color)"
            )
        if float(source.depth_scale) != self.depth_scale:
            raise InputError(
                f"source {str(source.path)!r} has depth scale {source.depth_scale} per metre, this "
                f"recording {self.depth_scale}"
            )
        if not source.has_color and self.color_codec is not None:
            raise InputError(
                f"source {str(source.path)!r} has no color; open the recording with color=None"
            )
        count = self._write_source(source, progress)
        _check_not_all_dropped(source, count)
        return count

    def _write_source(self, source: Source, progress: Callable[[int], None] | None) -> int:
        """The frames of ``source``, whose camera, depth scale and color are this recording's
        (checked by :meth:`write_source`; :func:`~pcdcodec.encode` opens the writer from the
        source)."""
        items = self._items_of(source)
        if source.has_color and self.color_codec is None:
            # The color is left out; the pose stays.
            items = (
                Frame(
                    None,
                    f.depth,
                    f.timestamp_ns,
                    pose=f.pose,
                    depth_timestamp_ns=f.depth_timestamp_ns,
                )
                if isinstance(f, Frame)
                else f
                for f in items
            )
        return self.write_frames(items, progress=progress)

    def _items_of(self, source: Source) -> Iterable[Any]:
        """The frames of ``source``, and the kept messages beside them where it has other
        topics (refused when this recording was not opened to keep them)."""
        theirs = source.kept_topics()
        if theirs and not self.kept_topics:
            names = ", ".join(t.topic for t in theirs[:5]) + (", ..." if len(theirs) > 5 else "")
            raise InputError(
                f"source {str(source.path)!r} has {len(theirs)} other topics ({names}) that this "
                "recording was not opened to keep: open it with kept_topics=source.kept_topics() "
                "(pcdcodec.encode does), or open the source with keep_topics=False to record the "
                "camera only"
            )
        return source.items() if theirs else source

    def _synchronizer(self) -> Any:
        if self._sync is None:
            from ..sync import Synchronizer

            self._sync = Synchronizer(max_difference=self.max_sync_difference)
        return self._sync

    #: Largest color/depth time difference (ns) that :meth:`write_color`/:meth:`write_depth`
    #: pair into one frame, as TUM's associate.py (20 ms).
    max_sync_difference: int = 20_000_000

    def write_color(self, color: Any, timestamp: int) -> None:
        """Add a color image that arrives on its own; it is paired with the depth image nearest
        in time (within :attr:`max_sync_difference`) and written as one frame at the depth's
        timestamp, the color keeping its own (``frame.color_timestamp_ns``). Images that find
        no partner are dropped and counted in :attr:`unpaired`. An error met encoding or
        writing an earlier frame is raised before the image is taken (call again to hand it
        in); the pairs it completes are all written, and the first error among them is raised
        after.
        """
        self._check_open()
        # Raised before the image is taken (call again to hand it in), not between the pairs
        # it completes: those are already out of the synchronizer.
        self._raise_background_error()
        self._write_pairs(self._synchronizer().add_color(timestamp, color))

    def write_depth(self, depth: Any, timestamp: int) -> None:
        """Add a depth image that arrives on its own (see :meth:`write_color`)."""
        self._check_open()
        self._raise_background_error()
        self._write_pairs(self._synchronizer().add_depth(timestamp, depth))

    def _write_pairs(self, pairs: Iterable[Any]) -> None:
        """Write the pairs a synchronizer made final, each of them whatever another raises
        (a pair not written is lost: it is in neither the file nor :attr:`unpaired`); the
        first error is raised at the end."""
        first: Exception | None = None
        for color_ts, rgb, depth_ts, depth in pairs:
            try:
                # At the depth's time; the color keeps its own (frame.color_timestamp_ns).
                self._take(rgb, depth, depth_ts, None, (color_ts, None))
            except Exception as exc:
                first = first or exc
        if first is not None:
            raise first

    @property
    def unpaired(self) -> dict[str, list[int]]:
        """Timestamps (ns) of the separately written images that found no partner."""
        if self._sync is None:
            return {"color": [], "depth": []}
        return {"color": list(self._sync.dropped_color), "depth": list(self._sync.dropped_depth)}


def no_frames_error(source: Source) -> InputError:
    """The error of a source that gave no frame: where pairing dropped every image, it says so,
    and what to do (record depth only, or pair within a larger tolerance)."""
    why = ""
    dropped = source.describe().get("dropped")
    if isinstance(dropped, dict) and any(dropped.values()):
        option = "color_topic=''" if hasattr(source, "color_topic") else "color=False"
        why = (
            f": every image was dropped for lack of a partner ({dropped.get('color', 0)} color, "
            f"{dropped.get('depth', 0)} depth); the streams' stamps differ by more than the "
            f"pairing tolerance: record depth only (--depth-only on the command line, {option} "
            "in Python) or pass a larger pairing tolerance (--max-difference 150ms on the "
            "command line, max_difference= in nanoseconds in Python)"
        )
    return InputError(f"{str(source.path)!r} gave no frames{why}")


def _check_not_all_dropped(frames: Any, count: int) -> None:
    """Raise :func:`no_frames_error` when a source gave no frame because pairing dropped every
    image (a source that holds no frame at all is no error here)."""
    if count == 0 and isinstance(frames, Source):
        dropped = frames.describe().get("dropped")
        if isinstance(dropped, dict) and any(dropped.values()):
            raise no_frames_error(frames)
