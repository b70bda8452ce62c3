"""The :class:`Evaluation` that :func:`~pcdcodec.bench.evaluation.evaluate` fills, and its
report: Markdown laid out like the tables of the compressed point cloud streams paper, JSON, CSV
and (through :mod:`pcdcodec.bench.plots`) PNG plots.
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .plots import plot_all
from .results import (
    POINTCLOUD2_BYTES_PER_POINT,
    ColorRow,
    DepthRow,
    RDPoint,
    StreamRow,
)
from .results import config_label as _label

__all__ = ["Evaluation"]


@dataclass
class Evaluation:
    """What :func:`evaluate` measured; write it out with :meth:`write`."""

    name: str
    frames: int
    width: int
    height: int
    depth: list[DepthRow] = field(default_factory=list)
    color: list[ColorRow] = field(default_factory=list)
    streams: list[StreamRow] = field(default_factory=list)
    rd: list[RDPoint] = field(default_factory=list)
    peers: list[dict[str, Any]] = field(default_factory=list)

    @property
    def pointcloud2_bytes_per_frame(self) -> int:
        return self.width * self.height * POINTCLOUD2_BYTES_PER_POINT

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "frames": self.frames,
            "width": self.width,
            "height": self.height,
            "pointcloud2_bytes_per_frame": self.pointcloud2_bytes_per_frame,
            "depth": [asdict(r) for r in self.depth],
            "color": [asdict(r) for r in self.color],
            "streams": [asdict(r) for r in self.streams],
            "rd": [asdict(r) for r in self.rd],
            "peers": self.peers,
        }

    def recommend(self) -> dict[str, dict[str, str]]:
        """The best codec of each kind on this data: by ratio and by speed (encode plus decode
        ms per frame). Depth considers codecs that gave the depth back exactly, and apart from
        them ("depth with an error bound") codecs given ``max_error`` / ``max_rel_error``; color
        gives the best lossy codec (with its PSNR) and, where measured, the best lossless one."""
        out: dict[str, dict[str, str]] = {}
        exact = [d for d in self.depth if d.exact]
        if exact:
            best = max(exact, key=lambda d: d.ratio_uint16)
            fast = min(exact, key=lambda d: d.encode_ms + d.decode_ms)
            out["depth"] = {
                "by ratio": f"{_label(best.config)} ({best.ratio_uint16:.2f}x, "
                f"{best.encode_ms + best.decode_ms:.1f} ms)",
                "by speed": f"{_label(fast.config)} ({fast.encode_ms + fast.decode_ms:.1f} ms, "
                f"{fast.ratio_uint16:.2f}x)",
            }
        bounded = [
            d
            for d in self.depth
            if not d.exact
            and (d.config.get("max_error") is not None or d.config.get("max_rel_error") is not None)
        ]
        if bounded:
            best = max(bounded, key=lambda d: d.ratio_uint16)
            out["depth with an error bound"] = {
                "by ratio": f"{_label(best.config)} ({best.ratio_uint16:.2f}x, largest error "
                f"{best.max_error_m * 1000:.1f} mm)"
            }
        for name, rows in (
            ("color", [c for c in self.color if not c.lossless]),
            ("lossless color", [c for c in self.color if c.lossless]),
        ):
            if not rows:
                continue
            best_c = max(rows, key=lambda c: c.ratio_rgb24)
            fast_c = min(rows, key=lambda c: c.encode_ms + c.decode_ms)
            out[name] = {
                "by ratio": f"{_label(best_c.config)} ({best_c.ratio_rgb24:.1f}x"
                + (", exact)" if best_c.lossless else f", PSNR {_db(best_c.psnr)} dB)"),
                "by speed": f"{_label(fast_c.config)} "
                f"({fast_c.encode_ms + fast_c.decode_ms:.1f} ms, {fast_c.ratio_rgb24:.1f}x)",
            }
        return out

    def to_markdown(self) -> str:
        """The report: the paper's four tables, per codec, measured on this sequence."""
        kib = 1024.0
        lines = [
            f"# Codec comparison: {self.name}",
            "",
            f"{self.frames} frames of {self.width}x{self.height}. Raw sizes per frame: RGB24 "
            f"{self.width * self.height * 3 / kib:.0f} KiB, uint16 depth "
            f"{self.width * self.height * 2 / kib:.0f} KiB, float32 depth "
            f"{self.width * self.height * 4 / kib:.0f} KiB, PointCloud2 XYZRGB "
            f"{self.pointcloud2_bytes_per_frame / kib:.0f} KiB (32 B/point, organized). "
            "Times are medians per frame on this machine.",
            "",
        ]
        if self.color:
            lines += [
                "## Table I: color codecs",
                "",
                "| codec | KiB/frame | bits/pixel | ratio vs RGB24 | PSNR dB | SSIM | "
                "encode ms | decode ms |",
                "|---|---|---|---|---|---|---|---|",
            ]
            for c in self.color:
                lines.append(
                    f"| {_label(c.config)} | {c.bytes_per_frame / kib:.1f} | "
                    f"{c.bits_per_pixel:.3f} | {c.ratio_rgb24:.1f} | {_db(c.psnr)} | "
                    f"{c.ssim:.4f} | {c.encode_ms:.2f} | {c.decode_ms:.2f} |"
                )
            lines.append("")
        if self.depth:
            # Error columns are zero by construction when every codec is exact: say it once.
            errors = any(not d.exact for d in self.depth)
            f32_input = any(d.ratio_float32_input for d in self.depth)
            head = "| codec | KiB/frame | ratio vs uint16 |"
            if f32_input:
                head += " float32 input |"
            head += " encode ms | decode ms |"
            if errors:
                head += " exact | RMSE mm (edge / interior) | cloud RMSE mm |"
            lines += [
                "## Table II: depth codecs",
                "",
                head,
                "|" + "---|" * head.count(" |"),
            ]
            for d in self.depth:
                row = (
                    f"| {_label(d.config)} | {d.bytes_per_frame / kib:.1f} | {d.ratio_uint16:.2f} |"
                )
                if f32_input:
                    f32 = f"{d.ratio_float32_input:.2f}" if d.ratio_float32_input else "-"
                    row += f" {f32} |"
                row += f" {d.encode_ms:.2f} | {d.decode_ms:.2f} |"
                if errors:
                    row += (
                        f" {'yes' if d.exact else 'no'} | {1000 * d.rmse_m:.3f} "
                        f"({1000 * d.edge_rmse_m:.3f} / {1000 * d.interior_rmse_m:.3f}) | "
                        f"{1000 * d.cloud_rmse_m:.3f} |"
                    )
                lines.append(row)
            lines.append("")
            notes = ["Against float32 depth (metres) every ratio doubles."]
            if not errors:
                notes.append(
                    "Every depth codec gave the depth back bit-exact: depth and point errors are 0."
                )
            lines += [" ".join(notes), ""]
        for title, rows in (
            ("Table III: whole stream, lossy color", [s for s in self.streams if not s.lossless]),
            ("Table IV: whole stream, fully lossless", [s for s in self.streams if s.lossless]),
        ):
            if not rows:
                continue
            lines += [
                f"## {title}",
                "",
                "| color | depth | KiB/frame | ratio vs raw RGB-D | ratio vs PointCloud2 |",
                "|---|---|---|---|---|",
            ]
            for s in rows:
                lines.append(
                    f"| {s.color} | {s.depth} | {s.bytes_per_frame / kib:.1f} | "
                    f"{s.ratio_raw:.1f} | {s.ratio_pointcloud2:.1f} |"
                )
            lines.append("")
        if self.peers:
            lines += ["## Peers", "", "| peer | kind | KiB/frame | encode ms | decode ms | notes |"]
            lines.append("|---|---|---|---|---|---|")
            for p in self.peers:
                lines.append(
                    f"| {p.get('name')} | {p.get('kind')} | "
                    f"{float(p.get('bytes_per_frame', 0)) / kib:.1f} | "
                    f"{float(p.get('encode_ms', 0)):.2f} | {float(p.get('decode_ms', 0)):.2f} | "
                    f"{p.get('notes', '')} |"
                )
            lines.append("")
        recommendation = self.recommend()
        if recommendation:
            lines += ["## Recommendation for this data", ""]
            for kind, picks in recommendation.items():
                lines.append(
                    f"- {kind}: by ratio {picks['by ratio']}; by speed {picks['by speed']}"
                )
            lines.append("")
        return "\n".join(lines)

    def write_csv(self, out_dir: Path) -> list[Path]:
        written = []
        for name, rows in (
            ("depth", self.depth),
            ("color", self.color),
            ("streams", self.streams),
            ("rd", self.rd),
        ):
            if not rows:
                continue
            path = out_dir / f"{name}.csv"
            dicts = [asdict(r) for r in rows]
            with path.open("w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=list(dicts[0]))
                writer.writeheader()
                for d in dicts:
                    writer.writerow(
                        {k: json.dumps(v) if isinstance(v, dict) else v for k, v in d.items()}
                    )
            written.append(path)
        return written

    def plot(self, out_dir: Path) -> list[Path]:
        """Write the PNG plots; needs matplotlib (``pip install "pcdcodec[bench]"``)."""
        return plot_all(self, out_dir)

    def write(self, out_dir: str | os.PathLike[str], *, plots: bool = True) -> list[Path]:
        """Write ``report.md``, ``results.json``, the CSV files and (optionally) the plots."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        report = out / "report.md"
        report.write_text(self.to_markdown() + "\n")
        results = out / "results.json"
        results.write_text(json.dumps(self.to_dict(), indent=2, default=_json_default) + "\n")
        written = [report, results, *self.write_csv(out)]
        if plots:
            written += self.plot(out)
        return written


def _json_default(value: Any) -> Any:
    if isinstance(value, float) and not np.isfinite(value):
        return str(value)
    return str(value)


def _db(value: float) -> str:
    return "inf" if value == float("inf") else f"{value:.2f}"
