"""A pytest plugin for comparing pcdcodec's codecs on your own RGB-D data with pytest-benchmark.

It is registered by installing pcdcodec (``pytest11`` entry point); ``-p
pcdcodec.bench.pytest_plugin`` loads it from a source tree. It adds:

* options: ``--pcdcodec-data [NAME=]PATH`` (repeatable: a folder, a ``.pcdc`` recording or any
  input :func:`pcdcodec.open_source` reads; the bundled sample when none is given),
  ``--pcdcodec-frames N`` (consecutive frames per sequence, 10 by default),
  ``--pcdcodec-depth-scale S`` (for inputs that do not say) and ``--pcdcodec-codecs a,b``
  (only these codecs);
* fixtures: ``rgbd_sequence`` (an :class:`~pcdcodec.RGBDSequence`, one test per input),
  ``depth_codec`` and ``color_codec`` (one test per available codec of the kind, or per codec of
  a ``@pytest.mark.pcdcodec_codecs("zstd", {"id": "jpegxl", "effort": 3})`` marker);
* helpers that measure a codec on a sequence and keep ratio, bytes per frame, PSNR and the
  largest depth error in the benchmark's ``extra_info``: :func:`record_depth`,
  :func:`record_color`, and :func:`bench_depth` / :func:`bench_color`, which also time it;
* a summary after the timed run: those columns beside the median times per frame.

A whole benchmark file::

    from pcdcodec.testing import bench_color, bench_depth

    def test_depth(benchmark, rgbd_sequence, depth_codec):
        bench_depth(benchmark, depth_codec, rgbd_sequence, op="encode")

    def test_color(benchmark, rgbd_sequence, color_codec):
        bench_color(benchmark, color_codec, rgbd_sequence, op="encode")

run as ``pytest bench_mine.py --pcdcodec-data ~/data/office --benchmark-only``.
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any

import numpy as np
import pytest

__all__ = [
    "DataSpec",
    "add_data",
    "bench_color",
    "bench_depth",
    "codec_label",
    "format_summary",
    "load_rgbd",
    "record_color",
    "record_depth",
]

_INFO_KEY = "pcdcodec"
_MARKER = "pcdcodec_codecs"


@dataclass(frozen=True)
class DataSpec:
    """One input to benchmark on: a name for the tables, a path, and options for the reader."""

    name: str
    path: Path | None  # None: the bundled sample
    options: dict[str, Any] = field(default_factory=dict)


_added = pytest.StashKey[list[DataSpec]]()
_cache: dict[tuple[str, str, str, int], Any] = {}


def add_data(
    config: pytest.Config, name: str, path: str | os.PathLike[str], **options: Any
) -> None:
    """Add an input from a ``conftest.py`` (in ``pytest_configure``); ``--pcdcodec-data`` on the
    command line takes the place of every added one. ``options`` go to the reader (for
    example ``depth_scale``)."""
    config.stash.setdefault(_added, []).append(DataSpec(name, Path(path), dict(options)))


def load_rgbd(
    path: str | os.PathLike[str] | None,
    frames: int = 10,
    *,
    name: str | None = None,
    **options: Any,
) -> Any:
    """The first ``frames`` frames of an input as an :class:`~pcdcodec.RGBDSequence`.

    ``path`` is a ``.pcdc`` recording, or anything :func:`pcdcodec.open_source` reads (options
    go to it); ``None`` is the bundled sample.
    """
    from ..datasets import RGBDSequence, load_sample
    from ..errors import InputError

    if frames < 1:
        raise InputError(f"frames must be at least 1, got {frames}")
    if path is None:
        seq = load_sample(max_frames=frames)
        seq.name = name or "sample"
        return seq
    p = Path(path)
    if p.is_file() and p.read_bytes()[:8] == b"\x89MCAP0\r\n":
        from ..recording import Recording

        with Recording(p) as rec:
            items = [rec[i] for i in range(min(frames, len(rec)))]
            return RGBDSequence(items, rec.intrinsics, rec.depth_scale, name=name or p.stem)
    from ..sources import open_source

    with open_source(p, **options) as source:
        items = list(islice(iter(source), frames))
        return RGBDSequence(items, source.intrinsics, source.depth_scale, name=name or p.name)


def codec_label(codec: Any) -> str:
    """The codec's name, followed by the parameters that differ from its defaults."""
    config = codec.get_config()
    try:
        defaults = type(codec)().get_config()
    except Exception:  # a codec without defaults: show nothing extra
        defaults = config
    diff = [f"{k}={v}" for k, v in config.items() if k != "id" and defaults.get(k) != v]
    return f"{codec.name}({','.join(diff)})" if diff else str(codec.name)


def _mark(benchmark: Any, kind: str, codec: Any, sequence: Any, **values: Any) -> None:
    benchmark.extra_info.update(
        {
            _INFO_KEY: kind,
            "codec": codec_label(codec),
            "sequence": sequence.name or "sequence",
            "frames": len(sequence),
            **values,
        }
    )


def record_depth(benchmark: Any, codec: Any, sequence: Any) -> list[bytes]:
    """Encode and decode every depth frame of ``sequence`` with ``codec``; keep the ratio
    against raw depth, bytes per frame and the largest absolute depth error (depth units;
    metres for float32 depth) in ``benchmark.extra_info``. A lossless codec that does not give
    the depth back bit-exact fails the test. Returns the encoded frames."""
    depths = [f.depth for f in sequence]
    encoded = [codec.encode(d) for d in depths]
    worst = 0.0
    for depth, data in zip(depths, encoded, strict=True):
        back = codec.decode(data)
        if getattr(codec, "lossless", True):
            assert back.dtype == depth.dtype
            np.testing.assert_array_equal(back, depth, err_msg=f"{codec.name} is not lossless")
        err = np.abs(back.astype(np.float64) - depth.astype(np.float64))
        worst = max(worst, float(np.nanmax(err, initial=0.0)))
    size = sum(len(b) for b in encoded)
    _mark(
        benchmark,
        "depth",
        codec,
        sequence,
        ratio=round(sum(d.nbytes for d in depths) / size, 3),
        bytes_per_frame=size / len(depths),
        max_depth_error=worst,
    )
    return encoded


def record_color(benchmark: Any, codec: Any, sequence: Any) -> tuple[list[Any], bytes | None]:
    """Encode the color frames of ``sequence`` as one stream with ``codec``, decode it, and keep
    the ratio against raw RGB, bytes per frame and the mean PSNR (dB; ``inf`` when lossless) in
    ``benchmark.extra_info``. Returns ``(packets, extradata)``."""
    from ..color import decode_packets, encode_frames
    from ..metrics import psnr

    colors = [f.color for f in sequence if f.color is not None]
    assert colors, f"{sequence.name!r} has no color frames"
    packets, extradata = encode_frames(codec, colors)
    h, w = colors[0].shape[:2]
    decoded = decode_packets(codec, packets, w, h, extradata)
    assert len(decoded) == len(colors), f"{codec.name} gave back {len(decoded)} frames"
    quality = float(np.mean([psnr(c, d.rgb) for c, d in zip(colors, decoded, strict=True)]))
    size = sum(len(p.data) for p in packets)
    _mark(
        benchmark,
        "color",
        codec,
        sequence,
        ratio=round(sum(c.nbytes for c in colors) / size, 3),
        bytes_per_frame=size / len(colors),
        psnr=quality if math.isfinite(quality) else "inf",
    )
    return packets, extradata


def bench_depth(benchmark: Any, codec: Any, sequence: Any, op: str = "encode") -> Any:
    """:func:`record_depth`, then time ``op`` (``"encode"`` or ``"decode"``) of the middle
    frame; the summary reports the median per frame."""
    encoded = record_depth(benchmark, codec, sequence)
    middle = len(encoded) // 2
    benchmark.group = f"depth {op} {sequence.name}"
    benchmark.extra_info.update(op=op, frames_per_call=1)
    if op == "encode":
        return benchmark(codec.encode, sequence[middle].depth)
    if op == "decode":
        return benchmark(codec.decode, encoded[middle])
    raise ValueError(f"op must be 'encode' or 'decode', got {op!r}")


def bench_color(
    benchmark: Any, codec: Any, sequence: Any, op: str = "encode", rounds: int = 3
) -> Any:
    """:func:`record_color`, then time ``op`` over the whole run of frames (a video codec keeps
    state across frames); the summary reports the median divided by the frame count."""
    from ..color import decode_packets, encode_frames

    packets, extradata = record_color(benchmark, codec, sequence)
    colors = [f.color for f in sequence if f.color is not None]
    benchmark.group = f"color {op} {sequence.name} ({len(colors)} frames per round)"
    benchmark.extra_info.update(op=op, frames_per_call=len(colors))
    if op == "encode":
        return benchmark.pedantic(encode_frames, args=(codec, colors), rounds=rounds)
    if op == "decode":
        h, w = colors[0].shape[:2]
        args = (codec, packets, w, h, extradata)
        return benchmark.pedantic(decode_packets, args=args, rounds=rounds)
    raise ValueError(f"op must be 'encode' or 'decode', got {op!r}")


# -- pytest hooks ----------------------------------------------------------------------------


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("pcdcodec", "pcdcodec codec comparisons")
    group.addoption(
        "--pcdcodec-data",
        action="append",
        default=[],
        metavar="[NAME=]PATH",
        help="RGB-D input for the rgbd_sequence fixture (repeatable); default: bundled sample",
    )
    group.addoption(
        "--pcdcodec-frames",
        type=int,
        default=10,
        metavar="N",
        help="consecutive frames read from each input (default 10)",
    )
    group.addoption(
        "--pcdcodec-depth-scale",
        type=float,
        default=None,
        metavar="S",
        help="depth units per metre, for inputs that do not say",
    )
    group.addoption(
        "--pcdcodec-codecs",
        default=None,
        metavar="A,B",
        help="compare only these codec names (depth_codec and color_codec fixtures)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{_MARKER}(*codecs): the codec names or configs the depth_codec / color_codec "
        "fixtures take in this test (default: every available codec of the kind)",
    )


def _specs(config: pytest.Config) -> list[DataSpec]:
    given = config.getoption("pcdcodec_data") or []
    scale = config.getoption("pcdcodec_depth_scale")
    options = {"depth_scale": scale} if scale else {}
    if given:
        specs = []
        for entry in given:
            name, sep, path = entry.partition("=")
            if not sep:
                name, path = Path(entry).name or entry, entry
            if not Path(path).exists():
                raise pytest.UsageError(f"--pcdcodec-data: {path!r} does not exist")
            specs.append(DataSpec(name, Path(path), options))
        return specs
    return config.stash.get(_added, None) or [DataSpec("sample", None)]


def _codec_params(metafunc: pytest.Metafunc, kind: str) -> list[Any]:
    from ..color.base import StreamCodec
    from ..registry import codec_class, list_codecs

    marker = metafunc.definition.get_closest_marker(_MARKER)
    if marker is not None:
        return list(marker.args)
    names = list_codecs(kind, available_only=True)
    if kind == "color":
        names = [n for n in names if issubclass(codec_class(n), StreamCodec)]
    only = metafunc.config.getoption("pcdcodec_codecs")
    if only:
        wanted = [n.strip() for n in only.split(",") if n.strip()]
        names = [n for n in names if n in wanted]
    return names


def _param_id(spec: Any) -> str:
    return spec if isinstance(spec, str) else str(spec.get("id", spec))


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "rgbd_sequence" in metafunc.fixturenames:
        specs = _specs(metafunc.config)
        metafunc.parametrize(
            "rgbd_sequence", specs, ids=[s.name for s in specs], indirect=True, scope="session"
        )
    for kind in ("depth", "color"):
        argname = f"{kind}_codec"
        if argname in metafunc.fixturenames:
            params = _codec_params(metafunc, kind)
            metafunc.parametrize(argname, params, ids=[_param_id(p) for p in params], indirect=True)


@pytest.fixture(scope="session")
def rgbd_sequence(request: pytest.FixtureRequest) -> Any:
    """The input's first ``--pcdcodec-frames`` frames, an :class:`~pcdcodec.RGBDSequence`."""
    spec: DataSpec = getattr(request, "param", DataSpec("sample", None))
    frames = int(request.config.getoption("pcdcodec_frames"))
    key = (spec.name, str(spec.path), repr(sorted(spec.options.items())), frames)
    if key not in _cache:
        _cache[key] = load_rgbd(spec.path, frames, name=spec.name, **spec.options)
    return _cache[key]


def _codec_fixture(request: pytest.FixtureRequest, kind: str) -> Any:
    from ..registry import get_codec

    spec = getattr(request, "param", None)
    if spec is None:
        raise pytest.UsageError(f"{kind}_codec is parametrised by the pcdcodec plugin")
    codec = get_codec(spec, kind=kind)
    if not codec.is_available():
        pytest.skip(f"{kind} codec {codec.name!r} is not available here")
    return codec


@pytest.fixture
def depth_codec(request: pytest.FixtureRequest) -> Any:
    """A depth codec: one test per available codec, or per ``pcdcodec_codecs`` marker entry."""
    return _codec_fixture(request, "depth")


@pytest.fixture
def color_codec(request: pytest.FixtureRequest) -> Any:
    """A color stream codec: one test per available codec, or per marker entry."""
    return _codec_fixture(request, "color")


def _fmt_ms(row: dict[str, Any], op: str) -> str:
    return f"{row[op]:9.2f}" if op in row else f"{'':>9}"


def summary_rows(benchmarks: Sequence[Any], kind: str) -> dict[tuple[str, str], dict[str, Any]]:
    """Rows by (sequence, codec label) of the benchmarks the helpers marked with ``kind``:
    their ``extra_info`` plus ``encode``/``decode`` median ms per frame."""
    rows: dict[tuple[str, str], dict[str, Any]] = defaultdict(dict)
    for bench in benchmarks:
        info = bench.extra_info
        if info.get(_INFO_KEY) != kind or bench.stats is None:
            continue
        row = rows[(info["sequence"], info["codec"])]
        row.update(info)
        if "op" in info:
            row[info["op"]] = bench.stats.median * 1000 / max(1, info.get("frames_per_call", 1))
    return rows


def format_summary(benchmarks: Sequence[Any]) -> list[str]:
    """The summary tables as lines (empty when no benchmark used the helpers)."""
    lines: list[str] = []
    depth = summary_rows(benchmarks, "depth")
    if depth:
        errors = {row.get("max_depth_error", 0.0) for row in depth.values()}
        show_error = errors != {0.0}
        lines += ["", "depth codecs: ratio against raw depth, median ms per frame"]
        head = f"| {'sequence':18} | {'codec':22} | {'ratio':>6} | {'KiB/frame':>9} |"
        rule = f"|{'-' * 20}|{'-' * 24}|{'-' * 8}|{'-' * 11}|"
        if show_error:
            head += f" {'max err':>8} |"
            rule += f"{'-' * 10}|"
        lines += [head + f" {'encode ms':>9} | {'decode ms':>9} |", rule + f"{'-' * 11}|" * 2]
        for (sequence, codec), row in sorted(depth.items()):
            line = (
                f"| {sequence:18} | {codec:22} | {row['ratio']:6.2f} "
                f"| {row['bytes_per_frame'] / 1024:9.1f} |"
            )
            if show_error:
                line += f" {row.get('max_depth_error', 0.0):8.4g} |"
            lines.append(line + f" {_fmt_ms(row, 'encode')} | {_fmt_ms(row, 'decode')} |")
        if not show_error:
            lines.append("every depth codec gave the depth back bit-exact (max error 0)")
    color = summary_rows(benchmarks, "color")
    if color:
        lines += ["", "color codecs: ratio against raw RGB24, mean PSNR, median ms per frame"]
        lines.append(
            f"| {'sequence':18} | {'codec':22} | {'ratio':>6} | {'KiB/frame':>9} "
            f"| {'PSNR dB':>7} | {'encode ms':>9} | {'decode ms':>9} |"
        )
        lines.append(
            f"|{'-' * 20}|{'-' * 24}|{'-' * 8}|{'-' * 11}|{'-' * 9}|{'-' * 11}|{'-' * 11}|"
        )
        for (sequence, codec), row in sorted(color.items()):
            quality = row["psnr"]
            q = f"{quality:7.2f}" if isinstance(quality, float) else f"{quality!s:>7}"
            lines.append(
                f"| {sequence:18} | {codec:22} | {row['ratio']:6.1f} "
                f"| {row['bytes_per_frame'] / 1024:9.1f} | {q} | {_fmt_ms(row, 'encode')} "
                f"| {_fmt_ms(row, 'decode')} |"
            )
    return lines


@pytest.hookimpl(trylast=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    session = getattr(config, "_benchmarksession", None)
    if session is None or getattr(session, "disabled", False):
        return
    for line in format_summary(session.benchmarks):
        terminalreporter.write_line(line)
