"""Counting the outcomes of a long fuzz run: what ``tests/run_fuzz_*.py`` share.

Each script runs seeded cases in worker processes and hands every result to a :class:`Tally`,
which counts outcomes by group (codec pair, bag format, clean file) and by mutation kind, keeps
the failures, prints progress, and writes ``summary.json``.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from pathlib import Path
from typing import Any


class Tally:
    """Outcomes of ``total`` fuzz cases; an outcome outside ``ok`` is a failure."""

    def __init__(
        self, total: int, ok: tuple[str, ...], groups: list[str], group_key: str, every: int
    ) -> None:
        self.total = total
        self.ok = ok
        self.group_key = group_key
        self.every = every
        self.outcomes: Counter[str] = Counter()
        self.by_group: dict[str, Counter[str]] = {g: Counter() for g in groups}
        self.by_kind: dict[str, Counter[str]] = {}
        self.failures: list[dict[str, Any]] = []
        self.done = 0
        self.start = time.perf_counter()

    def add(self, group: str, kind: str, case: int, outcome: str, detail: str) -> bool:
        """Count one result; print it when it fails, and progress every ``every`` cases.
        Returns whether the case failed."""
        self.done += 1
        self.outcomes[outcome] += 1
        self.by_group[group][outcome] += 1
        self.by_kind.setdefault(kind, Counter())[outcome] += 1
        failed = outcome not in self.ok
        if failed:
            self.failures.append(
                {self.group_key: group, "case": case, "outcome": outcome, "detail": detail}
            )
            print(f"FAIL {outcome}: {detail}", flush=True)
        if self.done % self.every == 0:
            rate = self.done / (time.perf_counter() - self.start)
            print(
                f"{self.done}/{self.total} cases, {rate:.1f}/s: {dict(self.outcomes)}", flush=True
            )
        return failed

    def finish(self, out: Path, head: dict[str, Any], groups_name: str, kinds_name: str) -> int:
        """Write ``out/summary.json`` (``head`` first), print it, and return the exit status:
        1 when any case failed."""
        summary = {
            **head,
            "seconds": round(time.perf_counter() - self.start, 1),
            "outcomes": dict(self.outcomes),
            groups_name: {g: dict(c) for g, c in self.by_group.items()},
            kinds_name: {k: dict(c) for k, c in sorted(self.by_kind.items())},
            "failures": self.failures,
        }
        (out / "summary.json").write_text(json.dumps(summary, indent=2))
        print(json.dumps({k: v for k, v in summary.items() if k != "failures"}, indent=2))
        print(
            f"{len(self.failures)} failing case(s) of {self.total}; summary in "
            f"{out / 'summary.json'}"
        )
        return 1 if self.failures else 0
