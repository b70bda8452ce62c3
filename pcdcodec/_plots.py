"""PNG plots of an :class:`~pcdcodec.evaluation.Evaluation` (matplotlib, imported here only)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import CodecUnavailableError

if TYPE_CHECKING:
    from .evaluation import Evaluation


def _pyplot() -> Any:
    try:
        import matplotlib
    except ImportError:
        raise CodecUnavailableError(
            'plots need matplotlib: pip install "pcdcodec[bench]"'
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_all(ev: Evaluation, out_dir: Path) -> list[Path]:
    plt = _pyplot()
    written = []
    kib = 1024.0

    if ev.rd:
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        curves: dict[str, list[Any]] = defaultdict(list)
        for p in ev.rd:
            curves[p.codec].append(p)
        for codec, points in sorted(curves.items()):
            points.sort(key=lambda p: p.bits_per_pixel)
            ax.plot([p.bits_per_pixel for p in points], [p.psnr for p in points], "o-", label=codec)
        ax.set_xlabel("bits per pixel")
        ax.set_ylabel("PSNR (dB, RGB)")
        ax.set_title(f"Color rate-distortion: {ev.name}")
        ax.grid(True, alpha=0.3)
        ax.legend()
        path = out_dir / "color_rd.png"
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    if ev.depth:
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        for d in ev.depth:
            ax.scatter(d.encode_ms, d.ratio_uint16, s=40)
            ax.annotate(
                d.codec, (d.encode_ms, d.ratio_uint16), textcoords="offset points", xytext=(5, 4)
            )
        ax.set_xscale("log")
        ax.set_xlabel("encode ms per frame (log)")
        ax.set_ylabel("ratio against raw uint16")
        ax.set_title(f"Depth codecs: {ev.name}")
        ax.grid(True, alpha=0.3)
        path = out_dir / "depth_ratio_speed.png"
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    if ev.streams:
        rows = sorted(ev.streams, key=lambda s: s.bytes_per_frame)
        labels = [f"{s.color} + {s.depth}" for s in rows] + ["PointCloud2 XYZRGB"]
        sizes = [s.bytes_per_frame / kib for s in rows] + [ev.pointcloud2_bytes_per_frame / kib]
        fig, ax = plt.subplots(figsize=(7.0, 0.35 * len(labels) + 1.5))
        bars = ax.barh(range(len(labels)), sizes, color=["C0"] * len(rows) + ["C3"])
        ax.set_yticks(range(len(labels)), labels)
        ax.set_xscale("log")
        ax.set_xlabel("KiB per frame (log)")
        ax.set_title(f"Whole stream per configuration: {ev.name}")
        for bar, row in zip(bars, rows, strict=False):
            ax.text(
                bar.get_width(),
                bar.get_y() + bar.get_height() / 2,
                f" {row.ratio_pointcloud2:.0f}x",
                va="center",
                fontsize=8,
            )
        ax.invert_yaxis()
        path = out_dir / "stream_sizes.png"
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)
    return written
