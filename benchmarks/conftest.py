"""After a timed benchmark run, print the depth codec table: ratio, encode and decode ms."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import pytest


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    session = getattr(config, "_benchmarksession", None)
    if session is None or getattr(session, "disabled", False):
        return
    rows: dict[tuple[str, str], dict[str, Any]] = defaultdict(dict)
    for bench in session.benchmarks:
        info = bench.extra_info
        if "codec" not in info or bench.stats is None:
            continue
        row = rows[(info["sequence"], info["codec"])]
        row["ratio"] = info["ratio"]
        row[info["op"]] = bench.stats.median * 1000
    if not rows:
        return
    write = terminalreporter.write_line
    write("")
    write("depth codecs: ratio against raw uint16, median ms per 640x480 frame")
    write(f"| {'sequence':18} | {'codec':7} | {'ratio':>6} | {'encode ms':>9} | {'decode ms':>9} |")
    write(f"|{'-' * 20}|{'-' * 9}|{'-' * 8}|{'-' * 11}|{'-' * 11}|")
    for (sequence, codec), row in sorted(rows.items()):
        enc = f"{row['encode']:9.2f}" if "encode" in row else f"{'':9}"
        dec = f"{row['decode']:9.2f}" if "decode" in row else f"{'':9}"
        write(f"| {sequence:18} | {codec:7} | {row['ratio']:6.2f} | {enc} | {dec} |")
