"""Choosing the color codec: h264, h265, AV1 and VP9 at the default's quality on every dense set.

Run: ``python scripts/color_table.py [--frames 60] [--gops 30,10] [--rounds 3]
[--sets sample,tum_fr1_rpy,...] [--extra '{"id": "vp9", "speed": 6}'] [--json OUT]``.

For each dense set present (the bundled sample and the sequences of ``../shared/data``) it
codes the color of the first ``--frames`` frames with today's default (``h264``, crf 18) and
with each candidate in a setting that holds back no frame (``h265`` zerolatency, ``av1`` with
SVT-AV1's low-delay structure, ``vp9`` with ``lag-in-frames`` 0), every codec on one thread.
Each candidate's crf is searched (integer steps, galloping then bisection) for the largest
one whose mean PSNR over the frames is at least the default's, then lowered until its mean
SSIM is too: the quality no worse than today's on both measures. The table gives both
settings ("PSNR only" and both), and the size at exactly the default's PSNR, interpolated
between the PSNR-only crf and the next (log size, linear in dB).

The whole stream is the color, today's default depth (``depthac``) and the recording's own
overhead, all measured on a real recording of the same frames with the default codecs,
against a PointCloud2 XYZRGB of the valid points (32 bytes per point, the mean count of
pixels with depth). "Held" is the most frames the encoder held back while encoding (frames in
minus frames whose packet came out): a SIGKILL loses them on top of the writer's own queue.

A second table takes, for each codec, the one crf that reaches the default's quality on every
set (the smallest of the per-set crfs) and measures it everywhere; its encode and decode rates
(one thread) are timed in rounds that interleave the codecs, so that the load of a shared
machine falls on all of them alike, and are also given relative to ``h264``'s in the same
round (above 1: faster). Random access is estimated as the decode time of the frames from
the last keyframe: (gop + 1) / 2 frames on average.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import SEQUENCES
from pcdcodec.color import StreamCodec, decode_packets
from pcdcodec.color.base import Packet
from pcdcodec.datasets import load_folder, load_sample
from pcdcodec.metrics import psnr, ssim

#: Bytes per point of a PointCloud2 XYZRGB (float32 x, y, z, packed RGB, padding).
PC2_BYTES = 32
TARGET_RATIO = 250.0
FPS = 30.0


@dataclass(frozen=True)
class Candidate:
    """A color codec setting whose ``crf`` is searched; the reference's is not."""

    label: str
    config: dict[str, Any]
    crf_range: tuple[int, int]
    start: int
    reference: bool = False


CANDIDATES = [
    Candidate("h264", {"id": "h264"}, (18, 18), 18, reference=True),
    Candidate("h265", {"id": "h265"}, (0, 51), 22),
    Candidate("av1", {"id": "av1", "low_delay": True}, (1, 63), 27),
    Candidate("vp9", {"id": "vp9"}, (0, 63), 28),
]


@dataclass
class Stream:
    """One coded stream: its crf, size, quality, and the frames its encoder held back."""

    crf: int
    bytes_per_frame: float
    psnr: float
    ssim: float | None = None
    held: int = 0
    keyframes: int = 0


@dataclass
class SetData:
    """A dense set's frames and what the rest of the stream costs per frame."""

    name: str
    colors: list[np.ndarray[Any, Any]]
    valid_points: float
    depth_bytes: float
    overhead_bytes: float
    default_ratio: float  # of the real recording with the default codecs

    @property
    def pointcloud2_bytes(self) -> float:
        return self.valid_points * PC2_BYTES

    def ratio(self, color_bytes: float) -> float:
        return self.pointcloud2_bytes / (color_bytes + self.depth_bytes + self.overhead_bytes)

    @property
    def color_budget(self) -> float:
        """Color bytes per frame that leave the whole stream at :data:`TARGET_RATIO`."""
        return self.pointcloud2_bytes / TARGET_RATIO - self.depth_bytes - self.overhead_bytes


def load_set(name: str, frames: int, workdir: Path) -> SetData:
    """The first ``frames`` frames of set ``name``, and a default recording of them."""
    if name == "sample":
        seq = load_sample(max_frames=frames)
    else:
        seq = load_folder(
            SEQUENCES[name].root, max_frames=frames, **SEQUENCES[name].reader_options()
        )
    n = len(seq)
    path = workdir / f"{name}.pcdc"
    with pcdcodec.open(
        path, "w", intrinsics=seq.intrinsics, depth_scale=seq.depth_scale, overwrite=True
    ) as writer:
        writer.write_frames(seq)
    size = path.stat().st_size
    path.unlink()
    valid = float(np.mean([np.count_nonzero(f.depth) for f in seq]))
    return SetData(
        name,
        [np.ascontiguousarray(f.color) for f in seq],
        valid,
        writer.bytes_depth / n,
        (size - writer.bytes_color - writer.bytes_depth) / n,
        valid * PC2_BYTES * n / size,
    )


def codec_of(cand: Candidate, crf: int, gop: int) -> StreamCodec:
    codec = pcdcodec.get_codec({**cand.config, "crf": crf, "gop": gop, "threads": 1})
    assert isinstance(codec, StreamCodec)
    return codec


def encode(
    codec: StreamCodec, colors: list[np.ndarray[Any, Any]]
) -> tuple[list[Packet], bytes | None, int, float]:
    """Packets, extradata, the most frames held back, and the encode time in seconds."""
    h, w = colors[0].shape[:2]
    start = time.perf_counter()
    encoder = codec.encoder(w, h, FPS)
    packets: list[Packet] = []
    held = 0
    for i, rgb in enumerate(colors):
        packets += encoder.encode(rgb, round(i * 1e9 / FPS))
        held = max(held, i + 1 - len(packets))
    packets += encoder.flush()
    return packets, encoder.extradata, held, time.perf_counter() - start


def decode(
    codec: StreamCodec, packets: list[Packet], extradata: bytes | None, w: int, h: int
) -> tuple[list[np.ndarray[Any, Any]], float]:
    start = time.perf_counter()
    frames = decode_packets(codec, packets, w, h, extradata)
    return [f.rgb for f in frames], time.perf_counter() - start


class Coder:
    """Codes one set's colors at (candidate, crf, gop), each once; SSIM only when asked."""

    def __init__(self, colors: list[np.ndarray[Any, Any]]) -> None:
        self.colors = colors
        self._streams: dict[tuple[str, int, int], Stream] = {}
        self._decoded: dict[tuple[str, int, int], list[np.ndarray[Any, Any]]] = {}

    def __call__(self, cand: Candidate, crf: int, gop: int, with_ssim: bool = False) -> Stream:
        key = (cand.label, crf, gop)
        if key not in self._streams:
            codec = codec_of(cand, crf, gop)
            packets, extradata, held, _ = encode(codec, self.colors)
            h, w = self.colors[0].shape[:2]
            decoded, _ = decode(codec, packets, extradata, w, h)
            if len(decoded) != len(self.colors):
                raise SystemExit(f"{cand.label} crf {crf}: {len(decoded)} frames decoded")
            n = len(self.colors)
            self._streams[key] = Stream(
                crf,
                sum(len(p.data) for p in packets) / n,
                float(np.mean([psnr(a, b) for a, b in zip(self.colors, decoded, strict=True)])),
                held=held,
                keyframes=sum(p.keyframe for p in packets),
            )
            self._decoded[key] = decoded
        stream = self._streams[key]
        if with_ssim and stream.ssim is None:
            pairs = zip(self.colors, self._decoded[key], strict=True)
            stream.ssim = float(np.mean([ssim(a, b) for a, b in pairs]))
        return stream


def search_crf(meets: Callable[[int], bool], lo: int, hi: int, start: int) -> int | None:
    """The largest crf in [lo, hi] that ``meets`` the target, for a target met by every crf
    below some point: gallop from ``start`` in steps of 4 to a bracket, then bisect."""
    good: int | None = None
    bad: int | None = None
    c = min(max(start, lo), hi)
    while True:
        if meets(c):
            good = c
            if c == hi or (bad is not None and bad == c + 1):
                break
            c = min(hi, c + 4) if bad is None else (c + bad) // 2
        else:
            bad = c
            if c == lo or (good is not None and good == c - 1):
                break
            c = max(lo, c - 4) if good is None else (good + c) // 2
    return good


@dataclass
class Matched:
    """A candidate at the default's quality on one set and gop."""

    #: At the largest crf with PSNR and SSIM no worse than the default's.
    stream: Stream
    #: At the largest crf with PSNR no worse (SSIM may be below the default's there).
    psnr_only: Stream
    bytes_at_equal_psnr: float
    ratio: float


def match(coder: Coder, cand: Candidate, gop: int, ref: Stream) -> Matched | None:
    """The candidate's largest crf with PSNR and SSIM no worse than ``ref``'s."""
    assert ref.ssim is not None
    lo, hi = cand.crf_range
    crf = search_crf(lambda c: coder(cand, c, gop).psnr >= ref.psnr, lo, hi, cand.start)
    if crf is None:
        return None
    # The size at exactly the reference's PSNR, between crf (above it) and crf + 1 (below).
    above = coder(cand, crf, gop)
    at_psnr = above.bytes_per_frame
    if crf < hi and not cand.reference:
        below = coder(cand, crf + 1, gop)
        if above.psnr > below.psnr:
            t = (ref.psnr - below.psnr) / (above.psnr - below.psnr)
            logs = math.log(below.bytes_per_frame), math.log(above.bytes_per_frame)
            at_psnr = math.exp(logs[0] + t * (logs[1] - logs[0]))

    def ssim_ok(c: int) -> bool:
        s = coder(cand, c, gop, with_ssim=True)
        assert s.ssim is not None
        assert ref.ssim is not None
        return s.ssim >= ref.ssim and s.psnr >= ref.psnr

    both = search_crf(ssim_ok, lo, crf, crf)
    if both is None:
        return None
    return Matched(
        coder(cand, both, gop, with_ssim=True), coder(cand, crf, gop, True), at_psnr, 0.0
    )


@dataclass
class Speed:
    """Encode and decode rates (frames/s, one thread) and their ratios to h264's per round."""

    encode_fps: float
    decode_fps: float
    encode_vs_h264: tuple[float, float] = (1.0, 1.0)
    decode_vs_h264: tuple[float, float] = (1.0, 1.0)
    random_access_ms: float = 0.0
    encode_s: list[float] = field(default_factory=list)
    decode_s: list[float] = field(default_factory=list)


def time_rounds(
    colors: list[np.ndarray[Any, Any]], setups: dict[str, StreamCodec], rounds: int, gop: int
) -> dict[str, Speed]:
    """Interleaved rounds: each round encodes and decodes the frames with every codec, the
    order rotating from round to round."""
    h, w = colors[0].shape[:2]
    n = len(colors)
    names = list(setups)
    enc: dict[str, list[float]] = {k: [] for k in names}
    dec: dict[str, list[float]] = {k: [] for k in names}
    for r in range(rounds):
        for name in names[r % len(names) :] + names[: r % len(names)]:
            codec = setups[name]
            packets, extradata, _, t_enc = encode(codec, colors)
            _, t_dec = decode(codec, packets, extradata, w, h)
            enc[name].append(t_enc)
            dec[name].append(t_dec)
    out = {}
    for name in names:
        e = [enc["h264"][i] / enc[name][i] for i in range(rounds)]
        d = [dec["h264"][i] / dec[name][i] for i in range(rounds)]
        dec_fps = n / statistics.median(dec[name])
        out[name] = Speed(
            n / statistics.median(enc[name]),
            dec_fps,
            (min(e), max(e)),
            (min(d), max(d)),
            1000.0 / dec_fps * (gop + 1) / 2,
            enc[name],
            dec[name],
        )
    return out


def fmt_range(r: tuple[float, float]) -> str:
    return f"{r[0]:.2f}" if f"{r[0]:.2f}" == f"{r[1]:.2f}" else f"{r[0]:.2f}–{r[1]:.2f}"


def run(args: argparse.Namespace) -> dict[str, Any]:
    candidates = list(CANDIDATES)
    for spec in args.extra:
        config = json.loads(spec)
        label = ",".join(f"{k}={v}" for k, v in config.items() if k != "id")
        candidates.append(Candidate(f"{config['id']}({label})", config, (0, 63), 28))
    names = args.sets.split(",") if args.sets else [n for n, s in SEQUENCES.items() if s.present]
    gops = [int(g) for g in args.gops.split(",")]
    kib = 1024.0
    result: dict[str, Any] = {"frames": args.frames, "gops": gops, "sets": {}, "common": {}}
    sets: dict[str, SetData] = {}
    coders: dict[str, Coder] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            sets[name] = load_set(name, args.frames, Path(tmp))
    ref_cand = candidates[0]
    matched: dict[tuple[str, int, str], Matched | None] = {}
    for name, data in sets.items():
        coder = coders[name] = Coder(data.colors)
        info = {
            "frames": len(data.colors),
            "valid_points": data.valid_points,
            "pointcloud2_bytes_per_frame": data.pointcloud2_bytes,
            "depth_bytes_per_frame": data.depth_bytes,
            "overhead_bytes_per_frame": data.overhead_bytes,
            "default_recording_ratio": data.default_ratio,
            "color_budget_250x": data.color_budget,
            "gops": {},
        }
        result["sets"][name] = info
        print(
            f"\n### {name}: {len(data.colors)} frames, {data.valid_points:,.0f} valid points "
            f"(PointCloud2 {data.pointcloud2_bytes / kib:.0f} KiB); depthac "
            f"{data.depth_bytes / kib:.1f} KiB, recording overhead "
            f"{data.overhead_bytes / kib:.2f} KiB per frame; color for {TARGET_RATIO:.0f}×: "
            f"{data.color_budget / kib:.2f} KiB; default recording {data.default_ratio:.1f}×\n"
        )
        print(
            "| gop | codec | crf (PSNR only) | KiB/frame (PSNR only) | SSIM (PSNR only) | "
            "KiB at equal PSNR | crf | color KiB/frame | PSNR dB | SSIM | held | whole stream × |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for gop in gops:
            ref = coder(ref_cand, 18, gop, with_ssim=True)
            rows = {}
            for cand in candidates:
                m = match(coder, cand, gop, ref)
                matched[name, gop, cand.label] = m
                if m is None:
                    print(f"| {gop} | {cand.label} | – | no crf reaches {ref.psnr:.2f} dB |")
                    continue
                m.ratio = data.ratio(m.stream.bytes_per_frame)
                s = m.stream
                rows[cand.label] = {
                    **asdict(s),
                    "bytes_at_equal_psnr": m.bytes_at_equal_psnr,
                    "psnr_only": asdict(m.psnr_only),
                }
                rows[cand.label]["ratio"] = m.ratio
                p = m.psnr_only
                print(
                    f"| {gop} | {cand.label} | {p.crf} | {p.bytes_per_frame / kib:.2f} | "
                    f"{p.ssim:.4f} | {m.bytes_at_equal_psnr / kib:.2f} | {s.crf} | "
                    f"{s.bytes_per_frame / kib:.2f} | {s.psnr:.2f} | {s.ssim:.4f} | "
                    f"{s.held} | {m.ratio:.1f} |",
                    flush=True,
                )
            info["gops"][str(gop)] = rows
    for gop in gops:
        common(result, candidates, sets, coders, matched, gop, args.rounds)
    return result


def common(
    result: dict[str, Any],
    candidates: list[Candidate],
    sets: dict[str, SetData],
    coders: dict[str, Coder],
    matched: dict[tuple[str, int, str], Matched | None],
    gop: int,
    rounds: int,
) -> None:
    """Each codec at the one crf that reaches the default's quality on every set."""
    kib = 1024.0
    out: dict[str, Any] = {}
    result["common"][str(gop)] = out
    settings: dict[str, Candidate] = {}
    crfs: dict[str, int] = {}
    for cand in candidates:
        per_set = [matched[name, gop, cand.label] for name in sets]
        if all(m is not None for m in per_set):
            crfs[cand.label] = min(m.stream.crf for m in per_set if m is not None)
            settings[cand.label] = cand
    print(
        f"\n### One setting for every set, gop {gop}: the largest crf at the default's PSNR "
        "and SSIM on each\n"
    )
    print(
        "| codec | crf | set | color KiB/frame | vs h264 | PSNR dB (h264) | SSIM (h264) | held | "
        "whole stream × | encode fps | decode fps | encode / h264 | decode / h264 | "
        "random access ms |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, data in sets.items():
        coder = coders[name]
        ref = coder(candidates[0], 18, gop, with_ssim=True)
        codecs = {k: codec_of(c, crfs[k], gop) for k, c in settings.items()}
        speeds = time_rounds(data.colors, codecs, rounds, gop)
        for label, cand in settings.items():
            s = coder(cand, crfs[label], gop, with_ssim=True)
            sp = speeds[label]
            assert s.ssim is not None
            assert ref.ssim is not None
            row = out.setdefault(label, {"crf": crfs[label], "sets": {}})
            row["sets"][name] = {
                **asdict(s),
                "ratio": sets[name].ratio(s.bytes_per_frame),
                "size_vs_h264": s.bytes_per_frame / ref.bytes_per_frame,
                "quality_no_worse": s.psnr >= ref.psnr and s.ssim >= ref.ssim,
                **asdict(sp),
            }
            print(
                f"| {label} | {crfs[label]} | {name} | {s.bytes_per_frame / kib:.2f} | "
                f"{s.bytes_per_frame / ref.bytes_per_frame:.2f} | {s.psnr:.2f} ({ref.psnr:.2f}) | "
                f"{s.ssim:.4f} ({ref.ssim:.4f}) | {s.held} | "
                f"{sets[name].ratio(s.bytes_per_frame):.1f} | {sp.encode_fps:.0f} | "
                f"{sp.decode_fps:.0f} | {fmt_range(sp.encode_vs_h264)} | "
                f"{fmt_range(sp.decode_vs_h264)} | {sp.random_access_ms:.1f} |",
                flush=True,
            )
    for label, row in out.items():
        rows = row["sets"].values()
        row["wins"] = label != "h264" and all(
            r["quality_no_worse"] and r["held"] <= 1 and r["size_vs_h264"] < 1 for r in rows
        )
        row["reaches_250x"] = all(r["ratio"] >= TARGET_RATIO for r in rows)
    winners = [k for k, r in out.items() if r["wins"]]
    print(
        f"\ngop {gop}: smaller than h264 at no worse PSNR and SSIM, holding back at most one "
        f"frame, on every set: {', '.join(winners) or 'none'}"
    )


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=60, help="frames per set (default 60)")
    parser.add_argument("--gops", default="30,10", help="keyframe intervals (default 30,10)")
    parser.add_argument("--rounds", type=int, default=3, help="timed rounds (default 3)")
    parser.add_argument("--sets", default="", help="comma-separated (default: every dense set)")
    parser.add_argument(
        "--extra", action="append", default=[], help="another candidate, a JSON config"
    )
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    result = run(args)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
