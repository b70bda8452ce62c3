"""Comparing codecs on a sequence: sizes, ratios, speeds and quality, as tables and plots.

:func:`evaluate` encodes and decodes a sequence with each chosen depth and color codec and
returns an :class:`Evaluation` (:mod:`pcdcodec.bench.report`), which writes a Markdown report
laid out like the tables of the compressed point cloud streams paper, CSV and JSON files, and PNG
plots (:mod:`pcdcodec.bench.plots`; matplotlib, from the ``bench`` extra). Its rows are defined
in :mod:`pcdcodec.bench.results`. ``pcdcodec bench`` is its command-line front.

Reference sizes per 640×480 frame: RGB24 color 900 KiB, uint16 depth 600 KiB, float32 depth
(ROS 32FC1, what the paper stored) 1200 KiB, and an organized PointCloud2 XYZRGB cloud at
32 bytes per point 9600 KiB.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..codec import Codec
from ..color.base import StreamCodec, decode_packets, encode_frames
from ..datasets import RGBDFrame, RGBDSequence, open_folder
from ..depth.base import FrameCodec
from ..errors import InputError
from ..geometry.camera import CameraIntrinsics
from ..geometry.projector import Projector
from ..metrics import depth_error, point_to_point, psnr, ssim
from ..recording import open as open_recording
from ..registry import codec_class, get_codec, list_codecs
from ..sources import open_source
from ..sources.base import detect_kind
from .peers import evaluate_peers
from .report import Evaluation
from .results import (
    COMPARED_COLOR_CODECS,
    POINTCLOUD2_BYTES_PER_POINT,
    RD_SETTINGS,
    ColorRow,
    DepthRow,
    RDPoint,
    StreamRow,
    rd_setting,
)
from .results import config_label as _label

__all__ = [
    "COMPARED_COLOR_CODECS",
    "POINTCLOUD2_BYTES_PER_POINT",
    "RD_SETTINGS",
    "ColorRow",
    "DepthRow",
    "Evaluation",
    "RDPoint",
    "StreamRow",
    "evaluate",
    "frames_of",
    "parse_list",
]


def _median_ms(times: list[float]) -> float:
    return 1000.0 * statistics.median(times) if times else float("nan")


def frames_of(
    source: Any,
    frames: int | None,
    intrinsics: CameraIntrinsics | None,
    depth_scale: float | None,
    *,
    need_color: bool = True,
) -> tuple[str, list[RGBDFrame], CameraIntrinsics | None, float]:
    """The name, first ``frames`` frames (all for ``None``), intrinsics and depth scale of
    ``source``: an :class:`RGBDSequence`, a folder or a file any source reads."""
    if isinstance(source, RGBDSequence):
        seq = source.frames[:frames] if frames else source.frames
        return (
            source.name or "sequence",
            list(seq),
            intrinsics or source.intrinsics,
            (depth_scale or source.depth_scale),
        )
    path = Path(source)
    if path.is_file():
        no_color = f"{str(path)!r} has no color stream to compare codecs on"
        if detect_kind(path) is not None:  # a bag or a camera recording, read as encode reads it
            options: dict[str, Any] = {}
            if intrinsics is not None:
                options["intrinsics"] = intrinsics
            if depth_scale is not None:
                options["depth_scale"] = depth_scale
            with open_source(path, **options) as src:
                taken: list[RGBDFrame] = []
                for f in src:
                    if need_color and f.color is None:
                        raise InputError(no_color)
                    taken.append(f)
                    if frames and len(taken) >= frames:
                        break
                return path.stem, taken, src.intrinsics, src.depth_scale
        with open_recording(path) as rec:
            count = min(len(rec), frames) if frames else len(rec)
            out = []
            for i in range(count):
                f = rec[i]
                if need_color and f.color is None:
                    raise InputError(no_color)
                out.append(f)
            return path.stem, out, intrinsics or rec.intrinsics, depth_scale or rec.depth_scale
    folder = open_folder(path, max_frames=frames, intrinsics=intrinsics, depth_scale=depth_scale)
    return path.name, list(folder), folder.intrinsics, folder.depth_scale


def evaluate(
    source: Any,
    *,
    depth: Sequence[str | dict[str, Any] | Codec] | None = None,
    color: Sequence[str | dict[str, Any] | Codec] | None = None,
    frames: int | None = 30,
    intrinsics: CameraIntrinsics | None = None,
    depth_scale: float | None = None,
    rd: bool = True,
    peers: bool = False,
    progress: Callable[[str], None] | None = None,
) -> Evaluation:
    """Measure depth and color codecs on a sequence.

    ``source`` is an :class:`~pcdcodec.RGBDSequence`, an RGB-D folder (as ``pcdcodec encode``
    reads) or a ``.pcdc`` recording (its decoded frames are the reference). ``depth`` and
    ``color`` name codecs or give configs (default: every available depth codec, and the
    available ones of :data:`COMPARED_COLOR_CODECS`, h264, h265 and AV1). ``frames`` limits the
    frames used (``None`` for all). ``rd`` adds the color rate-distortion sweep
    (:data:`RD_SETTINGS`, on the same frames as the color rows: the point at a codec's own
    setting is its color row); ``peers`` adds the optional peer rows
    (:mod:`pcdcodec.bench.peers`, when installed). ``progress`` is called with a short
    description of each step. Raises :class:`~pcdcodec.InputError` for an empty source or
    unknown codecs.
    """
    say = progress or (lambda _msg: None)
    name, items, cam, scale = frames_of(source, frames, intrinsics, depth_scale)
    if not items:
        raise InputError(f"{source!r} holds no frames to evaluate")
    height, width = items[0].depth.shape
    if items[0].depth.dtype != np.uint16:
        raise InputError("evaluate compares codecs on uint16 depth; this sequence is float32")
    result = Evaluation(name, len(items), width, height)
    depths = [f.depth for f in items]
    colors = [f.color for f in items if f.color is not None]
    if len(colors) != len(items):
        raise InputError(f"{name!r} has frames without color; evaluate compares color codecs too")
    depth_specs = list(depth) if depth is not None else list_codecs("depth", available_only=True)
    depth_codecs = [
        get_codec(s, kind="depth") if isinstance(s, (str, dict)) else s for s in depth_specs
    ]
    if color is None:
        available = list_codecs("color", available_only=True)
        color = [name for name in COMPARED_COLOR_CODECS if name in available]
    color_codecs = [get_codec(s, kind="color") if isinstance(s, (str, dict)) else s for s in color]
    for codec in depth_codecs:
        assert isinstance(codec, FrameCodec)
        say(f"depth {codec.name}")
        result.depth.append(_depth_row(codec, depths, scale, cam))
    for codec in color_codecs:
        if not isinstance(codec, StreamCodec):
            raise InputError(f"color codec {codec.name!r} is not a stream codec")
        say(f"color {codec.name}")
        row = _color_row(codec, colors)
        result.color.append(row)
        if rd and codec.name in RD_SETTINGS and not codec.lossless:
            result.rd.extend(_rd_curve(codec, row, colors, say))
    raw_rgbd = width * height * 5
    pc2 = result.pointcloud2_bytes_per_frame
    for c in result.color:
        for d in result.depth:
            total = c.bytes_per_frame + d.bytes_per_frame
            result.streams.append(
                StreamRow(
                    _label(c.config),  # settings that differ from the defaults show, such as
                    _label(d.config),  # a depth error bound beside the lossless row
                    total,
                    raw_rgbd / total,
                    pc2 / total,
                    c.lossless and d.exact,
                )
            )
    if peers:
        result.peers = evaluate_peers(items, cam, scale)
    return result


def _rd_curve(
    codec: StreamCodec,
    row: ColorRow,
    colors: list[npt.NDArray[np.uint8]],
    say: Callable[[str], None],
) -> list[RDPoint]:
    """``codec``'s rate-distortion points on the frames of its color row: the swept settings,
    its default and its own; the point at its own setting is ``row`` itself, so the curve
    passes through the table's row."""
    key, values = RD_SETTINGS[codec.name]
    config = codec.get_config()
    default: float = codec_class(codec.name)().get_config()[key]
    own: float = config[key]
    points = []
    for value in sorted({*values, default, own}):
        setting = rd_setting(key, value)
        if value == own:
            measured = row
        else:
            say(f"color {codec.name} {setting}")
            variant = get_codec({**config, key: value})
            assert isinstance(variant, StreamCodec)
            measured = _color_row(variant, colors, quality=False)
        points.append(RDPoint(codec.name, setting, measured.bits_per_pixel, measured.psnr))
    return points


def _depth_row(
    codec: FrameCodec,
    depths: list[npt.NDArray[Any]],
    scale: float,
    cam: CameraIntrinsics | None,
) -> DepthRow:
    enc_times, dec_times, sizes = [], [], []
    exact = True
    worst: Any = None
    for d in depths:
        t0 = time.perf_counter()
        data = codec.encode(d)
        t1 = time.perf_counter()
        back = codec.decode(data)
        t2 = time.perf_counter()
        enc_times.append(t1 - t0)
        dec_times.append(t2 - t1)
        sizes.append(len(data))
        same = bool(np.array_equal(back, d))
        exact &= same
        if not same or worst is None:
            err = depth_error(d, back, depth_scale=scale)
            if worst is None or err.rmse > worst.rmse:
                worst = err
    f32_ratio = None
    if "float32" in codec.dtypes:
        raw = 0
        packed = 0
        for d in depths:
            metres = (d / scale).astype(np.float32)
            metres[d == 0] = np.nan
            raw += metres.nbytes
            packed += len(codec.encode(metres))
        f32_ratio = raw / packed
    cloud_rmse = 0.0
    if not exact and cam is not None:
        # Exact depth rebuilds identical clouds; otherwise compare the middle frame's clouds.
        proj = Projector(cam, depth_scale=scale)
        mid = depths[len(depths) // 2]
        decoded = codec.decode(codec.encode(mid))
        cloud_rmse = point_to_point(proj.to_points(mid)[0], proj.to_points(decoded)[0]).rmse
    size = float(np.mean(sizes))
    pixels = depths[0].size
    return DepthRow(
        codec=codec.name,
        config=codec.get_config(),
        frames=len(depths),
        bytes_per_frame=size,
        ratio_uint16=pixels * 2 / size,
        ratio_float32=pixels * 4 / size,
        ratio_float32_input=f32_ratio,
        encode_ms=_median_ms(enc_times),
        decode_ms=_median_ms(dec_times),
        exact=exact,
        exact_fraction=worst.exact_fraction if worst is not None else 1.0,
        rmse_m=_units_to_m(worst, "rmse", scale),
        max_error_m=_units_to_m(worst, "max_abs_error", scale),
        edge_rmse_m=_units_to_m(worst, "edge_rmse", scale),
        interior_rmse_m=_units_to_m(worst, "interior_rmse", scale),
        cloud_rmse_m=float(cloud_rmse),
    )


def _units_to_m(err: Any, field_name: str, scale: float) -> float:
    """A depth error statistic in metres (0 where no pixel was compared)."""
    if err is None:
        return 0.0
    value = float(getattr(err, field_name))
    return 0.0 if not np.isfinite(value) else value / scale


def _color_row(
    codec: StreamCodec, colors: list[npt.NDArray[np.uint8]], *, quality: bool = True
) -> ColorRow:
    height, width = colors[0].shape[:2]
    t0 = time.perf_counter()
    packets, extradata = encode_frames(codec, colors)
    t1 = time.perf_counter()
    decoded = decode_packets(codec, packets, width, height, extradata)
    t2 = time.perf_counter()
    if len(decoded) != len(colors):
        raise InputError(f"{codec.name} gave back {len(decoded)} frames of {len(colors)}")
    size = sum(len(p.data) for p in packets) / len(colors)
    psnrs = [psnr(o, d.rgb) for o, d in zip(colors, decoded, strict=True)]
    finite = [p for p in psnrs if np.isfinite(p)]
    mean_psnr = float(np.mean(finite)) if finite else float("inf")
    ssim_value = float("nan")
    if quality:
        step = max(1, len(colors) // 8)  # SSIM is slow: eight frames spread over the run
        ssim_value = float(
            np.mean([ssim(colors[i], decoded[i].rgb) for i in range(0, len(colors), step)])
        )
    return ColorRow(
        codec=codec.name,
        config=codec.get_config(),
        frames=len(colors),
        bytes_per_frame=size,
        bits_per_pixel=8 * size / (width * height),
        ratio_rgb24=width * height * 3 / size,
        encode_ms=1000 * (t1 - t0) / len(colors),
        decode_ms=1000 * (t2 - t1) / len(colors),
        psnr=mean_psnr,
        ssim=ssim_value,
        lossless=bool(codec.lossless),
    )


def parse_list(text: str) -> list[str]:
    """``"lz4,jpegxl"`` to ``["lz4", "jpegxl"]`` (the CLI's codec lists)."""
    return [item.strip() for item in text.split(",") if item.strip()]
