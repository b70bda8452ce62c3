"""What an archive run reports: one :class:`ArchiveItem` per input, the run's
:class:`ArchiveSummary` (text and JSON), and the progress line shown while it runs."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any

__all__ = ["ArchiveItem", "ArchiveSummary"]


@dataclass
class ArchiveItem:
    """What happened to one input."""

    source: str
    output: str
    #: ``done``, ``verified``, ``source-deleted``, ``skipped`` (done before), ``failed``, or
    #: ``pending`` (not reached: the run stopped first)
    state: str
    #: the input's size in bytes, following symbolic links; ``None`` when some of it could not
    #: be reached (a dangling link, an unreadable folder)
    bytes_in: int | None = 0
    bytes_out: int = 0
    frames: int = 0
    segments: int = 0
    error: str | None = None
    #: the depth camera recorded (:meth:`~pcdcodec.CameraIntrinsics.to_dict`), and where it
    #: came from: ``"input"`` (recorded in it), a file of the input (``"camera.json"``,
    #: ``"camera-intrinsics.txt"``...), ``"given"`` (``input_options``) or the origin of
    #: ``camera`` (``"--camera tum-ros"``); ``None``/``""`` when not known (not probed)
    camera: dict[str, Any] | None = None
    camera_from: str = ""
    #: the depth scale recorded (units per metre), and where it came from (as ``camera_from``,
    #: or a dataset's convention: ``"TUM RGB-D dataset"``, ``"7-Scenes dataset"``)
    depth_scale: float | None = None
    depth_scale_from: str = ""
    #: where ``camera`` contradicted what the input carries (the input's own was used)
    notes: list[str] = field(default_factory=list)

    def camera_text(self) -> str:
        """``camera 640x480 fx=525 ... (from X), depth scale 5000 (from Y)``, or ``""``."""
        if self.camera is None and self.depth_scale is None:
            return ""
        parts = []
        if self.camera is not None:
            c = self.camera
            parts.append(
                f"camera {c['width']}x{c['height']} fx={c['fx']:g} fy={c['fy']:g} "
                f"cx={c['cx']:g} cy={c['cy']:g} (from {self.camera_from})"
            )
        if self.depth_scale is not None:
            parts.append(f"depth scale {self.depth_scale:g} (from {self.depth_scale_from})")
        return ", ".join(parts)


@dataclass
class ArchiveSummary:
    """The outcome of :func:`archive`. ``ok`` is true when no input failed or was left over."""

    items: list[ArchiveItem]
    seconds: float
    workers: int
    dashboard: str | None = None
    #: why the run stopped before the end (a full disk), else ``None``
    stopped: str | None = None

    def _of(self, *states: str) -> list[ArchiveItem]:
        return [i for i in self.items if i.state in states]

    @property
    def done(self) -> list[ArchiveItem]:
        """Inputs written in this run."""
        return self._of("done", "verified", "source-deleted")

    @property
    def skipped(self) -> list[ArchiveItem]:
        """Inputs already done by an earlier run."""
        return self._of("skipped")

    @property
    def failed(self) -> list[ArchiveItem]:
        return self._of("failed")

    @property
    def pending(self) -> list[ArchiveItem]:
        return self._of("pending")

    @property
    def ok(self) -> bool:
        return not self.failed and not self.pending and self.stopped is None

    @property
    def bytes_in(self) -> int | None:
        """Source bytes encoded in this run; ``None`` when an input's size is unknown."""
        sizes = [i.bytes_in for i in self.done]
        return None if None in sizes else sum(s for s in sizes if s is not None)

    @property
    def bytes_out(self) -> int:
        return sum(i.bytes_out for i in self.done)

    @property
    def frames(self) -> int:
        return sum(i.frames for i in self.done)

    @property
    def ratio(self) -> float | None:
        """Source bytes over output bytes; ``None`` when either is unknown or zero."""
        size = self.bytes_in
        return size / self.bytes_out if size and self.bytes_out else None

    @property
    def throughput(self) -> float | None:
        """Source megabytes (10^6 bytes) per second encoded in this run (``None`` when an
        input's size is unknown)."""
        size = self.bytes_in
        if size is None:
            return None
        return size / 1e6 / self.seconds if self.seconds > 0 else 0.0

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "inputs": len(self.items),
            "done": len(self.done),
            "skipped": len(self.skipped),
            "failed": len(self.failed),
            "pending": len(self.pending),
            "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out,
            "ratio": self.ratio,
            "seconds": self.seconds,
            "throughput_mb_s": self.throughput,
            "frames": self.frames,
            "frames_per_s": self.frames_per_second,
            "workers": self.workers,
            "dashboard": self.dashboard,
            "stopped": self.stopped,
            "items": [asdict(i) for i in self.items],
        }

    def to_text(self) -> str:
        ratio = f"{self.ratio:.1f}x" if self.ratio else "-"
        size, rate = self.bytes_in, self.throughput
        size_in = "? MB (an input's size is unknown)" if size is None else f"{size / 1e6:.1f} MB"
        rate_text = "?" if rate is None else f"{rate:.2f}"
        lines = [
            f"inputs {len(self.items)}: {len(self.done)} written, {len(self.skipped)} already "
            f"done, {len(self.failed)} failed"
            + (f", {len(self.pending)} not reached" if self.pending else ""),
            f"bytes  {size_in} in, {self.bytes_out / 1e6:.1f} MB out (ratio {ratio})",
            f"time   {self.seconds:.1f} s on {self.workers} worker(s): "
            f"{rate_text} MB/s, {self.frames_per_second:.1f} frames/s",
        ]
        if self.stopped:
            lines.append(f"stopped: {self.stopped}")
        cameras = [(i, i.camera_text()) for i in self.items]
        if any(text for _, text in cameras):
            lines.append("cameras:")
            lines += [f"  {i.source}: {text}" for i, text in cameras if text]
        for item in self.items:
            lines += [f"NOTE {item.source}: {note}" for note in item.notes]
        for item in self.items:
            if item.error is not None and item.state != "failed":
                lines.append(f"WARNING {item.source}: {item.error}")
        for item in self.failed:
            lines.append(f"FAILED {item.source}: {item.error}")
        return "\n".join(lines)


class _ByteProgress:
    """The progress line on stderr: source bytes encoded, their rate, and inputs finished."""

    def __init__(self, total: int, enabled: bool, stream: Any) -> None:
        self.total, self.done, self.enabled, self.stream = total, 0.0, enabled, stream
        self.inputs_done = 0
        self.inputs = 0
        self._start = time.perf_counter()
        self._last = 0.0

    def add(self, n: float) -> None:
        self.done = min(float(self.total), self.done + n)
        self.show()

    def show(self, force: bool = False) -> None:
        now = time.perf_counter()
        if not self.enabled or (not force and now - self._last < 0.2):
            return
        self._last = now
        pct = 100 * self.done / self.total if self.total else 100.0
        rate = self.done / 1e6 / max(now - self._start, 1e-9)
        self.stream.write(
            f"\rarchive {pct:3.0f}% {self.done / 1e6:,.1f}/{self.total / 1e6:,.1f} MB "
            f"({rate:.1f} MB/s), {self.inputs_done}/{self.inputs} inputs  "
        )
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.show(force=True)
            self.stream.write("\n")
            self.stream.flush()


def _take_camera(item: ArchiveItem, camera: Any) -> None:
    """Fill in ``item``'s camera from what the probe task found (kept in the manifest)."""
    if not isinstance(camera, dict):
        return  # a manifest of an earlier version
    item.camera = camera.get("camera")
    item.camera_from = str(camera.get("camera_from", ""))
    scale = camera.get("depth_scale")
    item.depth_scale = float(scale) if scale is not None else None
    item.depth_scale_from = str(camera.get("depth_scale_from", ""))
    item.notes = [str(n) for n in camera.get("notes", [])]
