"""Color as whole video files through OpenCV: ``cv2.VideoWriter`` and ``cv2.VideoCapture``.

This backend reproduces the color path of the published compressed RGB-D point cloud streams
method for ROS, which wrote color with ``cv2.VideoWriter`` (FFV1, HuffYUV, MJPEG, MPEG-4 and
H.264) and read it back with ``cv2.VideoCapture``. OpenCV works on files, not packets, so this is
a :class:`~pcdcodec.color.base.FileVideoCodec` (whose interface is in :mod:`.base`):
:meth:`~FileVideoCodec.writer` writes a file frame by frame and :meth:`~FileVideoCodec.reader`
reads one back. For new recordings prefer the packet codecs of
:mod:`pcdcodec.color.pyav`; this one exists to compare against the paper.

Limitations, measured with the pip ``opencv-python-headless`` 5.0 wheel
(``docs/opencv-backend.md``):

* A file carries only a frame rate: frame ``i`` is shown at ``i / fps``. Irregular timestamps
  (dropped frames, jitter) are not kept. The packet codecs keep every timestamp.
* Width and height must be even: OpenCV's FFmpeg writer silently drops the last row or column of
  odd sizes, for every fourcc, the lossless ones included, so odd sizes are refused.
* H.264 (``avc1``) does not open: the wheel's FFmpeg has no H.264 encoder. Use PyAV's ``h264``.
* Only ``FFV1`` and ``HFYU`` are lossless. OpenCV stores them as BGR (``bgra`` and ``bgr0``), so
  they are bit-exact; ``MJPG`` goes through full-range 4:2:0 YUV and ``mp4v``/``XVID`` (both
  FFmpeg's ``mpeg4`` encoder) through limited-range 4:2:0 YUV, at a bitrate OpenCV picks.

OpenCV is used through its FFmpeg backend only (``cv2.CAP_FFMPEG``), so the same fourcc always
gives the same file whichever other video backends the OpenCV build has.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from ..errors import CodecUnavailableError, DecodeError, InputError, InputTypeError
from .base import FileVideoCodec, PathArg, VideoFileReader, VideoFileWriter

__all__ = [
    "CONTAINERS",
    "FOURCCS",
    "LOSSLESS_FOURCCS",
    "FileVideoCodec",
    "OpenCVVideo",
    "VideoFileReader",
    "VideoFileWriter",
]

#: The fourccs the paper tested: each one's default container and the PyAV codec doing the same.
FOURCCS: dict[str, tuple[str, str]] = {
    "MJPG": (".avi", "mjpeg"),
    "FFV1": (".avi", "ffv1"),
    "HFYU": (".avi", "huffyuv"),
    "mp4v": (".mp4", "mpeg4"),
    "XVID": (".avi", "mpeg4"),
    "avc1": (".mp4", "h264"),
}
#: Fourccs whose files give back exactly the RGB bytes written (checked on noise and real frames).
LOSSLESS_FOURCCS: frozenset[str] = frozenset({"FFV1", "HFYU"})
#: File extensions (containers) the writer may use. Matroska holds the most codecs.
CONTAINERS: tuple[str, ...] = (".avi", ".mkv", ".mp4", ".mov")
#: Container for a fourcc not in :data:`FOURCCS`.
_FALLBACK_CONTAINER = ".mkv"
_INSTALL = "install OpenCV with FFmpeg video I/O (pip install opencv-python-headless)"


@functools.cache
def _cv2_reason() -> str | None:
    if importlib.util.find_spec("cv2") is None:
        return "OpenCV (cv2) is not installed"
    try:
        import cv2
    except Exception as exc:  # a broken install, e.g. a missing system library
        return f"cv2 does not import: {exc}"
    if not cv2.videoio_registry.hasBackend(cv2.CAP_FFMPEG):
        return "this OpenCV build has no FFmpeg video I/O backend"
    return None


def _check_fourcc(fourcc: Any) -> str:
    if not isinstance(fourcc, str):
        raise InputTypeError(f"fourcc must be a 4-character string, got {type(fourcc).__name__}")
    if len(fourcc) != 4 or not all(" " <= c <= "~" for c in fourcc):
        raise InputError(f"fourcc must be 4 printable ASCII characters, got {fourcc!r}")
    return fourcc


def _fourcc_code(fourcc: str) -> int:
    return sum(ord(c) << (8 * i) for i, c in enumerate(fourcc))


def _check_container(container: Any) -> None:
    if container is not None and container not in CONTAINERS:
        raise InputError(f"container must be one of {list(CONTAINERS)} or None, got {container!r}")


def _default_container(fourcc: str) -> str:
    return FOURCCS[fourcc][0] if fourcc in FOURCCS else _FALLBACK_CONTAINER


@functools.cache
def _probe(fourcc: str, suffix: str) -> bool:
    """Whether OpenCV writes ``fourcc`` into a ``suffix`` file and reads it back; tried once."""
    if _cv2_reason() is not None:
        return False
    import cv2

    frame = np.zeros((48, 64, 3), np.uint8)
    frame[::2, ::3] = (30, 160, 250)
    with tempfile.TemporaryDirectory(prefix="pcdcodec-cv2-") as tmp:
        path = str(Path(tmp) / f"probe{suffix}")
        try:
            writer = cv2.VideoWriter(path, cv2.CAP_FFMPEG, _fourcc_code(fourcc), 30.0, (64, 48))
            if not writer.isOpened():
                return False
            writer.write(frame)
            writer.write(frame)
            writer.release()
            cap = cv2.VideoCapture(path, cv2.CAP_FFMPEG)
            count = 0
            while cap.grab():
                count += 1
            cap.release()
        except cv2.error:
            return False
    return count == 2


class _Lossless:
    """``lossless`` per instance (it depends on the fourcc); ``False`` on the class, which as a
    whole promises nothing."""

    def __get__(self, obj: OpenCVVideo | None, owner: type[Any]) -> bool:
        return obj is not None and obj.fourcc in LOSSLESS_FOURCCS


class OpenCVVideo(FileVideoCodec):
    """Color video files written by ``cv2.VideoWriter`` and read by ``cv2.VideoCapture``.

    ``fourcc`` is the four-character code handed to OpenCV: one of :data:`FOURCCS` (``MJPG``,
    ``FFV1``, ``HFYU``, ``mp4v``, ``XVID``, ``avc1``), or any other code this OpenCV build can
    write (checked by writing a tiny file). ``container`` is the file extension, one of
    :data:`CONTAINERS`; ``None`` picks ``.avi`` for MJPG, FFV1, HFYU and XVID, ``.mp4`` for mp4v
    and avc1, and ``.mkv`` for other fourccs.

    :attr:`lossless` is true for FFV1 and HFYU only. OpenCV picks the bitrate of the lossy
    fourccs itself; there is no quality setting. See the module docstring for the limitations.
    """

    name: ClassVar[str] = "opencv"
    install_hint: ClassVar[str] = _INSTALL
    lossless = _Lossless()

    def __init__(self, *, fourcc: str = "MJPG", container: str | None = None) -> None:
        _check_fourcc(fourcc)
        _check_container(container)
        self.fourcc, self.container = fourcc, container
        if fourcc not in FOURCCS:
            self._require_available()
            if not _probe(fourcc, self.suffix):
                hint = ""
                if fourcc.upper() in ("H264", "X264", "AVC1"):
                    hint = "; for H.264 use the PyAV color codec 'h264'"
                raise InputError(
                    f"fourcc {fourcc!r} is not one of {list(FOURCCS)} and this OpenCV build "
                    f"cannot write it into a {self.suffix} file{hint}"
                )

    @classmethod
    def unavailable_reason(cls) -> str | None:
        return _cv2_reason()

    @classmethod
    def fourcc_available(cls, fourcc: str, container: str | None = None) -> bool:
        """Whether this OpenCV build writes and reads ``fourcc`` (in ``container``, by default
        the fourcc's own). Found out once per pair by writing a tiny file to a temporary folder."""
        _check_fourcc(fourcc)
        _check_container(container)
        return _probe(fourcc, container or _default_container(fourcc))

    @classmethod
    def available_fourccs(cls) -> tuple[str, ...]:
        """The fourccs of :data:`FOURCCS` that open here in their default container."""
        return tuple(f for f in FOURCCS if cls.fourcc_available(f))

    @property
    def suffix(self) -> str:
        return self.container or _default_container(self.fourcc)

    def _target(self, path: PathArg) -> Path:
        if not isinstance(path, (str, os.PathLike)):
            raise InputTypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
        target = Path(path)
        if not target.suffix:
            return target.with_name(target.name + self.suffix)
        if target.suffix.lower() != self.suffix:
            raise InputError(
                f"path {str(target)!r} ends in {target.suffix!r}, but this codec writes "
                f"{self.suffix} files; use a {self.suffix} path or pass container= to the codec"
            )
        return target

    def writer(
        self, path: PathArg, width: int, height: int, fps: float = 30.0, *, overwrite: bool = False
    ) -> VideoFileWriter:
        """Start writing ``width`` × ``height`` RGB frames at ``fps`` frames/s into ``path``.

        A path without an extension gets :attr:`suffix`. The file is written next to ``path``
        under a temporary name and moved into place by :meth:`VideoFileWriter.close`.

        Raises :class:`~pcdcodec.InputError` when ``path`` exists (unless ``overwrite``), when
        its folder does not exist, or for odd sizes (OpenCV would drop a row or column), and
        :class:`~pcdcodec.CodecUnavailableError` when OpenCV cannot write the fourcc here.
        """
        self._require_available()
        target = self._target(path)
        return _OpenCVWriter(self, target, width, height, fps, overwrite=overwrite)

    def reader(self, path: PathArg) -> VideoFileReader:
        """Open a video file for reading as RGB frames.

        Raises :class:`~pcdcodec.InputError` when ``path`` does not exist or is a folder, and
        :class:`~pcdcodec.DecodeError` when it is not a video OpenCV can read.
        """
        self._require_available()
        if not isinstance(path, (str, os.PathLike)):
            raise InputTypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
        return _OpenCVReader(self, Path(path))

    def _unavailable(self, suffix: str) -> CodecUnavailableError:
        import cv2

        default = _default_container(self.fourcc)
        start = f"OpenCV's VideoWriter did not open fourcc {self.fourcc!r} into a {suffix} file"
        if suffix != default and _probe(self.fourcc, default):
            return CodecUnavailableError(
                f"{start}: a {suffix} file cannot hold it here; pass container={default!r} "
                "(or None) to the codec"
            )
        why = f"this OpenCV build ({cv2.__version__}) cannot write it"
        if self.fourcc == "avc1":
            why += " (the pip opencv-python wheels have no usable H.264 encoder)"
        pyav = FOURCCS.get(self.fourcc, ("", "h264"))[1]
        return CodecUnavailableError(
            f"{start}: {why}; use the PyAV color codec {pyav!r} (pcdcodec.get_codec({pyav!r})) "
            "instead"
        )


class _OpenCVWriter(VideoFileWriter):
    codec: OpenCVVideo

    def __init__(
        self,
        codec: OpenCVVideo,
        path: Path,
        width: int,
        height: int,
        fps: float,
        *,
        overwrite: bool,
    ) -> None:
        import cv2

        super().__init__(codec, path, width, height, fps)
        if self.width % 2 or self.height % 2:
            raise InputError(
                f"OpenCV video needs an even width and height, got {self.width}x{self.height} "
                "(OpenCV's FFmpeg writer would silently drop the last row or column); crop or "
                "pad the frames, or use a PyAV color codec, which pads and crops back"
            )
        self._overwrite = overwrite
        self._check_target()
        if not path.parent.is_dir():
            raise InputError(f"folder {str(path.parent)!r} of {str(path)!r} does not exist")
        # Written under a temporary name in the same folder (so the final move is a rename);
        # the name keeps the extension, from which FFmpeg picks the container.
        from .._atomic import partial_path  # not loaded by `import pcdcodec`

        self._tmp = partial_path(path, unique=True, suffix=codec.suffix)
        self._tmp.touch(exist_ok=False)
        tmp = str(self._tmp)
        try:
            writer = cv2.VideoWriter(
                tmp, cv2.CAP_FFMPEG, _fourcc_code(codec.fourcc), self.fps, (self.width, self.height)
            )
            opened = writer.isOpened()
        except cv2.error as exc:
            self._tmp.unlink(missing_ok=True)
            raise InputError(f"OpenCV could not start writing {str(path)!r}: {exc}") from exc
        if not opened:
            writer.release()
            self._tmp.unlink(missing_ok=True)
            raise codec._unavailable(codec.suffix)
        self._writer = writer

    def _check_target(self) -> None:
        if self.path.is_dir():
            raise InputError(f"{str(self.path)!r} is a folder, not a video file path")
        if self.path.exists() and not self._overwrite:
            raise InputError(
                f"{str(self.path)!r} already exists; pass overwrite=True to replace it"
            )

    def _write(self, rgb: npt.NDArray[np.uint8]) -> None:
        import cv2

        try:
            self._writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        except cv2.error as exc:
            self.abort()
            raise InputError(f"OpenCV could not write frame {self.frames_written}: {exc}") from exc

    def _abort(self) -> None:
        self._writer.release()
        self._tmp.unlink(missing_ok=True)

    def _close(self) -> None:
        import cv2

        self._writer.release()
        try:
            if self.frames_written == 0:
                raise InputError(f"no frames were written; nothing was saved to {str(self.path)!r}")
            # VideoWriter.write reports no errors (a full disk, say), so the file is read back.
            cap = cv2.VideoCapture(str(self._tmp), cv2.CAP_FFMPEG)
            declared = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else -1
            cap.release()
            if declared != self.frames_written:
                raise DecodeError(
                    f"OpenCV wrote {str(self.path)!r} with {declared:.0f} frames readable of the "
                    f"{self.frames_written} given; the file was discarded"
                )
            self._check_target()
            os.replace(self._tmp, self.path)
        finally:
            self._tmp.unlink(missing_ok=True)


class _OpenCVReader(VideoFileReader):
    codec: OpenCVVideo

    def __init__(self, codec: OpenCVVideo, path: Path) -> None:
        import cv2

        super().__init__(codec, path)
        if not path.exists():
            raise InputError(f"video file {str(path)!r} does not exist")
        if path.is_dir():
            raise InputError(f"{str(path)!r} is a folder, not a video file")
        cap = self._open()
        self._width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        self._height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self._fps = float(cap.get(cv2.CAP_PROP_FPS))
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        if self._width <= 0 or self._height <= 0:
            cap.release()
            raise DecodeError(f"{str(path)!r} has no video stream OpenCV can read")
        # The frame count comes from the container's index (AVI, MP4, MOV) or, for Matroska,
        # from duration x frame rate; both were exact on every file this writer made. Where it
        # is missing (a still image read as video, say) the frames are counted when asked.
        self._declared: int | None = int(count) if math.isfinite(count) and count > 0 else None
        self._counted: int | None = None
        self._cap: Any = cap
        self._open_caps: list[Any] = []

    def _open(self) -> Any:
        import cv2

        try:
            cap = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
            opened = cap.isOpened()
        except cv2.error as exc:
            raise DecodeError(f"OpenCV could not open {str(self.path)!r}: {exc}") from exc
        if not opened:
            cap.release()
            raise DecodeError(f"{str(self.path)!r} is not a video file OpenCV can read")
        return cap

    def _take(self) -> Any:
        cap, self._cap = self._cap, None
        return cap if cap is not None else self._open()

    @property
    def width(self) -> int:
        return self._width

    @property
    def height(self) -> int:
        return self._height

    @property
    def fps(self) -> float:
        return self._fps

    def __len__(self) -> int:
        if self._declared is not None:
            return self._declared
        if self._counted is None:
            cap = self._open()
            count = 0
            try:
                while cap.grab():
                    count += 1
            finally:
                cap.release()
            self._counted = count
        return self._counted

    def __iter__(self) -> Iterator[npt.NDArray[np.uint8]]:
        import cv2

        cap = self._take()
        self._open_caps.append(cap)
        where = str(self.path)
        n = 0
        try:
            while True:
                try:
                    ok, bgr = cap.read()
                except cv2.error as exc:
                    raise DecodeError(
                        f"OpenCV could not decode frame {n} of {where!r}: {exc}"
                    ) from exc
                if not ok:
                    break
                if bgr is None or bgr.dtype != np.uint8 or bgr.shape != (*self.shape, 3):
                    got = None if bgr is None else (bgr.shape, str(bgr.dtype))
                    raise DecodeError(
                        f"frame {n} of {where!r} decoded as {got}, expected "
                        f"{(*self.shape, 3)} uint8"
                    )
                n += 1
                rgb: npt.NDArray[np.uint8] = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                yield rgb
        finally:
            cap.release()
            with contextlib.suppress(ValueError):
                self._open_caps.remove(cap)
        if self._declared is not None and n != self._declared:
            raise DecodeError(
                f"{where!r} declares {self._declared} frames, but {n} could be decoded "
                "(truncated or damaged file)"
            )

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of the frames."""
        return self._height, self._width

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        for cap in self._open_caps:
            cap.release()
        self._open_caps.clear()
