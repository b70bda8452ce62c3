"""PNG plots of an :class:`~pcdcodec.bench.report.Evaluation` (matplotlib, imported here
only)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any, Protocol

from ..color import DEFAULT_COLOR_CODEC
from ..depth import DEFAULT_DEPTH_CODEC
from ..errors import CodecUnavailableError
from .results import ColorRow, DepthRow, RDPoint, StreamRow, default_setting


class Plottable(Protocol):
    """What the plots read of an :class:`~pcdcodec.bench.report.Evaluation`."""

    @property
    def name(self) -> str: ...
    @property
    def depth(self) -> list[DepthRow]: ...
    @property
    def color(self) -> list[ColorRow]: ...
    @property
    def streams(self) -> list[StreamRow]: ...
    @property
    def rd(self) -> list[RDPoint]: ...
    @property
    def pointcloud2_bytes_per_frame(self) -> int: ...


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


def _save(plt: Any, fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_all(ev: Plottable, out_dir: Path) -> list[Path]:
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
            default = default_setting(codec)
            for p in points:
                if p.setting == default:
                    ax.plot(p.bits_per_pixel, p.psnr, "k*", markersize=12)
        ax.set_xlabel("bits per pixel")
        ax.set_ylabel("PSNR (dB, RGB)")
        ax.set_title(f"Color rate-distortion: {ev.name} (defaults starred)")
        ax.grid(True, alpha=0.3)
        ax.legend()
        written.append(_save(plt, fig, out_dir / "color_rd.png"))

    if ev.depth:
        fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4), sharey=True)
        for ax, attr, what in ((axes[0], "encode_ms", "encode"), (axes[1], "decode_ms", "decode")):
            for d in ev.depth:
                is_default = d.codec == DEFAULT_DEPTH_CODEC
                x = getattr(d, attr)
                ax.scatter(
                    x, d.ratio_uint16, s=90 if is_default else 40, marker="*" if is_default else "o"
                )
                label = f"{d.codec} (default)" if is_default else d.codec
                ax.annotate(
                    label,
                    (x, d.ratio_uint16),
                    textcoords="offset points",
                    xytext=(5, 4),
                    fontsize=9,
                    fontweight="bold" if is_default else "normal",
                )
            ax.set_xlim(left=0)
            ax.set_xlabel(f"{what} ms per frame")
            ax.grid(True, alpha=0.3)
        axes[0].set_ylabel("ratio against raw uint16")
        axes[0].set_ylim(bottom=0)
        fig.suptitle(f"Depth codecs: {ev.name} (the default starred)")
        written.append(_save(plt, fig, out_dir / "depth_ratio_speed.png"))

    if ev.streams:
        color_kib = {c.codec: c.bytes_per_frame / kib for c in ev.color}
        depth_kib = {d.codec: d.bytes_per_frame / kib for d in ev.depth}
        rows = sorted(ev.streams, key=lambda s: s.bytes_per_frame)
        labels = [
            f"{s.color} + {s.depth}"
            + (
                " (default)"
                if (s.color, s.depth) == (DEFAULT_COLOR_CODEC, DEFAULT_DEPTH_CODEC)
                else ""
            )
            for s in rows
        ]
        colors = [color_kib.get(s.color, 0.0) for s in rows]
        depths = [
            depth_kib.get(s.depth, s.bytes_per_frame / kib - c)
            for s, c in zip(rows, colors, strict=True)
        ]
        fig, ax = plt.subplots(figsize=(8.0, 0.4 * len(labels) + 1.8))
        y = list(range(len(labels)))
        ax.barh(y, colors, color="C0", label="color")
        bars = ax.barh(y, depths, left=colors, color="C1", label="depth")
        ax.set_yticks(y, labels, fontsize=9)
        for tick, label in zip(ax.get_yticklabels(), labels, strict=True):
            if label.endswith("(default)"):
                tick.set_fontweight("bold")
        ax.set_xlabel("KiB per frame (linear)")
        pc2 = ev.pointcloud2_bytes_per_frame / kib
        ax.set_title(
            f"Whole stream per configuration: {ev.name}\n"
            f"PointCloud2 XYZRGB: {pc2:,.0f} KiB per frame (ratios on the bars)",
            fontsize=10,
        )
        for bar, row in zip(bars, rows, strict=True):
            ax.text(
                bar.get_x() + bar.get_width(),
                bar.get_y() + bar.get_height() / 2,
                f" {row.ratio_pointcloud2:.0f}x",
                va="center",
                fontsize=8,
            )
        ax.margins(x=0.12)
        ax.legend(loc="upper right")
        ax.invert_yaxis()
        written.append(_save(plt, fig, out_dir / "stream_sizes.png"))
    return written
