"""Running an archive: :func:`archive` checks its arguments into a
:class:`~pcdcodec.archive.settings.RunSettings`, takes the lock, starts (or joins) the Dask
cluster, submits each input's tasks and keeps the manifest and the summary as they finish."""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import CodecUnavailableError, InputError, PcdcodecError
from .discover import _stat, find_inputs
from .manifest import DONE_STATES, PARTS, _disk_full, _Lock, _Manifest, _prune, _sweep
from .plan import segment_plan
from .settings import (
    RunSettings,
    _camera_defaults,
    _check_counts,
    _input_options,
    _jsonable,
    _writer_options,
)
from .summary import ArchiveItem, ArchiveSummary, _ByteProgress, _take_camera
from .tasks import _encode_segment, _existing_segment, _join_parts, _probe, _verify

__all__ = ["archive"]


def archive(
    sources: Sequence[str | os.PathLike[str]],
    output: str | os.PathLike[str],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    color: Any = "h264",
    depth: Any = DEFAULT_DEPTH_CODEC,
    fps: float = 30.0,
    segment_frames: int | None = None,
    verify: bool = False,
    delete_source_after_verify: bool = False,
    source_options: dict[str, Any] | None = None,
    camera: Any = None,
    input_options: Mapping[Any, dict[str, Any]] | None = None,
    processes: bool = True,
    progress: bool | Callable[[int, int], None] | None = None,
    log: Callable[[str], None] | None = None,
) -> ArchiveSummary:
    """Encode every input under ``sources`` into a ``.pcdc`` file under ``output``.

    ``scheduler`` is the address of a running Dask scheduler (``tcp://host:8786``); without
    it a local cluster of ``workers`` processes (default: one per CPU core) runs the work
    (``processes=False`` makes them threads of this process). ``color`` and ``depth`` are
    codec names, configs or codecs as for :func:`pcdcodec.open`; ``fps`` is the nominal rate.
    Long inputs are cut into segments of at most ``segment_frames`` frames (default: about
    1 GB of source and at least 300 frames; see :func:`segment_plan`), encoded one task each
    and joined. ``verify`` decodes every output and compares it with its source;
    ``delete_source_after_verify`` (implies ``verify``) then deletes each verified source.
    ``source_options`` go to :func:`pcdcodec.open_source` for every input.

    Cameras: an input's own camera and depth scale (recorded in it, in its folder's
    ``camera.json`` or intrinsics file, or its dataset's convention) always win. ``camera``
    fills in only what an input lacks: a preset name
    (:data:`~pcdcodec.geometry.camera.CAMERA_PRESETS`,
    camera and depth scale), a :class:`~pcdcodec.CameraIntrinsics`, or a
    :class:`~pcdcodec.sources.CameraDefaults`; ``intrinsics`` and ``depth_scale`` in
    ``source_options`` are taken the same way. Where it contradicts what an input carries, the
    input's is used, and a warning goes to ``log`` and into the input's ``notes``.
    ``input_options`` maps an input (a path as given or found) to options of its own, which
    go to its reader and replace what the input says (``{"take3": {"intrinsics": cam,
    "depth_scale": 1000.0}}``). The summary lists each input's camera and depth scale and
    where each came from. ``progress`` is
    ``True`` for a progress line on stderr (default: when stderr is a terminal), ``False``
    for none, or a callable given (bytes done, bytes total). ``log`` receives messages (the
    dashboard link); default: printed to stderr when progress is shown.

    Returns an :class:`ArchiveSummary`; inputs that fail are in ``summary.failed`` with their
    error and do not stop the others. Raises :class:`~pcdcodec.ArchiveLockedError` when
    another run holds ``output``, :class:`~pcdcodec.InputError` for bad arguments or inputs
    that cannot be found, and :class:`~pcdcodec.DiskFullError` when not even the manifest can
    be written.
    """
    started = time.perf_counter()
    _check_counts(scheduler, workers, segment_frames)
    verify = verify or delete_source_after_verify
    writer_options, keyframes = _writer_options(color, depth, fps)
    common = dict(source_options or {})
    defaults = _camera_defaults(camera, common)
    settings_all = dict(writer_options)
    if defaults is not None:
        # Another default camera may change what inputs without one record.
        settings_all["camera"] = {
            "intrinsics": defaults.intrinsics.to_dict() if defaults.intrinsics else None,
            "depth_scale": defaults.depth_scale,
        }
        common["defaults"] = defaults

    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    inputs = find_inputs(sources, exclude=out)
    own = _input_options(inputs, input_options)
    options = {rel: {**common, **own.get(rel, {})} for _, rel in inputs}
    recorded = {
        rel: {**settings_all, "input": _jsonable(own[rel])} if rel in own else settings_all
        for _, rel in inputs
    }
    show = sys.stderr.isatty() if progress is None else bool(progress)
    say = log if log is not None else (lambda m: print(m, file=sys.stderr) if show else None)
    warn = log if log is not None else (lambda m: print(m, file=sys.stderr))
    run = RunSettings(
        out=out,
        scheduler=scheduler,
        workers=workers,
        processes=processes,
        options=options,
        recorded=recorded,
        writer_options=writer_options,
        segment_frames=segment_frames,
        keyframes=keyframes,
        verify=verify,
        delete_source=delete_source_after_verify,
        progress=progress if callable(progress) else None,
        show=show,
        say=say,
        warn=warn,
    )

    with _Lock(out):
        _sweep(out)
        try:
            return _archive(inputs, run, started)
        finally:
            # Whatever stopped the run (Ctrl-C included), no half-written file stays behind.
            _sweep(out)
            _prune(out / PARTS)


def _archive(inputs: list[tuple[Path, str]], run: RunSettings, started: float) -> ArchiveSummary:
    """The run under the lock: skip what is done, run the rest on the cluster, summarise."""
    out = run.out
    manifest = _Manifest(out)
    items: dict[str, ArchiveItem] = {}
    todo: list[tuple[Path, str, int, int]] = []
    for path, rel in inputs:
        size, mtime = _stat(path)
        entry = manifest.entries.get(rel, {})
        item = ArchiveItem(str(path), str(out / rel), "pending", bytes_in=size)
        items[rel] = item
        unchanged = (
            size is not None
            and entry.get("size") == size
            and entry.get("mtime_ns") == mtime
            and entry.get("settings") == run.recorded[rel]
            and (out / rel).is_file()
        )
        if unchanged and entry.get("state") in DONE_STATES:
            if run.verify and entry.get("state") == "done":
                todo.append((path, rel, size or 0, mtime))  # encoded before, not yet verified
            else:
                item.state = "skipped"
                item.bytes_out = int(entry.get("bytes_out", 0))
                item.frames = int(entry.get("frames", 0))
                _take_camera(item, entry.get("camera"))
            continue
        todo.append((path, rel, size or 0, mtime))
    total = sum(s for _, _, s, _ in todo)
    bar = _ByteProgress(total, run.show and run.progress is None, sys.stderr)
    bar.inputs = len(todo)

    stopped: str | None = None
    workers_seen = 0
    dashboard: str | None = None
    if todo:
        with _cluster(run.scheduler, run.workers, run.processes) as client:
            dashboard = _dashboard(client)
            workers_seen = len(client.scheduler_info().get("workers", {}))
            run.say(
                f"dashboard: {dashboard}" if dashboard else "dashboard: install bokeh to see it"
            )
            try:
                stopped = _Run(client, run, manifest, items, bar).run(todo)
            finally:
                bar.close()
                manifest.save()
    # The cluster is closed, so no task of a failed input writes any more: its parts go.
    for rel, item in items.items():
        if item.state == "failed":
            shutil.rmtree(out / PARTS / rel, ignore_errors=True)
    if stopped is None and manifest.disk_full is not None:
        stopped = manifest.disk_full
    return ArchiveSummary(
        [items[rel] for _, rel in inputs],
        time.perf_counter() - started,
        workers_seen,
        dashboard,
        stopped,
    )


def _dashboard(client: Any) -> str | None:
    """The link to the cluster's dashboard, or ``None`` without bokeh to draw it."""
    import importlib.util

    if importlib.util.find_spec("bokeh") is None:
        return None  # the dashboard needs bokeh
    link = getattr(client, "dashboard_link", None)
    return str(link) if link else None


@contextlib.contextmanager
def _cluster(scheduler: str | None, workers: int | None, processes: bool) -> Iterator[Any]:
    """A client of the scheduler at ``scheduler``, or of a local cluster started for the run."""
    try:
        import importlib
        import logging

        dist: Any = importlib.import_module("distributed")
    except ImportError as exc:
        raise CodecUnavailableError(
            "pcdcodec archive needs Dask's distributed scheduler: pip install 'pcdcodec[archive]'"
        ) from exc
    if scheduler is not None:
        with dist.Client(scheduler) as client:
            yield client
        return
    n = workers if workers is not None else (os.cpu_count() or 1)
    dask: Any = importlib.import_module("dask")
    with (
        # Dask's worker profiler samples every thread's stack (sys._current_frames) 100 times a
        # second. CPython holds its thread-list lock while doing so, and a garbage collection
        # run inside it that frees an FFmpeg object (which lets go of the GIL to free it)
        # deadlocks against any thread starting at that moment: seen as a hung run with
        # thread workers. The profile is of no use to a run, so its workers go without.
        dask.config.set({"distributed.worker.profile.enabled": False}),
        dist.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=processes,
            dashboard_address=":0",
            # A failing input is reported in the summary with its error; the workers' own
            # log lines and tracebacks for it would only repeat it on stderr.
            silence_logs=logging.CRITICAL,
        ) as cluster,
        dist.Client(cluster) as client,
    ):
        yield client


@dataclass
class _Job:
    """One input on its way through the run: its segments and what they gave."""

    path: Path
    rel: str
    size: int
    mtime: int
    parts: list[Path] = field(default_factory=list)
    plan: list[tuple[int, int | None]] = field(default_factory=list)
    remaining: int = 0
    colors: dict[int, list[str]] = field(default_factory=dict)
    frames: int = 0
    futures: list[Any] = field(default_factory=list)
    retried_whole: bool = False


class _Run:
    """The client's side of a run: it submits each input's tasks (probe, segments, join,
    verify) and takes their results as they finish, keeping the manifest and the items."""

    def __init__(
        self,
        client: Any,
        run: RunSettings,
        manifest: _Manifest,
        items: dict[str, ArchiveItem],
        bar: _ByteProgress,
    ) -> None:
        import importlib

        self.client = client
        self.run_settings = run
        self.manifest = manifest
        self.items = items
        self.bar = bar
        self.jobs: dict[str, _Job] = {}
        self.what: dict[Any, tuple[str, str, int]] = {}  # future key -> (rel, step, segment)
        self.pool: Any = importlib.import_module("distributed").as_completed()
        #: why the run stopped early (a full disk), else None
        self.stopped: str | None = None

    def run(self, todo: list[tuple[Path, str, int, int]]) -> str | None:
        """Archive the inputs ``todo`` (path, output name, size, modification time); return why
        the run stopped early, or ``None``."""
        s = self.run_settings
        for path, rel, size, mtime in todo:
            self.jobs[rel] = _Job(path, rel, size, mtime)
            entry = self.manifest.entries.get(rel, {})
            if (
                entry.get("state") == "done"
                and entry.get("settings") == s.recorded[rel]
                and s.verify
            ):
                item = self.items[rel]
                item.state = "done"
                item.bytes_out = int(entry.get("bytes_out", 0))
                item.frames = int(entry.get("frames", 0))
                _take_camera(item, entry.get("camera"))
                self.submit(
                    rel, "verify", 0, _verify, str(path), s.options[rel], str(s.out / rel), None
                )
                self.advance(size)
                continue
            self.submit(
                rel, "probe", 0, _probe, str(path), s.options[rel], s.segment_frames, s.keyframes
            )
        for fut in self.pool:
            self.take(fut)
        self.manifest.save()
        return self.stopped

    def advance(self, n: float) -> None:
        """Count ``n`` more bytes of source as encoded."""
        self.bar.add(n)
        if self.run_settings.progress is not None:
            self.run_settings.progress(round(self.bar.done), self.bar.total)

    def submit(self, rel: str, step: str, seg: int, fn: Callable[..., Any], *args: Any) -> None:
        """Submit task ``fn(*args)``, step ``step`` (segment ``seg``) of input ``rel``."""
        # Joins and verifications first: they finish inputs and free their segment files.
        priority = {"probe": 0, "segment": 1, "join": 2, "verify": 3}[step]
        fut = self.client.submit(
            fn, *args, key=f"{step}-{uuid.uuid4().hex}", pure=False, priority=priority
        )
        self.what[fut.key] = (rel, step, seg)
        self.jobs[rel].futures.append(fut)
        self.pool.add(fut)

    def fail(self, rel: str, exc: BaseException) -> None:
        """Mark input ``rel`` failed with ``exc``: its tasks are cancelled, its parts go."""
        job = self.jobs[rel]
        for f in job.futures:
            f.cancel()
        item = self.items[rel]
        item.state = "failed"
        item.error = (
            f"{type(exc).__name__}: {exc}" if not isinstance(exc, PcdcodecError) else str(exc)
        )
        self.manifest.update(rel, state="failed", error=item.error)
        shutil.rmtree(self.run_settings.out / PARTS / rel, ignore_errors=True)
        self.bar.inputs_done += 1

    def take(self, fut: Any) -> None:
        """Take a finished task's result (or error) and submit what comes next."""
        out = self.run_settings.out
        rel, step, seg = self.what.pop(fut.key)
        job = self.jobs[rel]
        if self.items[rel].state == "failed" or fut.status == "cancelled":
            if self.items[rel].state == "failed":
                # A segment already running when its input failed cannot be cancelled: what it
                # wrote after the failure goes now.
                shutil.rmtree(out / PARTS / rel, ignore_errors=True)
            return
        exc = fut.exception() if fut.status == "error" else None
        if exc is not None:
            self.task_failed(job, step, exc)
            return
        if self.stopped is not None and step != "join":
            return  # a join that finished anyway left a complete output: record it
        result = fut.result()
        fut.release()
        if step == "probe":
            self.probed(job, result)
        elif step == "segment":
            self.segment_written(job, seg, result)
        elif step == "join":
            self.joined(job, result)
        elif step == "verify":
            self.verified(job)
        self.manifest.save(force=False)

    def task_failed(self, job: _Job, step: str, exc: BaseException) -> None:
        """A task raised ``exc``: encode the input whole, fail it, or stop for a full disk."""
        s = self.run_settings
        if (
            step == "join"
            and isinstance(exc, InputError)
            and "cannot follow" in str(exc)
            and not job.retried_whole
        ):
            # Segments whose codec set-up differs cannot be joined: encode the input whole.
            job.retried_whole = True
            shutil.rmtree(s.out / PARTS / job.rel, ignore_errors=True)
            job.plan, job.remaining, job.colors, job.frames = [(0, None)], 1, {}, 0
            job.parts = [s.out / PARTS / job.rel / "whole.pcdc"]
            self.submit(
                job.rel,
                "segment",
                0,
                _encode_segment,
                str(job.path),
                s.options[job.rel],
                str(job.parts[0]),
                0,
                None,
                s.writer_options,
                s.verify,
            )
            return
        full = _disk_full(exc, s.out)
        self.fail(job.rel, full if full is not None else exc)
        if full is not None and self.stopped is None:
            self.stopped = str(full)
            # Joins under way are let finish: they free their segments' space, and
            # their outputs are complete.
            for other in self.jobs.values():
                for f in other.futures:
                    if f.key in self.what and self.what[f.key][1] != "join":
                        f.cancel()

    def probed(self, job: _Job, result: dict[str, Any]) -> None:
        """Plan the input's segments, and submit those not written by an earlier run."""
        s, rel = self.run_settings, job.rel
        _take_camera(self.items[rel], result["camera"])
        for note in result["camera"]["notes"]:
            s.warn(f"warning: {job.path}: {note}")
        entry = self.manifest.entries.get(rel, {})
        plan = segment_plan(result["frames"], result["size"] or 0, s.segment_frames, s.keyframes)
        index = result.get("index") if len(plan) > 1 else None
        parts_dir = s.out / PARTS / rel
        same = (
            entry.get("hash") == result["hash"]
            and entry.get("settings") == s.recorded[rel]
            and [tuple(seg) for seg in entry.get("segments", [])] == plan
        )
        if not same:
            shutil.rmtree(parts_dir, ignore_errors=True)
        job.plan = plan
        job.parts = [parts_dir / f"seg-{i:05d}.pcdc" for i in range(len(plan))]
        self.manifest.update(
            rel,
            source=str(job.path),
            size=result["size"],
            mtime_ns=result["mtime_ns"],
            hash=result["hash"],
            frames=result["frames"],
            segments=[list(seg) for seg in plan],
            settings=s.recorded[rel],
            camera=result["camera"],
            state="encoding",
            error=None,
        )
        for i, (start, stop) in enumerate(plan):
            job.remaining += 1
            if same and job.parts[i].is_file():
                # Written by an earlier run, and complete: it was renamed when done.
                self.submit(rel, "segment", i, _existing_segment, str(job.parts[i]), s.verify)
                continue
            self.submit(
                rel,
                "segment",
                i,
                _encode_segment,
                str(job.path),
                s.options[rel],
                str(job.parts[i]),
                start,
                stop,
                s.writer_options,
                s.verify,
                index.slice(start, stop) if index is not None else None,
                _window(index, plan, i),
            )

    def segment_written(self, job: _Job, seg: int, result: dict[str, Any]) -> None:
        """Count the segment; when it is the input's last, submit the join."""
        rel = job.rel
        job.remaining -= 1
        job.colors[seg] = result["colors"]
        job.frames += result["frames"]
        n = self.manifest.entries[rel].get("frames")
        self.advance(job.size * result["frames"] / n if n else job.size)
        if job.remaining == 0:
            output = str(self.run_settings.out / rel)
            self.submit(rel, "join", 0, _join_parts, [str(p) for p in job.parts], output)

    def joined(self, job: _Job, result: dict[str, Any]) -> None:
        """The input's output is complete: record it, and submit its verification."""
        s, rel = self.run_settings, job.rel
        shutil.rmtree(s.out / PARTS / rel, ignore_errors=True)
        item = self.items[rel]
        item.state, item.bytes_out = "done", result["bytes"]
        item.frames = job.frames or int(self.manifest.entries[rel].get("frames") or 0)
        item.segments = len(job.plan)
        self.manifest.update(rel, state="done", bytes_out=item.bytes_out, frames=item.frames)
        if s.verify and self.stopped is None:
            colors = (
                [c for i in sorted(job.colors) for c in job.colors[i]]
                if s.writer_options["color"] is not None and len(job.colors) == len(job.plan)
                else None
            )
            self.submit(
                rel, "verify", 0, _verify, str(job.path), s.options[rel], str(s.out / rel), colors
            )
        else:
            self.bar.inputs_done += 1

    def verified(self, job: _Job) -> None:
        """The output decodes to its source: record it, and delete the source if asked."""
        rel = job.rel
        item = self.items[rel]
        item.state = "verified"
        self.manifest.update(rel, state="verified")
        if self.run_settings.delete_source:
            try:
                if job.path.is_dir() and not job.path.is_symlink():
                    shutil.rmtree(job.path)
                else:  # a file, or a link (to a file or a folder): the link goes
                    job.path.unlink()
            except OSError as err:
                item.error = f"verified, but the source could not be deleted: {err}"
            else:
                item.state = "source-deleted"
                self.manifest.update(rel, state="source-deleted")
        self.bar.inputs_done += 1


def _window(
    index: Any, plan: list[tuple[int, int | None]], i: int
) -> tuple[int | None, int | None]:
    """The log times (ns, ``[low, high)``) of the kept messages segment ``i`` of ``plan``
    keeps: from its first frame's time to the next segment's, the first from the start and the
    last to the end, so that each message is in one segment. Without a frame index (no times
    to cut at), the first segment keeps them all."""
    if len(plan) == 1:
        return None, None
    times = getattr(index, "timestamps", None)  # (a rig's index has none: it keeps no topics)
    if times is None:
        return (None, None) if i == 0 else (0, 0)
    low = None if i == 0 else int(times[plan[i][0]])
    high = None if i == len(plan) - 1 else int(times[plan[i + 1][0]])
    return low, high
