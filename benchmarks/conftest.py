"""After a timed benchmark run, print summary tables: the codecs' ratios, quality and speed."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import pytest


def _collect(session: Any, kind: str) -> dict[tuple[str, str], dict[str, Any]]:
    rows: dict[tuple[str, str], dict[str, Any]] = defaultdict(dict)
    for bench in session.benchmarks:
        info = bench.extra_info
        if info.get("kind") != kind or bench.stats is None:
            continue
        row = rows[(info["sequence"], info["codec"])]
        row.update(info)
        per_frame = bench.stats.median * 1000 / (info["frames"] if kind == "color" else 1)
        row[info["op"]] = per_frame
    return rows


def _ms(row: dict[str, Any], op: str) -> str:
    return f"{row[op]:9.2f}" if op in row else f"{'':9}"


def _psnr(value: Any) -> str:
    return f"{value:7.2f}" if isinstance(value, float) else f"{value!s:>7}"


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    session = getattr(config, "_benchmarksession", None)
    if session is None or getattr(session, "disabled", False):
        return
    write = terminalreporter.write_line
    depth = _collect(session, "depth")
    if depth:
        write("")
        write("depth codecs: ratio against raw uint16, median ms per frame, times / jpegxl's")
        write(
            f"| {'sequence':26} | {'codec':8} | {'ratio':>6} | {'encode ms':>9} "
            f"| {'decode ms':>9} | {'enc/jxl':>7} | {'dec/jxl':>7} |"
        )
        write(f"|{'-' * 28}|{'-' * 10}|{'-' * 8}|{'-' * 11}|{'-' * 11}|{'-' * 9}|{'-' * 9}|")
        for (sequence, codec), row in sorted(depth.items()):
            jxl = depth.get((sequence, "jpegxl"), {})
            rel = [
                f"{row[op] / jxl[op]:7.2f}" if op in row and jxl.get(op) else f"{'':7}"
                for op in ("encode", "decode")
            ]
            write(
                f"| {sequence:26} | {codec:8} | {row['ratio']:6.2f} | {_ms(row, 'encode')} "
                f"| {_ms(row, 'decode')} | {rel[0]} | {rel[1]} |"
            )
    color = _collect(session, "color")
    if color:
        write("")
        write("color codecs: size, ratio against raw RGB24, mean PSNR, median ms per frame")
        write(
            f"| {'sequence':18} | {'codec':13} | {'KiB/frame':>9} | {'ratio':>6} | {'PSNR dB':>7} "
            f"| {'encode ms':>9} | {'decode ms':>9} |"
        )
        write(f"|{'-' * 20}|{'-' * 15}|{'-' * 11}|{'-' * 8}|{'-' * 9}|{'-' * 11}|{'-' * 11}|")
        for (sequence, codec), row in sorted(color.items()):
            write(
                f"| {sequence:18} | {codec:13} | {row['bytes_per_frame'] / 1024:9.1f} "
                f"| {row['ratio']:6.1f} | {_psnr(row['psnr'])} | {_ms(row, 'encode')} "
                f"| {_ms(row, 'decode')} |"
            )

    projector: dict[str, dict[str, float]] = defaultdict(dict)
    for b in session.benchmarks:
        if b.extra_info.get("kind") == "projector" and b.stats is not None:
            info = b.extra_info
            projector[info.get("sequence", "")][info["path"]] = b.stats.median * 1000
    for sequence, paths in sorted(projector.items()):
        reference = paths.get("open3d-tensor-create_from_rgbd_image")
        if not reference:
            continue
        write("")
        write(f"depth to colored points, {sequence}: median ms and ratio to Open3D's tensor API")
        write(f"| {'path':38} | {'ms':>6} | {'x o3d.t':>7} |")
        write(f"|{'-' * 40}|{'-' * 8}|{'-' * 9}|")
        for path, ms in sorted(paths.items(), key=lambda item: item[1]):
            write(f"| {path:38} | {ms:6.2f} | {ms / reference:7.2f} |")

    recording = [
        (b.extra_info, b.stats.median)
        for b in session.benchmarks
        if b.extra_info.get("kind") == "recording" and b.stats is not None
    ]
    if recording:
        write("")
        write("recordings, 640x480, default codecs: frames per second")
        write(f"| {'sequence':18} | {'what':44} | {'fps':>7} |")
        write(f"|{'-' * 20}|{'-' * 46}|{'-' * 9}|")
        labels = {
            "write": "record (color + depth threads, 2 cores)",
            "play": "decode + point cloud (1 core)",
        }
        for info, median in sorted(recording, key=lambda r: (r[0]["sequence"], r[0]["op"])):
            fps = info["frames"] / median
            write(f"| {info['sequence']:18} | {labels[info['op']]:44} | {fps:7.1f} |")
