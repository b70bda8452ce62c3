"""The :class:`Source` protocol: what yields timestamped RGB-D frames (and the input's other
messages a recording keeps as they came, :meth:`Source.items`), knowing its camera (for
unregistered sensors the color camera and depth-to-color transform too) and depth scale.
Folders, ROS bags and camera files implement it; the writer takes it through one path
(:meth:`pcdcodec.RecordingWriter.write_source`). :func:`open_source` picks the reader from the
path's content (magic bytes, folder layout), never its name. Readers register themselves
(:func:`register_source`); this module imports none (:mod:`pcdcodec.sources` loads them).
"""

from __future__ import annotations

import abc
import os
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InputError, PcdcodecError

if TYPE_CHECKING:
    from ..frame import Frame
    from ..geometry.camera import CameraIntrinsics
    from ..ros.kept import KeptMessage, KeptTopic
    from .camera_rule import CameraDefaults, settle_camera

__all__ = [
    "CameraDefaults",
    "FrameIndex",
    "InputStream",
    "Source",
    "SourceKind",
    "detect_kind",
    "name_input",
    "open_source",
    "register_source",
    "settle_camera",
    "source_kind",
    "source_kinds",
    "streams_by_name",
]


@dataclass(frozen=True, eq=False)
class FrameIndex:
    """Where each frame of a source is, so that a stretch of frames can be read on its own.

    ``rows`` is an N × K int64 array, one row per frame in the order the source yields them:
    column 0 is the frame's timestamp (ns), the other columns say where the source finds the
    frame (for a bag: the log time and header stamp of each message the frame is made of).
    ``first`` is the number of the frame in row 0. A :meth:`slice` is small and picklable, so
    it can be sent to another process, which reads just those frames with
    :meth:`Source.frames_at` on a source of the same input.
    """

    rows: Any
    first: int = 0

    def __len__(self) -> int:
        return int(self.rows.shape[0])

    @property
    def timestamps(self) -> Any:
        """The frames' timestamps (int64 ns)."""
        return self.rows[:, 0]

    def slice(self, start: int = 0, stop: int | None = None) -> FrameIndex:
        """Frames ``start`` to ``stop`` (exclusive, counted from this index's first row)."""
        n = len(self)
        stop = n if stop is None else min(stop, n)
        start = min(max(start, 0), stop)
        return FrameIndex(self.rows[start:stop].copy(), self.first + start)


@dataclass(frozen=True)
class InputStream:
    """A topic, track or file of an input, as its index or listing states it: ``name`` (the
    topic, the track's title), ``type`` (the message type, the track's kind) and ``count``,
    the messages (or blocks) it holds where the index says so without reading them (``None``
    where only reading them would tell)."""

    name: str
    type: str
    count: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "type": self.type, "messages": self.count}


def streams_by_name(items: Any) -> list[InputStream]:
    """One :class:`InputStream` per name from ``(name, type, count)`` items (a ROS 1 bag has a
    connection per publisher: their counts add up, their types are joined), in name order."""
    found: dict[str, tuple[list[str], int | None]] = {}
    for name, kind, count in items:
        types, total = found.get(name, ([], 0))
        if kind not in types:
            types.append(kind)
        found[name] = types, None if total is None or count is None else total + int(count)
    return [InputStream(n, " | ".join(t), c) for n, (t, c) in sorted(found.items())]


class Source(abc.ABC):
    """Timestamped RGB-D frames with the camera that took them.

    Attributes every source sets:

    * ``path``: where it reads from;
    * ``intrinsics``: the depth camera (``None`` when the source does not know it);
    * ``depth_scale``: depth units per metre of uint16 depth (float32 depth is metres);
    * ``metadata``: strings kept in the recording (device name, serial, topics, ...);
    * ``color_intrinsics`` and ``depth_to_color``: for sensors whose color camera is apart from
      the depth camera, the color camera and the rigid 4 × 4 transform from the depth to the
      color camera frame (both ``None`` when color is registered to depth, the default).
    * ``has_color``: whether frames carry color (``RGBDFrame.color`` is ``None`` otherwise).
    * ``intrinsics_origin`` and ``depth_scale_origin``: where the camera and the depth scale
      came from: ``"input"`` (recorded in the input), a file of the input (``"camera.json"``,
      ``"camera-intrinsics.txt"``), a dataset's convention (``"TUM RGB-D dataset"``),
      ``"given"`` (an option), or the origin of the :class:`CameraDefaults` that filled it in.
    * ``camera_notes``: where :class:`CameraDefaults` contradicted what the input carries.
    * ``fps`` and ``frame_id``: the nominal frame rate and the camera's frame name the input
      records (both ``None`` where it does not say; :func:`pcdcodec.encode` then uses its own
      ``fps`` and the writer's default frame name).
    * :attr:`left_out`: the topics, tracks or files of the input whose content a recording of
      it does not hold (IMU, infrared, device options, ...), as :class:`InputStream` items.
      A reader says what its input holds (:meth:`input_streams`) and which of those it records
      (:meth:`recorded_streams`); every reader reports through these two, and
      :meth:`describe` (so an ``encode`` summary and ``info``) lists what is left out.

    Iterating yields frames one at a time, so a source of any length runs in bounded memory.
    A source is a context manager; :meth:`close` releases files it holds.

    Every :class:`~pcdcodec.PcdcodecError` raised while opening a source, iterating it or
    indexing it names the input: the methods a subclass defines (``__init__``, ``__iter__``,
    ``frames``, ``frames_at``, ``frame_index``, ``encoded_frames``, ``candidates``) and the
    iterators they return put the source's path in front of a message that lacks it, keeping
    the error's class (:func:`name_input`). Readers name the topic, stream or frame themselves.
    """

    path: Path
    intrinsics: CameraIntrinsics | None
    depth_scale: float
    metadata: dict[str, str]
    color_intrinsics: CameraIntrinsics | None = None
    depth_to_color: Any = None
    has_color: bool = True
    intrinsics_origin: str = "input"
    depth_scale_origin: str = "input"
    camera_notes: tuple[str, ...] = ()
    fps: float | None = None
    frame_id: str | None = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for name in _NAMED_METHODS:
            method = cls.__dict__.get(name)
            if callable(method) and not getattr(method, "_names_input", False):
                setattr(cls, name, _naming(method, name))

    @abc.abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        """The frames, in time order."""

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[Frame]:
        """Frames ``start`` to ``stop`` (exclusive), in time order.

        This reads and drops the frames before ``start``; sources that can seek override it, so
        a long input can be encoded in segments without reading it from the top each time.
        """
        import itertools

        return itertools.islice(iter(self), start, stop)

    def frame_index(self) -> FrameIndex | None:
        """An index of the frames for :meth:`frames_at`, or ``None`` for sources that seek by
        frame number on their own (folders) or cannot seek at all.

        Sources whose frame count is not known without reading (bags) build it in one pass
        over the message headers, without decoding images, and keep it.
        """
        return None

    def frames_at(self, index: FrameIndex) -> Iterator[Frame]:
        """The frames an :meth:`frame_index` slice lists, read without reading those before.

        The frames are those that iterating the whole source yields at those positions, with the
        same timestamps and data. Sources without an index read ``frames(first, first + n)``.
        """
        return self.frames(index.first, index.first + len(index))

    def __len__(self) -> int:
        """The number of frames; sources that cannot tell cheaply raise ``TypeError``."""
        raise TypeError(f"{type(self).__name__} does not know its frame count in advance")

    @property
    def frame_count(self) -> int | None:
        """The number of frames, or ``None`` where it is not known before reading."""
        try:
            return len(self)
        except TypeError:
            return None

    def input_streams(self) -> list[InputStream]:
        """Every topic, track or file the input holds, from its index or listing
        (never by reading the messages). Readers override it; the default, no streams,
        is for inputs whose every part a recording holds."""
        return []

    def recorded_streams(self) -> set[str]:
        """The names, among :meth:`input_streams`, of those whose content a recording of this
        source holds: the frames' images, and the topics the camera, the depth scale, the
        poses and the metadata come from."""
        return set()

    @property
    def left_out(self) -> tuple[InputStream, ...]:
        """The input's topics, tracks or files a recording of it does not hold: those of
        :meth:`input_streams` neither recorded nor kept (:meth:`kept_topics`), by name."""
        kept = self.recorded_streams() | {t.topic for t in self.kept_topics()}
        return tuple(s for s in self.input_streams() if s.name not in kept)

    def kept_topics(self) -> list[KeptTopic]:
        """The input's topics a recording keeps as they came (:meth:`kept_messages`): for a
        bag, every topic not made into frames. The default: none."""
        return []

    def kept_messages(self) -> Iterator[KeptMessage]:
        """The messages of :meth:`kept_topics`, in the input's order, bytes as stored."""
        return iter(())

    def items(self) -> Iterator[Frame | KeptMessage]:
        """Frames and kept messages, streamed in time order (a frame at its timestamp, a
        message at its log time): what :meth:`pcdcodec.RecordingWriter.write_source` writes."""
        from ..ros.kept import by_time

        return by_time(iter(self), self.kept_messages())

    def describe(self) -> dict[str, Any]:
        """What an ``encode`` summary prints: the reader, camera, depth scale, and what of the
        input is kept as it came and left out (``kept``, ``left_out``: name, type, messages)."""
        from ..ros.kept import kept_listing

        return {
            "source": type(self).__name__,
            "path": str(self.path),
            "frames": self.frame_count,
            "intrinsics": self.intrinsics.to_dict() if self.intrinsics is not None else None,
            "depth_scale": self.depth_scale,
            "color_intrinsics": self.color_intrinsics and self.color_intrinsics.to_dict(),
            "left_out": [s.to_dict() for s in self.left_out],
            "kept": kept_listing(self.kept_topics(), self.input_streams()),
            "intrinsics_from": self.intrinsics_origin,
            "depth_scale_from": self.depth_scale_origin,
            "camera_notes": list(self.camera_notes),
        }

    def close(self) -> None:  # noqa: B027 - optional hook, most sources hold nothing open
        """Release whatever the source holds open."""

    def __enter__(self) -> Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: Methods of every Source whose errors (and whose iterators' errors) name the input.
_NAMED_METHODS = (
    "__init__",
    "__iter__",
    "frames",
    "frames_at",
    "frame_index",
    "encoded_frames",
    "candidates",
    "items",
    "kept_messages",
)


def name_input(exc: PcdcodecError, path: Any) -> PcdcodecError:
    """Make ``exc`` name the input ``path`` when its message does not already (by full path or
    file name): the message gets the path in front, the class and traceback stay."""
    if path is None:
        return exc
    p = Path(path)
    text = str(exc.args[0]) if exc.args else ""
    if str(p) in text or (p.name and (repr(p.name) in text or f"/{p.name}" in text)):
        return exc
    exc.args = (f"{str(p)!r}: {text}" if text else f"{str(p)!r}", *exc.args[1:])
    return exc


def _where(source: Any, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    path = getattr(source, "path", None)
    if path is None:
        path = args[0] if args else kwargs.get("path")
    return path if isinstance(path, (str, os.PathLike)) else None


def _naming(method: Callable[..., Any], name: str) -> Callable[..., Any]:
    """``method`` with every PcdcodecError it raises naming the source's input; an iterator it
    returns is wrapped, so errors raised while iterating name the input too."""
    import functools

    @functools.wraps(method)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
        try:
            out = method(self, *args, **kwargs)
        except PcdcodecError as exc:
            name_input(exc, _where(self, args, kwargs))
            raise
        if isinstance(out, Iterator) and not isinstance(out, _NamedIterator):
            return _NamedIterator(self, out)
        return out

    wrapper._names_input = True  # type: ignore[attr-defined]
    return wrapper


class _NamedIterator(Iterator[Any]):
    """An iterator whose PcdcodecErrors name the source's input (see :func:`name_input`)."""

    def __init__(self, source: Any, it: Iterator[Any]) -> None:
        self._source = source
        self._it = it

    def __next__(self) -> Any:
        try:
            return next(self._it)
        except PcdcodecError as exc:
            name_input(exc, getattr(self._source, "path", None))
            raise

    def close(self) -> None:
        close = getattr(self._it, "close", None)
        if close is not None:
            close()


@dataclass(frozen=True)
class SourceKind:
    """A registered reader: ``probe(path)`` says from the content whether it reads ``path``.

    ``cameras``, for inputs that may hold several cameras, opens them: ``cameras(path,
    **options)`` gives a :class:`~pcdcodec.sources.rig.CameraInput` per camera and the name of
    the frame their rig poses take points into, or ``None`` for an input of one camera (read
    by ``opener``). :func:`pcdcodec.sources.rig.open_inputs` uses it.

    ``missing(path)``, for a path no probe takes, says what the input lacks when it is nearly
    one of this kind (a folder of color images without its depth), or ``None``; the error of
    :func:`open_source` then says that instead of listing every kind.
    """

    name: str
    probe: Callable[[Path], bool]
    opener: Callable[..., Source]
    description: str = ""
    cameras: Callable[..., Any] | None = None
    missing: Callable[[Path], str | None] | None = None


_KINDS: dict[str, SourceKind] = {}


def register_source(
    name: str,
    probe: Callable[[Path], bool],
    opener: Callable[..., Source],
    description: str = "",
    *,
    first: bool = False,
    cameras: Callable[..., Any] | None = None,
    missing: Callable[[Path], str | None] | None = None,
) -> None:
    """Register a source reader. Probes run in registration order; ``first`` puts this one
    ahead of the others (a more specific reader, such as a RealSense bag, before plain ROS 1).
    ``cameras`` opens the cameras of an input of several, ``missing`` says what a near miss
    lacks (see :class:`SourceKind`)."""
    kind = SourceKind(name, probe, opener, description, cameras, missing)
    _KINDS.pop(name, None)
    if first:
        items = [(name, kind), *_KINDS.items()]
        _KINDS.clear()
        _KINDS.update(items)
    else:
        _KINDS[name] = kind


def source_kinds() -> list[SourceKind]:
    """The registered readers, in the order :func:`open_source` tries them."""
    _load_builtin()
    return list(_KINDS.values())


def source_kind(name: str) -> SourceKind | None:
    """The registered reader called ``name`` (as :func:`detect_kind` names it), or ``None``."""
    _load_builtin()
    return _KINDS.get(name)


def read_magic(path: Path, n: int = 16) -> bytes:
    """The first ``n`` bytes of a file (empty for folders and unreadable files)."""
    try:
        with path.open("rb") as f:
            return f.read(n)
    except OSError:
        return b""


def detect_kind(path: str | os.PathLike[str]) -> str | None:
    """The name of the reader :func:`open_source` would pick for ``path``, or ``None``."""
    _load_builtin()
    p = Path(path)
    if not p.exists():
        return None
    return next((k.name for k in _KINDS.values() if k.probe(p)), None)


def _call(kind: SourceKind, p: Path, options: dict[str, Any]) -> Source:
    try:
        return kind.opener(p, **options)
    except TypeError as exc:
        if "unexpected keyword argument" not in str(exc):
            raise
        raise _NoSuchOptionError(
            f"the {kind.name} reader takes no option {str(exc).rsplit(' ', 1)[-1]} "
            f"(given: {', '.join(sorted(options))})"
        ) from None


class _NoSuchOptionError(InputError):
    """A reader was given an option it does not take."""


def given_intrinsics(value: Any, width: int | None, height: int | None) -> CameraIntrinsics:
    """Deprecated: :func:`pcdcodec.geometry.camera.as_intrinsics` (``value, "intrinsics",
    width, height``) takes every form of camera; this goes in a later release."""
    import warnings

    from ..geometry.camera import as_intrinsics

    warnings.warn(
        "pcdcodec.sources.base.given_intrinsics is deprecated; use "
        "pcdcodec.geometry.camera.as_intrinsics",
        DeprecationWarning,
        stacklevel=2,
    )
    return as_intrinsics(value, "intrinsics", width, height)


def _open(kind: SourceKind, p: Path, options: dict[str, Any]) -> Source:
    source = _call(kind, p, options)
    # A camera or scale passed as a reader option replaces the input's own.
    if options.get("intrinsics") is not None and source.intrinsics_origin == "input":
        source.intrinsics_origin = "given"
    if options.get("depth_scale") is not None and source.depth_scale_origin == "input":
        source.depth_scale_origin = "given"
    return source


def _with_defaults(kind: SourceKind, p: Path, options: dict[str, Any], d: CameraDefaults) -> Source:
    """Open ``p`` with what it carries, and settle its camera with ``d`` (:func:`settle_camera`).

    Where ``d`` replaces or fills in what the reader itself uses while reading (a bag's
    cloud quantised at the depth scale, an intrinsics file sized by the images), the input is
    opened again with ``d``'s values as reader options.
    """
    scale_filled = False
    try:
        source = _open(kind, p, options)
    except InputError as first:
        if d.depth_scale is None or options.get("depth_scale") is not None:
            raise
        # Opening failed, and only the depth scale changes on the second try: when that
        # opens, the scale was what the input lacked.
        try:
            source = _open(kind, p, {**options, "depth_scale": d.depth_scale})
        except InputError:
            raise first from None
        scale_filled = True
    reopen: dict[str, Any] = {}
    if d.override and d.depth_scale is not None and source.depth_scale != d.depth_scale:
        reopen["depth_scale"] = d.depth_scale
    if isinstance(d.intrinsics, (str, os.PathLike)) and (d.override or source.intrinsics is None):
        reopen["intrinsics"] = d.intrinsics  # the reader sizes a bare matrix by its images
    elif d.override and d.intrinsics is not None and source.intrinsics != d.intrinsics:
        reopen["intrinsics"] = d.intrinsics
    from .camera_rule import settle_camera  # loaded when a camera is given, not at import

    if not reopen:
        settle_camera(source, d, scale_filled=scale_filled)
        return source
    own = (
        source.intrinsics,
        source.intrinsics_origin,
        source.depth_scale,
        source.depth_scale_origin,
        source.camera_notes,
    )
    source.close()
    if scale_filled:
        options = {**options, "depth_scale": d.depth_scale}
    try:
        source = _open(kind, p, {**options, **reopen})  # the reader reads with the given values
    except _NoSuchOptionError:
        source = _open(kind, p, options)  # a reader that takes none is given them after
    read = source.intrinsics
    if "intrinsics" in reopen and read is not None and read != own[0]:
        import dataclasses

        d = dataclasses.replace(d, intrinsics=read)  # the file as the reader sized it
    # Settled with the input's own values in place, so that the notes name them; a reader
    # that ignores the options is given the values then.
    (
        source.intrinsics,
        source.intrinsics_origin,
        source.depth_scale,
        source.depth_scale_origin,
        source.camera_notes,
    ) = own
    settle_camera(source, d, scale_filled=scale_filled)
    return source


def open_source(
    path: str | os.PathLike[str],
    *,
    kind: str | None = None,
    defaults: CameraDefaults | None = None,
    **options: Any,
) -> Source:
    """Open any RGB-D input: a folder, a ROS 1 or ROS 2 bag, a camera recording.

    The reader is chosen from the content of ``path`` (``kind`` names one explicitly);
    ``options`` go to that reader (for example topics; ``intrinsics`` and ``depth_scale`` given
    as reader options replace what the input says, as the reader is told). ``defaults``
    (:class:`CameraDefaults`) is how commands give a camera: the input's own camera and depth
    scale win, the defaults fill in only what the input lacks, a contradiction is said in the
    source's ``camera_notes``, and ``CameraDefaults(..., override=True)`` replaces the input's
    own, saying so (:func:`settle_camera`). Raises :class:`~pcdcodec.InputError` when
    ``path`` does not exist, no reader knows it, or ``depth_scale`` is not a positive finite
    number.
    """
    _load_builtin()
    p = Path(path)
    if not p.exists():
        raise InputError(f"{str(p)!r} does not exist")
    if options.get("depth_scale") is not None:
        from .._validate import check_depth_scale

        options["depth_scale"] = check_depth_scale(options["depth_scale"])  # every reader alike
    if kind is not None:
        if kind not in _KINDS:
            raise InputError(f"unknown source kind {kind!r}; known: {', '.join(_KINDS)}")
        found: SourceKind | None = _KINDS[kind]
    else:
        found = next((k for k in _KINDS.values() if k.probe(p)), None)
        if found is None and options.get("depth_pattern") is not None and p.is_dir():
            found = _KINDS.get("folder")  # files named as the caller says, not as probed
    if found is not None:
        try:
            if defaults is not None:
                return _with_defaults(found, p, options, defaults)
            return _open(found, p, options)
        except _NoSuchOptionError as exc:  # the reader's own words, as a public error
            raise InputError(f"{str(p)!r}: {exc}") from None
    for k in _KINDS.values():
        lacks = k.missing(p) if k.missing is not None else None
        if lacks:
            raise InputError(f"{str(p)!r} {lacks}")
    raise InputError(
        f"{str(p)!r} is not an input pcdcodec reads; expected one of: "
        + "; ".join(f"{k.name} ({k.description})" for k in _KINDS.values())
    )


def __getattr__(name: str) -> Any:
    # The camera rule's names, served from their module on first use (import pcdcodec stays light).
    if name in ("CameraDefaults", "settle_camera"):
        from . import camera_rule

        return getattr(camera_rule, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: Loaders of readers that register themselves when imported, run before the registry is first
#: consulted. :mod:`pcdcodec.sources` adds the built-in readers' here, so that importing the
#: package loads none of them and this module imports no reader.
_LOADERS: list[Callable[[], None]] = []


_LOADING = threading.RLock()  # re-entrant: a reader's import may consult the registry


def _load_builtin() -> None:
    # One thread runs the loaders; another using the registry meanwhile waits for them to end.
    with _LOADING:
        while _LOADERS:
            _LOADERS.pop(0)()  # taken off first: a reader's probe may consult the registry
