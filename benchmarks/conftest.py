"""The repository's benchmarks use pcdcodec's own pytest plugin (as a user's would): its
fixtures, codec parametrisation and codec summary table. The inputs are the sequences of
:mod:`pcdcodec.bench.sequences` that are present; ``--pcdcodec-data`` replaces them. After a
timed run this file adds the projector and recording tables."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import pytest

from pcdcodec.bench.sequences import PRESENT, SEQUENCES

pytest_plugins = ["pcdcodec.bench.pytest_plugin"]


def pytest_configure(config: pytest.Config) -> None:
    from pcdcodec.testing import add_data  # after pytest_plugins, so pytest rewrites its asserts

    for name in PRESENT:
        seq = SEQUENCES[name]
        add_data(config, name, seq.root, **seq.reader_options())


def _depthac_jxl_table(session: Any, write: Any) -> None:
    """``test_bench_depthac_jxl.py``: depthac against JPEG XL effort 2 per set, and the range
    over every set of depthac's time over libjxl's (the "≤ JPEG XL" rows: ≤ 1 meets them)."""
    rows: dict[str, dict[str, Any]] = defaultdict(dict)
    for b in session.benchmarks:
        info = b.extra_info
        if info.get("kind") == "depthac-jxl" and b.stats is not None:
            row = rows[info["sequence"]]
            row["shape"] = info["shape"]
            row[(info["coder"], "ratio")] = info["ratio"]
            # The best round: on a shared machine the median moves with the neighbours' load.
            row[(info["coder"], info["op"])] = b.stats.min * 1000 / info["frames"]
    if not rows:
        return
    write("")
    write("depthac against JPEG XL effort 2, one thread: ms per frame (best round), / libjxl's")
    write(
        f"| {'set':28} | {'size':9} | {'ratio':>5} | {'jxl':>5} | {'enc ms':>6} | {'jxl':>6} "
        f"| {'enc /':>5} | {'dec ms':>6} | {'jxl':>6} | {'dec /':>5} | {'codec':>5} |"
    )
    write("|" + "|".join("-" * (w + 2) for w in (28, 9, 5, 5, 6, 6, 5, 6, 6, 5, 5)) + "|")
    rel: dict[str, list[float]] = defaultdict(list)
    for sequence, row in rows.items():  # in the order they ran: ALL_DEPTH_SETS

        def cell(coder: str, what: str, fmt: str, row: dict[str, Any] = row) -> str:
            value = row.get((coder, what))
            return format(value, fmt) if value is not None else ""

        over: dict[str, str] = {}
        for op, against in (("encode", "libjxl"), ("decode", "libjxl"), ("decode", "jpegxl")):
            mine, theirs = row.get(("depthac", op)), row.get((against, op))
            if mine is not None and theirs:
                rel[f"{op} / {against}"].append(mine / theirs)
                over[f"{op} / {against}"] = f"{mine / theirs:.2f}"
        write(
            f"| {sequence:28} | {row['shape']:9} | {cell('depthac', 'ratio', '5.2f'):>5} "
            f"| {cell('libjxl', 'ratio', '5.2f'):>5} | {cell('depthac', 'encode', '6.2f'):>6} "
            f"| {cell('libjxl', 'encode', '6.2f'):>6} | {over.get('encode / libjxl', ''):>5} "
            f"| {cell('depthac', 'decode', '6.2f'):>6} | {cell('libjxl', 'decode', '6.2f'):>6} "
            f"| {over.get('decode / libjxl', ''):>5} | {over.get('decode / jpegxl', ''):>5} |"
        )
    write("(codec: depthac's decode over pcdcodec's jpegxl codec, same container, threads=1)")
    for what, values in sorted(rel.items()):
        met = sum(v <= 1.0 for v in values)
        write(
            f"depthac {what}: {min(values):.2f}-{max(values):.2f} over {len(values)} sets, "
            f"at most 1 on {met}"
        )


def _random_access_table(session: Any, write: Any) -> None:
    """``test_bench_random_access.py``: rec[i] at random over reading in order, per set (the
    "random access" row: at most 2)."""
    rows = [b.extra_info for b in session.benchmarks if b.extra_info.get("kind") == "random-access"]
    if not rows:
        return
    write("")
    write("random access: ms per frame in order and at random (median of rounds, interleaved)")
    write(f"| {'set':20} | {'frames':>6} | {'in order':>8} | {'random':>8} | random / in order |")
    write(f"|{'-' * 22}|{'-' * 8}|{'-' * 10}|{'-' * 10}|{'-' * 19}|")
    for info in rows:
        write(
            f"| {info['sequence']:20} | {info['frames']:6} | {info['in_order_ms']:8.2f} "
            f"| {info['random_ms']:8.2f} | {info['ratio']:.2f} "
            f"({info['ratio_min']:.2f}-{info['ratio_max']:.2f}) |"
        )


def _bag_peer_table(session: Any, write: Any) -> None:
    """``test_bench_bag_peers.py``: each bag's size under each peer, its ratio and MB/s."""
    rows = [
        (b.extra_info, b.stats)
        for b in session.benchmarks
        if b.extra_info.get("kind") == "bag-peer"
    ]
    if not rows:
        return
    write("")
    write("bag peers: bytes, the bag's size over them, MB/s of the bag (median of rounds)")
    write(
        f"| {'bag':12} | {'peer':13} | {'bytes in':>11} | {'bytes out':>11} "
        f"| {'ratio':>6} | {'MB/s':>7} |"
    )
    write(f"|{'-' * 14}|{'-' * 15}|{'-' * 13}|{'-' * 13}|{'-' * 8}|{'-' * 9}|")
    for info, stats in sorted(rows, key=lambda r: (r[0]["bag"], r[0]["peer"])):
        rate = info["bytes_in"] / 1e6 / stats.median if stats is not None else info["mb_per_s"]
        write(
            f"| {info['bag']:12} | {info['peer']:13} | {info['bytes_in']:>11,} "
            f"| {info['bytes_out']:>11,} | {info['ratio']:6.2f} | {rate:7.1f} |"
        )


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    session = getattr(config, "_benchmarksession", None)
    if session is None or getattr(session, "disabled", False):
        return
    write = terminalreporter.write_line

    sets: dict[tuple[str, str], dict[str, Any]] = defaultdict(dict)
    for b in session.benchmarks:
        info = b.extra_info
        if info.get("kind") == "depthset" and b.stats is not None:
            row = sets[(info["sequence"], info["codec"])]
            row.update(info)
            row[info["op"]] = b.stats.median * 1000
    if sets:
        write("")
        write("depth test sets: ratio against raw uint16, median ms per frame, times / jpegxl's")
        write(
            f"| {'set':26} | {'codec':8} | {'ratio':>6} | {'encode ms':>9} "
            f"| {'decode ms':>9} | {'enc/jxl':>7} | {'dec/jxl':>7} |"
        )
        write(f"|{'-' * 28}|{'-' * 10}|{'-' * 8}|{'-' * 11}|{'-' * 11}|{'-' * 9}|{'-' * 9}|")
        for (sequence, codec), row in sorted(sets.items()):
            jxl = sets.get((sequence, "jpegxl"), {})
            cells = [f"{row[op]:9.2f}" if op in row else f"{'':9}" for op in ("encode", "decode")]
            rel = [
                f"{row[op] / jxl[op]:7.2f}" if op in row and jxl.get(op) else f"{'':7}"
                for op in ("encode", "decode")
            ]
            write(
                f"| {sequence:26} | {codec:8} | {row['ratio']:6.2f} | {cells[0]} "
                f"| {cells[1]} | {rel[0]} | {rel[1]} |"
            )

    _depthac_jxl_table(session, write)
    _random_access_table(session, write)
    _bag_peer_table(session, write)

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
