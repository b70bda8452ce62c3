"""PyTorch datasets over recordings: :class:`RecordingDataset` (map-style, random access) and
:class:`IterableRecordingDataset` (in order, split between DataLoader workers).

Both pickle as paths and settings and open their recordings lazily, once per process, so they
work in a ``DataLoader`` with worker processes, forked or spawned (``docs/learning.md``).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
from torch.utils.data import Dataset, IterableDataset, get_worker_info

from ..errors import InputError, InputTypeError, PcdcodecWarning
from ..recording.framesets import match_times
from .catalog import Readers, find_recordings
from .items import COLOR_FIELDS, DEFAULT_FIELDS, Decoded, build_item, check_fields

__all__ = ["TRAINING_COLOR", "IterableRecordingDataset", "RecordingDataset"]

#: The color codec to record training data with (``pcdcodec.open(..., color=TRAINING_COLOR)``):
#: AV1 with every frame a keyframe, so that a random frame costs what a frame read in order
#: costs, and dav1d decodes it faster than a color PNG file is read. ``crf`` 52 of SVT-AV1's
#: low-delay mode (which holds no frame back) keeps color at 33–37 dB PSNR on the measured
#: 640×480 sensors, small enough that color and lossless depth together take under a tenth of
#: a color and a depth PNG file; preset 8 encodes about 2.4× faster than preset 6 for 1–2 %
#: more bytes (``docs/learning.md``, measured on every set, with the trade-offs).
TRAINING_COLOR: dict[str, Any] = {
    "id": "av1",
    "gop": 1,
    "crf": 52,
    "preset": 8,
    "low_delay": True,
}

#: Recordings a process keeps open at once, by default.
MAX_OPEN = 32

_NS = 1_000_000_000


def _tensors(value: Any) -> Any:
    """``value`` with every numpy array (also inside dicts) turned into a torch tensor."""
    if isinstance(value, np.ndarray):
        return torch.from_numpy(value if value.flags.writeable else value.copy())
    if isinstance(value, dict):
        return {k: _tensors(v) for k, v in value.items()}
    return value


def _check_cameras(cameras: Any) -> tuple[str, ...]:
    """``cameras`` as a tuple of camera names, each once."""
    try:
        names = tuple(cameras) if not isinstance(cameras, str) else None
    except TypeError:
        names = None
    if names is None or not all(isinstance(c, str) for c in names):
        raise InputTypeError(f"cameras must be a list of camera names, got {cameras!r}")
    if not names:
        raise InputError("cameras is empty: leave it out for every camera")
    if len(set(names)) != len(names):
        raise InputError(f"cameras names a camera twice: {list(names)}")
    return names


def _check_threads(threads: Any) -> int | None:
    if threads is not None and (
        isinstance(threads, bool) or not isinstance(threads, int) or not 0 <= threads <= 256
    ):
        raise InputError(f"threads must be None or an int in 0..256, got {threads!r}")
    return threads


class RecordingDataset(Dataset[Any]):
    """A map-style dataset over the frames of one or many recordings.

    ``recordings`` is a ``.pcdc`` path, a folder (every ``.pcdc`` in it, recursively, sorted),
    a glob pattern, or a list of these. Item ``i`` is a ``dict`` of ``fields`` (names from
    :data:`pcdcodec.torch.FIELDS`; default ``("color", "depth")``) for the ``i``-th frame,
    counting the recordings in order and, in a recording of several cameras, camera after
    camera (``cameras`` picks some, in the order given).

    ``framesets=True`` makes an item one set of frames of the cameras matched by time (as
    :meth:`pcdcodec.RigRecording.framesets` matches them: a frame of each other camera within
    ``tolerance`` seconds, by default half the first camera's frame interval): a ``dict`` of
    camera name to that camera's fields. Sets missing a camera are left out.

    ``dataset[i]`` decodes the frame's depth, and its color from the keyframe before it (the
    recording's ``gop`` bounds how far back that is); fields without color skip the color
    stream altogether. ``tensors=True`` turns arrays into ``torch`` tensors (sharing memory);
    ``transform``, if given, is applied to the item last and its result returned. ``threads``
    is the decoder threads of each reader (``1``, the default, suits one worker per core);
    ``max_open`` bounds the recordings a process keeps open.

    Frames that ``pcdcodec recover`` kept without their color (``Recording.color_missing``)
    have no item with a color field: such a recording is refused when the dataset is made
    (:class:`~pcdcodec.InputError` naming the file, the camera and the frames), unless
    ``skip_missing_color=True``, which leaves those frames (and frame sets holding one) out and
    says how many, in :attr:`skipped` and a :class:`~pcdcodec.PcdcodecWarning`. Fields
    without color read every frame.
    """

    def __init__(
        self,
        recordings: Any,
        fields: Any = DEFAULT_FIELDS,
        *,
        cameras: list[str] | tuple[str, ...] | None = None,
        framesets: bool = False,
        tolerance: float | None = None,
        transform: Callable[[Any], Any] | None = None,
        tensors: bool = False,
        threads: int | None = 1,
        max_open: int = MAX_OPEN,
        skip_missing_color: bool = False,
    ) -> None:
        self.fields = check_fields(fields)
        if not isinstance(skip_missing_color, bool):
            raise InputTypeError(
                f"skip_missing_color must be True or False, got {skip_missing_color!r}"
            )
        if transform is not None and not callable(transform):
            raise InputTypeError(f"transform must be callable, got {type(transform).__name__}")
        if isinstance(max_open, bool) or not isinstance(max_open, int) or max_open < 1:
            raise InputError(f"max_open must be an int >= 1, got {max_open!r}")
        if cameras is not None:
            cameras = _check_cameras(cameras)
        if tolerance is not None and (
            isinstance(tolerance, bool)
            or not isinstance(tolerance, (int, float))
            or not 0 <= tolerance < 1e6
        ):
            raise InputError(f"tolerance must be a number of seconds >= 0, got {tolerance!r}")
        self.transform = transform
        self.tensors = bool(tensors)
        self.framesets = bool(framesets)
        self.tolerance = tolerance
        self._readers = Readers(_check_threads(threads), max_open)
        self._color = bool(COLOR_FIELDS & set(self.fields))
        self._pose = "pose" in self.fields
        self.skip_missing_color = skip_missing_color and self._color
        self.sources = [str(p) for p in find_recordings(recordings)]
        #: per part (a camera's frames, or a recording's frame sets): source, cameras, items
        self.parts: list[tuple[str, tuple[str, ...], int]] = []
        #: Items left out for lack of color (``skip_missing_color``), by recording: frames, or
        #: frame sets holding such a frame.
        self.skipped: dict[str, int] = {}
        self._sets: dict[str, npt.NDArray[np.int64]] = {}
        self._kept: dict[tuple[str, str], npt.NDArray[np.int64] | None] = {}
        try:
            self._catalog(None if cameras is None else tuple(cameras))
        finally:
            self._readers.close()  # nothing stays open in the process that made the dataset
        if self.skipped:
            warnings.warn(
                f"{sum(self.skipped.values())} item(s) left out: their frames were kept by "
                "`pcdcodec recover` without their color ("
                + ", ".join(f"{n} of {s!r}" for s, n in self.skipped.items())
                + ")",
                PcdcodecWarning,
                stacklevel=2,
            )
        counts = np.array([n for _, _, n in self.parts], np.int64)
        self._starts: npt.NDArray[np.int64] = np.concatenate([[0], np.cumsum(counts)])
        if not len(self) and self.skipped:
            raise InputError(
                f"no item left in {self.sources}: every frame asked for was kept by `pcdcodec "
                "recover` without its color; ask for fields without color"
            )
        if not len(self):  # a sampler would fail later, saying nothing of why
            raise InputError(
                f"no complete frame set in {self.sources}: in each, some camera of "
                f"{[list(c) for _, c, _ in self.parts]} has no frame within the tolerance of "
                "the first camera's"
                if self.framesets
                else f"the recordings {self.sources} hold no frame"
            )
        self._sets.clear()  # rebuilt where read: they are not worth pickling
        self._kept.clear()

    def _catalog(self, wanted: tuple[str, ...] | None) -> None:
        found: set[str] = set()
        every: set[str] = set()
        for source in self.sources:
            rec = self._readers.recording(source)
            names = list(rec.camera_names)
            every.update(names)
            chosen = names if wanted is None else [c for c in wanted if c in names]
            found.update(chosen)
            if self.framesets and wanted is not None and len(chosen) != len(wanted):
                missing = [c for c in wanted if c not in names]
                raise InputError(
                    f"{source!r} has no camera {missing[0]!r} (its cameras: {names}); frame "
                    "sets need every camera asked for in every recording"
                )
            for name in chosen:
                cam = self._readers.camera(source, name)
                if self._color and not cam.has_color:
                    raise InputError(
                        f"{source!r}: camera {name!r} was recorded without color, and fields "
                        f"{list(self.fields)} ask for it"
                    )
                if self._color and not self.skip_missing_color:
                    self._refuse_missing_color(source, name, cam.recording.color_missing)
            if self.framesets:
                if chosen:
                    sets = len(self._matches(source, chosen))
                    self.parts.append((source, tuple(chosen), sets))
                    if self.skip_missing_color:
                        left = len(self._matches(source, chosen, every=True)) - sets
                        self._count_skipped(source, left)
            else:
                for name in chosen:
                    frames = len(self._readers.camera(source, name).timestamps)
                    kept = self._kept_frames(source, name)
                    self.parts.append((source, (name,), frames if kept is None else len(kept)))
                    self._count_skipped(source, 0 if kept is None else frames - len(kept))
        if wanted is not None:
            absent = [c for c in wanted if c not in found]
            if absent:
                raise InputError(
                    f"no recording has camera {absent[0]!r}; their cameras are {sorted(every)}"
                )

    def _refuse_missing_color(self, source: str, camera: str, lost: list[int]) -> None:
        if not lost:
            return
        shown = ", ".join(str(i) for i in lost[:8]) + (", ..." if len(lost) > 8 else "")
        raise InputError(
            f"{source!r}: camera {camera!r} holds {len(lost)} frame(s) that `pcdcodec recover` "
            f"kept without their color, lost to damage (frames {shown}), and fields "
            f"{list(self.fields)} ask for color: pass skip_missing_color=True to leave those "
            "frames out, or ask for fields without color"
        )

    def _count_skipped(self, source: str, left: int) -> None:
        if left:
            self.skipped[source] = self.skipped.get(source, 0) + left

    def _kept_frames(self, source: str, camera: str) -> npt.NDArray[np.int64] | None:
        """The frames of ``camera`` in ``source`` that items are made of, where
        ``skip_missing_color`` leaves some out; ``None`` for every frame."""
        key = (source, camera)
        if key in self._kept:
            return self._kept[key]
        kept = None
        if self.skip_missing_color:
            cam = self._readers.camera(source, camera)
            lost = cam.recording.color_missing
            if lost:
                every = np.arange(len(cam.timestamps), dtype=np.int64)
                kept = np.setdiff1d(every, np.asarray(lost, np.int64))
        self._kept[key] = kept
        return kept

    def _matches(
        self, source: str, cameras: tuple[str, ...] | list[str], every: bool = False
    ) -> npt.NDArray[np.int64]:
        """The complete frame sets of ``cameras`` in ``source``: sets × cameras frame indexes;
        with ``skip_missing_color``, those without a frame that lacks its color (unless
        ``every``)."""
        got = self._sets.get(source)
        if got is not None and not every:
            return got
        times = [self._readers.camera(source, c).timestamps for c in cameras]
        ref = self._readers.camera(source, cameras[0]).recording
        tolerance = self.tolerance if self.tolerance is not None else 0.5 / ref.fps
        tol = round(tolerance * _NS)
        columns = [np.arange(len(times[0]), dtype=np.int64)]
        columns += [match_times(times[0], t, tol) for t in times[1:]]
        matches = np.stack(columns, axis=1)
        matches = matches[(matches >= 0).all(axis=1)]
        if every:
            return matches
        for k, camera in enumerate(cameras):
            kept = self._kept_frames(source, camera)
            if kept is not None:
                matches = matches[np.isin(matches[:, k], kept)]
        self._sets[source] = matches
        return matches

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_sets"] = {}  # rebuilt from the files, in each worker
        state["_kept"] = {}
        return state

    def __len__(self) -> int:
        return int(self._starts[-1])

    def locate(self, i: int) -> tuple[str, tuple[str, ...], int]:
        """Where item ``i`` is: its recording, its camera(s), and its frame (or set) index."""
        part, j = self._where(i)
        source, cameras, _ = self.parts[part]
        return source, cameras, j

    def _where(self, i: int) -> tuple[int, int]:
        """Item ``i``'s part and its frame (or set) index in that part."""
        n = len(self)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise InputTypeError(f"an item index must be an int, got {type(i).__name__}")
        if not -n <= i < n:
            raise IndexError(f"item {i} is out of range for {n} items")
        i = int(i) % n
        part = int(np.searchsorted(self._starts, i, side="right")) - 1
        return part, i - int(self._starts[part])

    def _frame(self, source: str, camera: str, j: int) -> dict[str, Any]:
        cam = self._readers.camera(source, camera)
        rec = cam.recording
        if self._color:
            frame = rec[j]
            color, depth, pose = frame.color, frame.depth, frame.pose
        else:  # no color field: the color stream is never touched
            color, depth = None, rec.depth(j)
            pose = cam.pose(j) if self._pose else None
        decoded = Decoded(
            color,
            depth,
            int(cam.timestamps[j]),
            pose,
            rec.projector,
            cam.rig_pose,
            camera,
            source,
            j,
        )
        return build_item(decoded, self.fields)

    def raw(self, i: int) -> Any:
        """Item ``i`` as numpy arrays, before ``tensors`` and ``transform``."""
        part, j = self._where(i)
        source, cameras, counted = self.parts[part]
        if self.framesets:
            sets = self._matches(source, cameras)
            self._check_count(source, "frame sets", counted, len(sets))
            row = sets[j]
            return {c: self._frame(source, c, int(k)) for c, k in zip(cameras, row, strict=True)}
        frames = len(self._readers.camera(source, cameras[0]).timestamps)
        kept = self._kept_frames(source, cameras[0])
        if kept is not None:
            frames = len(kept)
        self._check_count(source, f"frames of camera {cameras[0]!r}", counted, frames)
        return self._frame(source, cameras[0], j if kept is None else int(kept[j]))

    @staticmethod
    def _check_count(source: str, what: str, counted: int, now: int) -> None:
        # A file rewritten since it was counted: reading past its end would raise IndexError,
        # which ends a plain iteration over the dataset early, without a word.
        if now != counted:
            raise InputError(
                f"{source!r} has {now} {what}, {counted} when the dataset was made: the file "
                "changed since; make the dataset again"
            )

    def __getitem__(self, i: int) -> Any:
        item = self.raw(i)
        if self.tensors:
            item = _tensors(item)
        if self.transform is not None:
            item = self.transform(item)
        return item

    def close(self) -> None:
        """Close the recordings this process opened (they open again when next read)."""
        self._readers.close()

    def __repr__(self) -> str:
        kind = "frame sets" if self.framesets else "frames"
        skipped = sum(self.skipped.values())
        left = f", {skipped} left out without color" if skipped else ""
        return (
            f"<{type(self).__name__}: {len(self)} {kind} of {len(self.sources)} recording(s), "
            f"fields {list(self.fields)}{left}>"
        )


def share(n: int) -> tuple[int, int]:
    """The items ``[start, stop)`` of ``n`` this process reads: all of them outside a
    DataLoader worker, else the worker's contiguous share (the first workers take one more)."""
    info = get_worker_info()
    if info is None:
        return 0, n
    workers, k = int(info.num_workers), int(info.id)
    return n * k // workers, n * (k + 1) // workers


class IterableRecordingDataset(IterableDataset[Any]):
    """The items of a :class:`RecordingDataset` (same arguments), read in order: the fastest
    full pass, since each color packet is decoded once.

    In a ``DataLoader`` with workers, each worker reads a contiguous share of the items (the
    first ``len / num_workers``, the next, ...), so a batch holds consecutive frames of one
    worker and batches come from the workers in turn. Shuffle with :class:`RecordingDataset`
    and a sampler instead.
    """

    def __init__(self, recordings: Any, fields: Any = DEFAULT_FIELDS, **options: Any) -> None:
        #: the map-style dataset whose items this reads in order
        self.dataset = RecordingDataset(recordings, fields, **options)

    def __len__(self) -> int:
        return len(self.dataset)

    def __iter__(self) -> Iterator[Any]:
        start, stop = share(len(self.dataset))
        for i in range(start, stop):
            # rec[j] after rec[j - 1] continues the decoder: one color packet per frame.
            yield self.dataset[i]

    def close(self) -> None:
        """Close the recordings this process opened."""
        self.dataset.close()

    def __repr__(self) -> str:
        return repr(self.dataset).replace("RecordingDataset", type(self).__name__, 1)
