"""Rate–distortion of lossy depth: pcdcodec's bounded-error depth against its peers.

Every method turns the same uint16 depth frames into bytes and back; each point reports the
size and how far the decoded depth strays, measured the same way for all
(:func:`pcdcodec.metrics.depth_error`): the largest error relative to depth, the largest and
the RMS error in metres, the RMS and largest error at depth edges, and the holes created or
filled. Methods (each at several settings):

* ``depthac`` with ``max_rel_error`` (ours: a stated, verified bound);
* 12-bit HEVC (libx265 through PyAV, ``gray12le``, one stream over the frames) at several CRFs,
  as robot-learning datasets store depth; depth is divided by the smallest integer that brings
  the largest value under 4096;
* JPEG XL lossy on the depth image (imagecodecs, ``distance``, effort 2);
* LERC with its absolute bound ``maxZError`` (imagecodecs), holes passed as its mask;
* log depth quantised to steps of ``1 + 2r`` and coded losslessly with ``depthac`` or with
  JPEG XL effort 2.

:func:`depth_rd` runs it; ``pcdcodec bench --depth-rd`` prints the table and plots the curves.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..depth.depthac import DepthAC
from ..errors import InputError
from ..metrics import depth_error

__all__ = ["METHODS", "DepthRDPoint", "depth_rd", "plot_depth_rd", "rd_markdown", "write_rd_csv"]

U16 = npt.NDArray[np.uint16]
#: A method: (frames, depth scale, setting) -> (bytes per frame list, decoded frames, enc s, dec s)
Runner = Callable[[list[U16], float, float], tuple[list[int], list[U16], float, float]]


@dataclass(frozen=True)
class DepthRDPoint:
    """One method at one setting over a set of frames; errors over the valid reference pixels."""

    sequence: str
    method: str
    setting: str
    frames: int
    bytes_per_frame: float
    ratio: float  # against raw uint16
    max_rel_error: float  # max |error| / depth over pixels valid before and after
    max_error_m: float
    rmse_m: float
    edge_rmse_m: float
    edge_max_error_m: float
    holes_created: int
    holes_filled: int
    encode_ms: float
    decode_ms: float


# -- the methods -------------------------------------------------------------------------------


def _ours(frames: list[U16], scale: float, rel: float) -> tuple[list[int], list[U16], float, float]:
    codec = DepthAC(max_rel_error=rel)
    return _frame_codec(frames, codec.encode, codec.decode)


def _frame_codec(
    frames: list[U16], encode: Callable[[Any], bytes], decode: Callable[[bytes], Any]
) -> tuple[list[int], list[U16], float, float]:
    sizes, out = [], []
    enc = dec = 0.0
    for d in frames:
        t0 = time.perf_counter()
        data = encode(d)
        t1 = time.perf_counter()
        back = np.asarray(decode(data))
        t2 = time.perf_counter()
        enc += t1 - t0
        dec += t2 - t1
        sizes.append(len(data))
        out.append(back)
    return sizes, out, enc, dec


def _log_quantiser(rel: float) -> tuple[Callable[[U16], U16], Callable[[U16], U16]]:
    """Log depth in steps of 1 + 2·rel (index 0 = hole), and back to depth units."""
    step = math.log1p(2 * rel)

    def forward(d: U16) -> U16:
        q = np.zeros(d.shape, dtype=np.uint16)
        v = d > 0
        q[v] = np.rint(np.log(d[v].astype(np.float64)) / step).astype(np.uint16) + 1
        return q

    def back(q: U16) -> U16:
        d = np.zeros(q.shape, dtype=np.uint16)
        v = q > 0
        d[v] = np.clip(np.rint(np.exp((q[v].astype(np.float64) - 1) * step)), 1, 65535)
        return d

    return forward, back


def _log_depthac(
    frames: list[U16], scale: float, rel: float
) -> tuple[list[int], list[U16], float, float]:
    fwd, back = _log_quantiser(rel)
    codec = DepthAC()
    return _frame_codec(frames, lambda d: codec.encode(fwd(d)), lambda b: back(codec.decode(b)))


def _log_jpegxl(
    frames: list[U16], scale: float, rel: float
) -> tuple[list[int], list[U16], float, float]:
    import imagecodecs

    fwd, back = _log_quantiser(rel)
    return _frame_codec(
        frames,
        lambda d: bytes(imagecodecs.jpegxl_encode(fwd(d), lossless=True, effort=2, numthreads=1)),
        lambda b: back(np.asarray(imagecodecs.jpegxl_decode(b, numthreads=1))),
    )


def _jpegxl_lossy(
    frames: list[U16], scale: float, distance: float
) -> tuple[list[int], list[U16], float, float]:
    import imagecodecs

    return _frame_codec(
        frames,
        lambda d: bytes(
            imagecodecs.jpegxl_encode(d, lossless=False, distance=distance, effort=2, numthreads=1)
        ),
        lambda b: np.asarray(imagecodecs.jpegxl_decode(b, numthreads=1)),
    )


def _lerc(
    frames: list[U16], scale: float, max_error_m: float
) -> tuple[list[int], list[U16], float, float]:
    import imagecodecs

    level = max_error_m * scale

    def encode(d: U16) -> bytes:
        return bytes(imagecodecs.lerc_encode(d, level=level, masks=d > 0))

    def decode(data: bytes) -> U16:
        values, mask = imagecodecs.lerc_decode(data, masks=True)
        out = np.where(mask, values, 0).astype(np.uint16)
        return out

    return _frame_codec(frames, encode, decode)


def _hevc12(
    frames: list[U16], scale: float, crf: float
) -> tuple[list[int], list[U16], float, float]:
    """One libx265 stream of the frames in 12-bit gray; the size is its bytes per frame."""
    from fractions import Fraction

    import av

    top = max(int(d.max()) for d in frames)
    div = max(1, -(-top // 4095))
    h, w = frames[0].shape
    enc = av.CodecContext.create("libx265", "w")
    enc.width, enc.height = w, h
    enc.pix_fmt = "gray12le"
    enc.time_base = Fraction(1, 30)
    enc.options = {
        "crf": str(int(crf)),
        "preset": "medium",
        "x265-params": "log-level=error:pools=1:frame-threads=1",
    }
    packets: list[Any] = []
    t0 = time.perf_counter()
    for i, d in enumerate(frames):
        v12 = np.rint(d / div).astype(np.uint16)
        frame = av.VideoFrame.from_ndarray(v12, format="gray12le")
        frame.pts = i
        packets.extend(enc.encode(frame))
    packets.extend(enc.encode(None))
    t1 = time.perf_counter()
    dec = av.CodecContext.create("hevc", "r")
    out: list[U16] = []
    for p in packets:
        out.extend(
            (f.to_ndarray().astype(np.uint32) * div).clip(0, 65535).astype(np.uint16)
            for f in dec.decode(p)
        )
    out.extend(
        (f.to_ndarray().astype(np.uint32) * div).clip(0, 65535).astype(np.uint16)
        for f in dec.decode(None)
    )
    t2 = time.perf_counter()
    total = sum(p.size for p in packets)
    per = [total // len(frames)] * len(frames)
    return per, out, t1 - t0, t2 - t1


#: Method name -> (runner, setting name, settings, how a setting is written).
METHODS: dict[str, tuple[Runner, str, tuple[float, ...]]] = {
    "depthac bounded (ours)": (_ours, "max_rel_error", (0.001, 0.0025, 0.005, 0.01, 0.02)),
    "log quantised + depthac": (_log_depthac, "r", (0.0025, 0.005, 0.01, 0.02)),
    "log quantised + JPEG XL e2": (_log_jpegxl, "r", (0.0025, 0.005, 0.01, 0.02)),
    "JPEG XL lossy e2": (_jpegxl_lossy, "distance", (0.05, 0.2, 0.5, 1.0, 2.0)),
    "LERC": (_lerc, "maxZError_m", (0.001, 0.0025, 0.005, 0.01, 0.02)),
    "HEVC 12-bit (x265)": (_hevc12, "crf", (0, 8, 16, 24, 32)),
}


# -- measuring ---------------------------------------------------------------------------------


def _measure(
    sequence: str,
    method: str,
    setting: str,
    frames: list[U16],
    decoded: list[U16],
    sizes: list[int],
    scale: float,
    enc_s: float,
    dec_s: float,
) -> DepthRDPoint:
    sq = sq_n = esq = esq_n = 0.0
    max_abs = max_rel = edge_max = 0.0
    created = filled = 0
    for ref, got in zip(frames, decoded, strict=True):
        err = depth_error(ref, got, depth_scale=scale)
        created += err.holes_created
        filled += err.holes_filled
        if err.compared_pixels:
            sq += err.rmse**2 * err.compared_pixels
            sq_n += err.compared_pixels
            max_abs = max(max_abs, err.max_abs_error)
        if err.edge_pixels and math.isfinite(err.edge_rmse):
            esq += err.edge_rmse**2 * err.edge_pixels
            esq_n += err.edge_pixels
            edge_max = max(edge_max, err.edge_max_abs_error)
        both = (ref > 0) & (got > 0)
        if both.any():
            r = ref[both].astype(np.float64)
            max_rel = max(max_rel, float(np.max(np.abs(got[both] - r) / r)))
    n = len(frames)
    size = float(np.mean(sizes))
    return DepthRDPoint(
        sequence=sequence,
        method=method,
        setting=setting,
        frames=n,
        bytes_per_frame=size,
        ratio=frames[0].nbytes / size,
        max_rel_error=max_rel,
        max_error_m=max_abs / scale,
        rmse_m=math.sqrt(sq / sq_n) / scale if sq_n else 0.0,
        edge_rmse_m=math.sqrt(esq / esq_n) / scale if esq_n else 0.0,
        edge_max_error_m=edge_max / scale,
        holes_created=created,
        holes_filled=filled,
        encode_ms=1000 * enc_s / n,
        decode_ms=1000 * dec_s / n,
    )


def available_methods() -> list[str]:
    """The methods whose backends work here (HEVC needs libx265 in PyAV, the others
    imagecodecs with JPEG XL and LERC)."""
    out = []
    for name in METHODS:
        try:
            if name.startswith("HEVC"):
                import av

                av.codec.Codec("libx265", "w")
            elif "JPEG XL" in name or name == "LERC":
                import imagecodecs

                codec = imagecodecs.JPEGXL if "JPEG XL" in name else imagecodecs.LERC
                if not codec.available:
                    continue
        except Exception:
            continue
        out.append(name)
    return out


def depth_rd(
    frames: Sequence[npt.ArrayLike],
    depth_scale: float,
    *,
    sequence: str = "",
    methods: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[DepthRDPoint]:
    """Run every method (default: all available) at each of its settings on uint16 ``frames``
    (depth units, ``depth_scale`` units per metre; consecutive frames suit the video peer).

    Raises :class:`~pcdcodec.InputError` for no frames, non-uint16 depth, mixed shapes or an
    unknown method.
    """
    arrays = [np.ascontiguousarray(f) for f in frames]
    if not arrays:
        raise InputError("depth_rd needs at least one frame")
    if any(a.dtype != np.uint16 or a.ndim != 2 for a in arrays):
        raise InputError("depth_rd compares methods on 2-D uint16 depth frames")
    if len({a.shape for a in arrays}) != 1:
        raise InputError("depth_rd frames must all have one shape")
    if not (depth_scale > 0 and math.isfinite(depth_scale)):
        raise InputError(f"depth_scale must be positive and finite, got {depth_scale}")
    names = list(methods) if methods is not None else available_methods()
    unknown = [m for m in names if m not in METHODS]
    if unknown:
        raise InputError(f"unknown depth RD method {unknown[0]!r}; known: {list(METHODS)}")
    say = progress or (lambda _m: None)
    points = []
    for name in names:
        runner, key, settings = METHODS[name]
        for value in settings:
            say(f"{name} {key}={value:g}")
            sizes, decoded, enc_s, dec_s = runner(arrays, depth_scale, value)
            points.append(
                _measure(
                    sequence,
                    name,
                    f"{key}={value:g}",
                    arrays,
                    decoded,
                    sizes,
                    depth_scale,
                    enc_s,
                    dec_s,
                )
            )
    return points


# -- reporting ---------------------------------------------------------------------------------


def rd_markdown(points: Sequence[DepthRDPoint]) -> str:
    """A markdown table of the points, one row each."""
    lines = [
        "| sequence | method | setting | ratio | max rel. error | max error (mm) | RMSE (mm) "
        "| edge RMSE (mm) | edge max (mm) | holes created / filled | enc / dec ms |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in points:
        lines.append(
            f"| {p.sequence} | {p.method} | {p.setting} | {p.ratio:.1f}× "
            f"| {100 * p.max_rel_error:.2f} % | {1000 * p.max_error_m:.1f} "
            f"| {1000 * p.rmse_m:.2f} | {1000 * p.edge_rmse_m:.2f} "
            f"| {1000 * p.edge_max_error_m:.1f} | {p.holes_created} / {p.holes_filled} "
            f"| {p.encode_ms:.1f} / {p.decode_ms:.1f} |"
        )
    return "\n".join(lines)


def write_rd_csv(points: Sequence[DepthRDPoint], path: str | Path) -> Path:
    """Write the points as CSV (one row per point, the dataclass fields as columns)."""
    out = Path(path)
    with out.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=[f.name for f in fields(DepthRDPoint)])
        writer.writeheader()
        for p in points:
            writer.writerow(asdict(p))
    return out


def plot_depth_rd(points: Sequence[DepthRDPoint], path: str | Path, title: str = "") -> Path:
    """Plot compression ratio against max relative error, RMSE and edge RMSE (one curve per
    method, log axes) into a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = (
        ("max_rel_error", "max error relative to depth (%)", 100.0),
        ("rmse_m", "RMSE (mm)", 1000.0),
        ("edge_rmse_m", "RMSE at depth edges (mm)", 1000.0),
    )
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    methods = list(dict.fromkeys(p.method for p in points))
    for ax, (attr, label, mult) in zip(axes, panels, strict=True):
        for m in methods:
            pts = sorted((p for p in points if p.method == m), key=lambda p: getattr(p, attr))
            xs = [max(getattr(p, attr) * mult, 1e-3) for p in pts]
            ys = [p.ratio for p in pts]
            ax.plot(xs, ys, marker="o", label=m, lw=2.2 if "ours" in m else 1.2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("compression ratio vs raw uint16")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
