"""A small progress line on stderr for long work (shown only on a terminal)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``with Progress(total, "encoding") as p: ... p.update(n)`` prints ``encoding 12/120 …``.

    Nothing is printed when ``stream`` is not a terminal (logs, pipes, tests) or when disabled,
    so output stays clean where it is read by programs.
    """

    def __init__(
        self,
        total: int | None,
        label: str,
        *,
        stream: TextIO | None = None,
        enabled: bool | None = None,
        unit: str = "frames",
    ) -> None:
        self.total, self.label, self.unit = total, label, unit
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.count = 0
        self._start = time.perf_counter()
        self._last = 0.0

    def update(self, count: int) -> None:
        self.count = count
        now = time.perf_counter()
        if self.enabled and (now - self._last > 0.1 or count == self.total):
            self._last = now
            rate = count / max(now - self._start, 1e-9)
            of = f"/{self.total}" if self.total else ""
            pct = f" {100 * count / self.total:3.0f}%" if self.total else ""
            self.stream.write(f"\r{self.label}{pct} {count}{of} {self.unit} ({rate:.1f}/s)  ")
            self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled and self.count:
            self.stream.write("\n")
            self.stream.flush()
