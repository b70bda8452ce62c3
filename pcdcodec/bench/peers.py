"""Comparison rows against peer libraries from PyPI, for the evaluation report.

Each peer runs a whole sequence through another library and gives back one
:class:`PeerResult` row (size, median time per frame, error), so ``pcdcodec bench`` can print it
next to pcdcodec's own codecs. The peers are optional, installed with
``pip install "pcdcodec[peers]"``, and imported only when a peer function runs:

* ``"draco"`` (:func:`draco_cloud`): Google Draco point cloud compression through the
  `DracoPy <https://pypi.org/project/DracoPy/>`_ package, the codec behind ROS
  ``point_cloud_transport``'s ``draco`` plugin. It codes the back-projected cloud itself
  (points and colors), so it is the point-cloud-native baseline. It quantizes positions, so it
  is lossy.
* ``"rvl-pypi"`` (:func:`rvl_package_depth`): the `rvl <https://pypi.org/project/rvl/>`_
  package, C bindings of Wilson's RVL depth compression. It is lossless and checked against
  pcdcodec's own :class:`~pcdcodec.depth.rvl.RVL`: its output is a 4-byte little-endian pixel
  count followed by an RVL bitstream, and that bitstream is compared byte for byte with ours.

A missing package raises :class:`~pcdcodec.CodecUnavailableError` with the install command;
:func:`available_peers` says up front which peers can run.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt

from .._validate import check_depth
from ..depth.rvl import RVL
from ..errors import CodecUnavailableError, DecodeError, InputError, InputTypeError
from ..geometry.projector import Projector
from ..metrics import point_to_point

__all__ = [
    "PEERS",
    "PeerResult",
    "available_peers",
    "draco_cloud",
    "draco_error_bound_m",
    "draco_quantization_step_m",
    "evaluate_peers",
    "rvl_package_depth",
]

_INSTALL_HINT = 'pip install "pcdcodec[peers]"'


@dataclass(frozen=True)
class _Peer:
    """A peer library: the module to import and the PyPI distribution that provides it."""

    module: str
    distribution: str


#: Peer name -> the package it needs.
PEERS: dict[str, _Peer] = {
    "draco": _Peer(module="DracoPy", distribution="DracoPy"),
    "rvl-pypi": _Peer(module="rvl", distribution="rvl"),
}


@dataclass(frozen=True)
class PeerResult:
    """One comparison row: a peer library run over a sequence of frames.

    Sizes are in bytes and averaged over frames; times are medians over frames in milliseconds
    (``time.perf_counter`` around the peer's own encode or decode call, including the
    conversion of its output to numpy arrays but not the error measurement).
    """

    #: Peer name, a key of :data:`PEERS` (``"draco"`` or ``"rvl-pypi"``).
    name: str
    #: What the peer codes: ``"cloud"`` (points and colors) or ``"depth"`` (uint16 images).
    kind: str
    #: The package that did the work, ``"<distribution> <version>"``.
    package: str
    #: Number of frames coded.
    frames: int
    #: Mean encoded size per frame, bytes.
    bytes_per_frame: float
    #: Mean size per frame of what was coded, uncompressed: N × 15 bytes for a colored cloud
    #: (three float32 coordinates and three uint8 colors per point, N × 12 without colors),
    #: H × W × 2 bytes for a uint16 depth image.
    raw_bytes_per_frame: float
    #: Median encode time per frame, milliseconds.
    encode_ms: float
    #: Median decode time per frame, milliseconds.
    decode_ms: float
    #: True when every frame came back exactly (positions, colors or depth values).
    lossless: bool
    #: Largest position error over all frames, metres (0.0 when lossless).
    max_error_m: float
    #: Root mean square position error over all points of all frames, metres.
    rmse_m: float
    #: For a peer that should write the same bitstream as a pcdcodec codec: whether it did on
    #: every frame. ``None`` where no such comparison applies.
    matches_pcdcodec: bool | None
    #: Settings, how the error was measured, and anything a reader of the report should know.
    notes: str
    #: The peer's settings as plain JSON values.
    settings: dict[str, Any] = field(default_factory=dict, hash=False)

    @property
    def ratio(self) -> float:
        """Compression ratio: raw size over encoded size."""
        return self.raw_bytes_per_frame / self.bytes_per_frame


def _import_peer(name: str) -> tuple[ModuleType, str]:
    """Import the package of peer ``name``; return it and ``"<distribution> <version>"``."""
    peer = PEERS[name]
    try:
        module = importlib.import_module(peer.module)
    except ImportError as exc:
        raise CodecUnavailableError(
            f"peer {name!r} needs the {peer.distribution} package, which could not be imported "
            f"({exc}); install it with {_INSTALL_HINT} or pip install {peer.distribution}"
        ) from exc
    try:
        version = importlib.metadata.version(peer.distribution)
    except importlib.metadata.PackageNotFoundError:
        version = str(getattr(module, "__version__", "unknown version"))
    return module, f"{peer.distribution} {version}"


def available_peers() -> dict[str, str | None]:
    """Which peers can run: peer name -> ``None`` when usable, else the reason and the fix."""
    status: dict[str, str | None] = {}
    for name in PEERS:
        try:
            _import_peer(name)
        except CodecUnavailableError as exc:
            status[name] = str(exc)
        else:
            status[name] = None
    return status


# -- Draco -------------------------------------------------------------------------------


def draco_quantization_step_m(points: npt.ArrayLike, quantization_bits: int) -> float:
    """Draco's position quantization step for ``points``, in the points' units (metres).

    Draco maps each coordinate onto ``2 ** quantization_bits - 1`` equal steps spanning the
    largest side of the cloud's axis-aligned bounding box (the same step on all three axes), so
    the step is ``extent / (2 ** quantization_bits - 1)``. For a TUM frame about 2.1 m across,
    14 bits give a 0.13 mm step, 11 bits 1.0 mm, 16 bits 0.032 mm; TUM's depth unit is 0.2 mm.
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise InputError(f"points must have shape (N, 3) with N > 0, got {arr.shape}")
    bits = _int_in_range(quantization_bits, "quantization_bits", 1, 30)
    extent = float(np.ptp(arr, axis=0).max())
    if extent == 0.0:
        extent = 1.0  # Draco's own choice for a cloud of one repeated point
    return extent / float((1 << bits) - 1)


def draco_error_bound_m(points: npt.ArrayLike, quantization_bits: int) -> float:
    """The largest distance a point of ``points`` can move through Draco's quantization, metres.

    Each coordinate is rounded to the nearest step, so it moves by at most half a step, and a
    point by at most ``sqrt(3) / 2`` steps; two float32 spacings of the largest coordinate are
    added for the float32 arithmetic of quantizing and dequantizing.
    """
    step = draco_quantization_step_m(points, quantization_bits)
    largest = float(np.abs(np.asarray(points, dtype=np.float64)).max())
    slack = 2.0 * float(np.spacing(np.float32(largest)))
    return math.sqrt(3.0) * (step / 2.0 + slack)


def draco_cloud(
    depth_frames: Sequence[Any],
    color_frames: Sequence[Any] | None,
    projector: Projector,
    *,
    quantization_bits: int = 14,
    compression_level: int = 7,
    preserve_order: bool = False,
) -> PeerResult:
    """Code each frame's point cloud with Draco (DracoPy) and measure size, time and error.

    Each depth frame (with its color frame, when ``color_frames`` is given) is back-projected
    with ``projector.to_points`` to N × 3 float32 metres and N × 3 uint8 colors, encoded with
    ``DracoPy.encode`` and decoded with ``DracoPy.decode``.

    Settings:

    * ``quantization_bits`` (1-30): position precision; see :func:`draco_quantization_step_m`.
      At the default 14 the step is the cloud's extent / 16383, 0.13 mm for a 2.1 m wide
      frame, and no point moves more than ``sqrt(3) / 2`` steps (0.11 mm). Colors are uint8
      and coded without loss.
    * ``compression_level`` (0-10): DracoPy sets Draco's encode and decode speed to
      ``10 - compression_level``. 7 is Draco's command-line default; ROS's ``draco`` plugin
      defaults to speed 7, i.e. ``compression_level=3``.
    * ``preserve_order``: ``False`` lets Draco pick its method, which for a quantized cloud is
      the k-d tree coder (as the ROS plugin does with ``encode_method`` 0); it reorders the
      points, so errors are nearest-neighbour distances (:func:`pcdcodec.metrics.point_to_point`:
      symmetric Hausdorff and RMSE, which can only understate the per-point error) and colors
      are compared as multisets. ``True`` makes DracoPy use the sequential coder, which keeps
      the order, so errors are exact per-point distances and colors are compared per point.

    Raises :class:`~pcdcodec.CodecUnavailableError` without DracoPy;
    :class:`~pcdcodec.InputTypeError` for a projector that is not a
    :class:`~pcdcodec.Projector` or a non-integer setting; :class:`~pcdcodec.InputError` for no
    frames, frame counts that differ, a setting out of range or a frame without valid depth
    (Draco cannot code an empty cloud); whatever ``projector.to_points`` raises for a bad frame;
    and :class:`~pcdcodec.DecodeError` when Draco fails or gives back a different number of
    points.
    """
    draco, package = _import_peer("draco")
    if not isinstance(projector, Projector):
        raise InputTypeError(
            f"projector must be a pcdcodec.Projector, got {type(projector).__name__}"
        )
    bits = _int_in_range(quantization_bits, "quantization_bits", 1, 30)
    level = _int_in_range(compression_level, "compression_level", 0, 10)
    if not isinstance(preserve_order, (bool, np.bool_)):
        raise InputTypeError(
            f"preserve_order must be a bool, got {type(preserve_order).__name__} {preserve_order!r}"
        )
    depths = _frames(depth_frames, "depth_frames")
    colors: list[Any] | None = None
    if color_frames is not None:
        colors = _frames(color_frames, "color_frames")
        if len(colors) != len(depths):
            raise InputError(
                f"color_frames has {len(colors)} frames and depth_frames {len(depths)}; "
                "they must pair up"
            )

    sizes: list[int] = []
    raw_sizes: list[int] = []
    enc_ms: list[float] = []
    dec_ms: list[float] = []
    max_err = 0.0
    sq_sum = 0.0
    n_total = 0
    colors_exact = True
    worst_bound = 0.0
    for i, depth in enumerate(depths):
        points, rgb = projector.to_points(depth, None if colors is None else colors[i])
        n = points.shape[0]
        if n == 0:
            raise InputError(
                f"depth_frames[{i}] has no valid depth pixels; Draco cannot code an empty cloud"
            )
        t0 = time.perf_counter()
        try:
            data = draco.encode(
                points,
                quantization_bits=bits,
                compression_level=level,
                preserve_order=bool(preserve_order),
                colors=rgb,
            )
        except Exception as exc:  # DracoPy raises ValueError, AssertionError or its own
            raise InputError(f"Draco could not encode frame {i} ({n} points): {exc}") from exc
        t1 = time.perf_counter()
        try:
            cloud = draco.decode(data)
            out_points = np.asarray(cloud.points, dtype=np.float32).reshape(-1, 3)
            out_colors = None if rgb is None else np.asarray(cloud.colors).reshape(-1, 3)
        except Exception as exc:
            raise DecodeError(f"Draco could not decode its own frame {i}: {exc}") from exc
        t2 = time.perf_counter()
        if out_points.shape[0] != n or (out_colors is not None and out_colors.shape[0] != n):
            raise DecodeError(
                f"Draco gave back {out_points.shape[0]} points for frame {i}, which had {n}"
            )
        sizes.append(len(data))
        raw_sizes.append(n * (12 + (0 if rgb is None else 3)))
        enc_ms.append((t1 - t0) * 1e3)
        dec_ms.append((t2 - t1) * 1e3)
        worst_bound = max(worst_bound, draco_error_bound_m(points, bits))

        if preserve_order:
            dist = np.linalg.norm(out_points.astype(np.float64) - points.astype(np.float64), axis=1)
            max_err = max(max_err, float(dist.max()))
            sq_sum += float(np.dot(dist, dist))
            if rgb is not None and out_colors is not None and not np.array_equal(out_colors, rgb):
                colors_exact = False
        else:
            d1 = point_to_point(points, out_points)
            max_err = max(max_err, d1.hausdorff)
            sq_sum += d1.mse * n
            if rgb is not None and out_colors is not None:
                colors_exact &= np.array_equal(_sorted_rgb(out_colors), _sorted_rgb(rgb))
        n_total += n

    method = "sequential (order kept)" if preserve_order else "k-d tree (points reordered)"
    error_kind = (
        "per-point distances"
        if preserve_order
        else "nearest-neighbour distances (symmetric Hausdorff / D1 RMSE)"
    )
    if colors is None:
        color_note = "no colors"
    elif colors_exact:
        color_note = "uint8 colors exact" + ("" if preserve_order else " (as a multiset)")
    else:
        color_note = "uint8 colors changed"
    notes = (
        f"Draco {method}, quantization_bits={bits} (step = extent / {(1 << bits) - 1}, "
        f"error bound {worst_bound * 1e3:.4f} mm on these frames), compression_level={level} "
        f"(Draco speed {10 - level}); errors are {error_kind}; {color_note}"
    )
    return PeerResult(
        name="draco",
        kind="cloud",
        package=package,
        frames=len(depths),
        bytes_per_frame=statistics.fmean(sizes),
        raw_bytes_per_frame=statistics.fmean(raw_sizes),
        encode_ms=statistics.median(enc_ms),
        decode_ms=statistics.median(dec_ms),
        lossless=max_err == 0.0 and colors_exact,
        max_error_m=max_err,
        rmse_m=math.sqrt(sq_sum / n_total),
        matches_pcdcodec=None,
        notes=notes,
        settings={
            "quantization_bits": bits,
            "compression_level": level,
            "preserve_order": bool(preserve_order),
            "colors": colors is not None,
        },
    )


def _sorted_rgb(rgb: npt.NDArray[Any]) -> npt.NDArray[np.uint32]:
    """Colors packed into one integer each and sorted, to compare two clouds' colors as sets."""
    c = rgb.astype(np.uint32)
    packed: npt.NDArray[np.uint32] = np.sort((c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2])
    return packed


# -- RVL (PyPI package) ------------------------------------------------------------------


def rvl_package_depth(depth_frames: Sequence[Any], *, depth_scale: float = 1000.0) -> PeerResult:
    """Code each uint16 depth frame with the ``rvl`` package and check it against ours.

    Each frame is compressed with ``rvl.compress`` and decompressed with ``rvl.decompress``;
    the result must equal the input bit for bit. The package writes a 4-byte little-endian pixel
    count and then the RVL bitstream; that bitstream is compared with the body of pcdcodec's own
    :class:`~pcdcodec.depth.rvl.RVL` codec, and :attr:`PeerResult.matches_pcdcodec` says whether
    all frames were byte-identical. ``bytes_per_frame`` counts the package's whole output.

    ``depth_scale`` (depth units per metre) only turns a depth error into metres, should a
    frame not come back exactly.

    The package's decoder trusts its input: it reads past the end of truncated data and can
    crash on corrupt data, so this function only ever decodes what the package just encoded.

    Raises :class:`~pcdcodec.CodecUnavailableError` without the package;
    :class:`~pcdcodec.InputError` for no frames or a frame that is not 2-D;
    :class:`~pcdcodec.InputTypeError` for a frame that is not uint16; and
    :class:`~pcdcodec.DecodeError` when the package rejects its own output.
    """
    rvl, package = _import_peer("rvl-pypi")
    if isinstance(depth_scale, (bool, np.bool_)) or not isinstance(depth_scale, (int, float)):
        raise InputTypeError(
            f"depth_scale must be a number (depth units per metre), got "
            f"{type(depth_scale).__name__} {depth_scale!r}"
        )
    if not (math.isfinite(depth_scale) and depth_scale > 0):
        raise InputError(f"depth_scale must be positive and finite, got {depth_scale!r}")
    frames = [
        check_depth(d, allowed=("uint16",), name=f"depth_frames[{i}]")
        for i, d in enumerate(_frames(depth_frames, "depth_frames"))
    ]

    ours = RVL()
    sizes: list[int] = []
    enc_ms: list[float] = []
    dec_ms: list[float] = []
    exact = True
    identical = True
    max_units = 0
    sq_sum = 0.0
    differing: list[int] = []
    for i, depth in enumerate(frames):
        t0 = time.perf_counter()
        # The package takes the raw bytes of little-endian uint16 pixels, which check_depth gave.
        data = rvl.compress(depth.data.cast("B"))
        t1 = time.perf_counter()
        try:
            raw = rvl.decompress(data)
        except ValueError as exc:
            raise DecodeError(f"rvl could not decompress its own frame {i}: {exc}") from exc
        back = np.frombuffer(raw, dtype="<u2")
        t2 = time.perf_counter()
        sizes.append(len(data))
        enc_ms.append((t1 - t0) * 1e3)
        dec_ms.append((t2 - t1) * 1e3)

        if back.size != depth.size:
            raise DecodeError(
                f"rvl gave back {back.size} pixels for frame {i}, which has {depth.size}"
            )
        diff = np.abs(back.astype(np.float64) - depth.reshape(-1))
        if diff.any():
            exact = False
            max_units = max(max_units, int(diff.max()))
            sq_sum += float(np.dot(diff, diff))
        header_ok = data[:4] == depth.size.to_bytes(4, "little")
        if not (header_ok and data[4:] == ours._encode_body(depth)):
            identical = False
            differing.append(i)

    n_pixels = sum(f.size for f in frames)
    if identical:
        match_note = (
            f"bitstream after the 4-byte pixel count byte-identical to pcdcodec's RVL body on "
            f"all {len(frames)} frames"
        )
    else:
        match_note = f"bitstream differs from pcdcodec's RVL body on frames {differing}"
    return PeerResult(
        name="rvl-pypi",
        kind="depth",
        package=package,
        frames=len(frames),
        bytes_per_frame=statistics.fmean(sizes),
        raw_bytes_per_frame=statistics.fmean(f.size * 2 for f in frames),
        encode_ms=statistics.median(enc_ms),
        decode_ms=statistics.median(dec_ms),
        lossless=exact,
        max_error_m=max_units / depth_scale,
        rmse_m=math.sqrt(sq_sum / n_pixels) / depth_scale,
        matches_pcdcodec=identical,
        notes=(
            "RVL (Wilson 2017) via the rvl package: 4-byte little-endian pixel count + RVL "
            f"bitstream; {'bit-exact round trip' if exact else 'NOT bit-exact'}; {match_note}"
        ),
        settings={},
    )


# -- shared checks -----------------------------------------------------------------------


def _frames(frames: Any, name: str) -> list[Any]:
    """A non-empty list of the frames in ``frames`` (a sequence, not one array)."""
    if isinstance(frames, np.ndarray) and frames.ndim < 3:
        raise InputError(
            f"{name} must be a sequence of frames, got one array of shape {frames.shape}; "
            f"wrap a single frame in a list"
        )
    try:
        out = list(frames)
    except TypeError as exc:
        raise InputTypeError(
            f"{name} must be a sequence of frames, got {type(frames).__name__}"
        ) from exc
    if not out:
        raise InputError(f"{name} is empty; give at least one frame")
    return out


def _int_in_range(value: Any, name: str, low: int, high: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputTypeError(f"{name} must be an int, got {type(value).__name__} {value!r}")
    if not low <= int(value) <= high:
        raise InputError(f"{name} must be in {low}..{high}, got {int(value)}")
    return int(value)


def evaluate_peers(
    frames: Sequence[Any], intrinsics: Any, depth_scale: float, *, max_frames: int = 5
) -> list[dict[str, Any]]:
    """The peer rows of :func:`pcdcodec.evaluate`: every installed peer on the same frames.

    Draco runs in its default k-d tree mode (as ROS point_cloud_transport's draco plugin) and
    in sequential mode, at 14 quantization bits; both code whole colored clouds, so their size
    compares with a color + depth stream. The RVL package codes depth. Peers that are not
    installed are left out. At most ``max_frames`` frames are used: Draco is slow.
    """
    chosen = list(frames)[:max_frames]
    depths = [f.depth for f in chosen]
    colors = [f.color for f in chosen]
    rows: list[PeerResult] = []
    available = available_peers()
    if available.get("draco") is None and intrinsics is not None:
        projector = Projector(intrinsics, depth_scale=depth_scale)
        for preserve in (False, True):
            rows.append(draco_cloud(depths, colors, projector, preserve_order=preserve))
    if available.get("rvl-pypi") is None:
        rows.append(rvl_package_depth(depths, depth_scale=depth_scale))
    return [
        {
            "name": r.name,
            "kind": r.kind,
            "package": r.package,
            "bytes_per_frame": r.bytes_per_frame,
            "encode_ms": r.encode_ms,
            "decode_ms": r.decode_ms,
            "lossless": r.lossless,
            "max_error_m": r.max_error_m,
            "notes": r.notes,
        }
        for r in rows
    ]
