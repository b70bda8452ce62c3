"""Lossless coding of 8-bit RGB images the way cameras make them.

Most RGB-D color cameras do not measure three values a pixel. Their sensor measures one,
through a Bayer filter (a 2x2 pattern of one red, two green and one blue), and the driver
fills in the other two by interpolating the neighbours ("demosaicing"). An image made that
way holds a third of the information its three bytes a pixel suggest: the Kinect v1 through
the OpenNI driver (every TUM RGB-D sequence) is one such camera.

:func:`encode` looks for that structure before coding:

- **Bayer model.** It tries the four placements of the pattern and three ways of filling in
  green (the edge-aware weighted rule of the OpenNI driver, the edge-aware rule that takes
  the flatter direction, and the plain four-neighbour mean; red and blue by the two- and
  four-neighbour means) on a sample of rows. When one rebuilds nearly every sampled pixel,
  only the measured values are coded (one byte a pixel, as four planes), with the few
  pixels the rebuild misses (the borders, a driver's own variations) as a residual.
- **Planar model** otherwise: green, red minus green and blue minus green (modulo 256), as
  three planes.

The planes are one 8-bit gray image coded by JPEG-LS (CharLS, through imagecodecs); the
residual is zstd. Every image comes back bit-exact whichever model is chosen: the model only
decides how small it gets. On TUM frames the Bayer model takes 0.39 of lossless JPEG XL's
(effort 1) bytes; on RealSense and 7-Scenes frames the planar model takes 0.85-0.87.

Layout: ``b"RGBL"``, a version byte, the model (0 planar, 1 Bayer), the Bayer placement and
green rule, height and width (uint32), then two sections (uint32 length and bytes): the
JPEG-LS planes and the zstd residual (empty when nothing is left over).
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["decode", "encode", "model_of"]

_MAGIC = b"RGBL"
_VERSION = 1
_HEAD = struct.Struct("<4sBBBBII")  # magic, version, model, phase, green rule, height, width
_PLANAR, _BAYER, _YUY2 = 0, 1, 2
#: Green filled in at a red or blue site: OpenNI's edge-aware weighted mean, the mean of the
#: flatter direction, the four-neighbour mean.
_RULES = (0, 1, 2)
#: A Bayer model is used when it rebuilds at least this share of the sampled pixels.
_MIN_MATCH = 0.95
_SAMPLE_ROWS = 16  # a band of 4 rows in every 64 is sampled when choosing the model


@njit(cache=True, nogil=True, inline="always")
def _green(u: int, d: int, left: int, right: int, rule: int) -> int:
    if rule == 2:
        return (u + d + left + right) >> 2
    dh = abs(left - right)
    dv = abs(u - d)
    if rule == 1:
        if dh > dv:
            return (u + d) >> 1
        if dv > dh:
            return (left + right) >> 1
        return (u + d + left + right) >> 2
    if dh + dv == 0:
        return (u + d + left + right) >> 2
    return ((u + d) * dh + (left + right) * dv) // (2 * (dh + dv))


@njit(cache=True, nogil=True, inline="always")
def _mirror(i: int, n: int) -> int:
    if i < 0:
        return 1 if n > 1 else 0
    if i >= n:
        return n - 2 if n > 1 else n - 1
    return i


@njit(cache=True, nogil=True)
def _rebuild_rows(
    mosaic: Any, out: Any, ry: int, rx: int, rule: int, row0: int, row_step: int
) -> None:
    """Demosaic rows ``row0, row0 + row_step, ...`` (each with the row after it) of
    ``mosaic`` into ``out`` (H x W x 3): red sites at parity ``(ry, rx)``, blue at the other
    corner, green elsewhere."""
    h, w = mosaic.shape
    for top in range(row0, h, row_step):
        for i in range(top, min(top + 2, h)):
            up = _mirror(i - 1, h)
            dn = _mirror(i + 1, h)
            red_row = (i & 1) == ry
            for j in range(w):
                lf = _mirror(j - 1, w)
                rt = _mirror(j + 1, w)
                c = np.int64(mosaic[i, j])
                red_col = (j & 1) == rx
                if red_row == red_col:  # a red or a blue site
                    diag = (
                        np.int64(mosaic[up, lf])
                        + np.int64(mosaic[up, rt])
                        + np.int64(mosaic[dn, lf])
                        + np.int64(mosaic[dn, rt])
                    ) >> 2
                    g = _green(
                        np.int64(mosaic[up, j]),
                        np.int64(mosaic[dn, j]),
                        np.int64(mosaic[i, lf]),
                        np.int64(mosaic[i, rt]),
                        rule,
                    )
                    r, b = (c, diag) if red_row else (diag, c)
                else:  # a green site: red and blue from the two neighbours of each
                    hor = (np.int64(mosaic[i, lf]) + np.int64(mosaic[i, rt])) >> 1
                    ver = (np.int64(mosaic[up, j]) + np.int64(mosaic[dn, j])) >> 1
                    g = c
                    r, b = (hor, ver) if red_row else (ver, hor)
                out[i, j, 0] = r
                out[i, j, 1] = g
                out[i, j, 2] = b


@njit(cache=True, nogil=True)
def _mosaic_of(rgb: Any, ry: int, rx: int) -> Any:
    """The value each site of the pattern measures: red at red sites, and so on."""
    h, w, _ = rgb.shape
    out = np.empty((h, w), np.uint8)
    for i in range(h):
        red_row = (i & 1) == ry
        for j in range(w):
            red_col = (j & 1) == rx
            if red_row == red_col:
                out[i, j] = rgb[i, j, 0] if red_row else rgb[i, j, 2]
            else:
                out[i, j] = rgb[i, j, 1]
    return out


@njit(cache=True, nogil=True)
def _misses(bands: Any, ry: int, rx: int, rule: int) -> int:
    """How many pixels of the middle two rows of each 4-row band of ``bands`` (the borders
    left out) a Bayer model misses."""
    h, w, _ = bands.shape
    mosaic = _mosaic_of(bands, ry, rx)
    out = np.empty_like(bands)
    _rebuild_rows(mosaic, out, ry, rx, rule, 1, 4)
    missed = 0
    for top in range(1, h, 4):
        for i in range(top, min(top + 2, h)):
            for j in range(1, w - 1):
                if (
                    out[i, j, 0] != bands[i, j, 0]
                    or out[i, j, 1] != bands[i, j, 1]
                    or out[i, j, 2] != bands[i, j, 2]
                ):
                    missed += 1
    return missed


@njit(cache=True, nogil=True, inline="always")
def _yuy2_pixel(y: int, d: int, e: int) -> tuple[int, int, int]:
    """librealsense's YUY2 to RGB (its SIMD form: each product floored on its own)."""
    k = (298 * (y - 16)) >> 8
    r = k + ((409 * e) >> 8)
    g = k - ((100 * d) >> 8) - ((208 * e) >> 8)
    b = k + ((516 * d) >> 8)
    return min(max(r, 0), 255), min(max(g, 0), 255), min(max(b, 0), 255)


_STEPS = np.array([0, -1, 1, -2, 2], np.int64)  # luma
_CHROMA_STEPS = np.array([0, -1, 1, -2, 2, -3, 3, -4, 4], np.int64)  # wider where clamped


@njit(cache=True, nogil=True, inline="always")
def _luma_for(r: int, g: int, b: int, y0: int, d: int, e: int) -> int:
    """The luma near ``y0`` that gives the pixel ``(r, g, b)`` with chroma ``d, e``, or -1."""
    for k in range(5):
        y = y0 + ((k + 1) >> 1) * (1 if k % 2 == 0 else -1)  # y0, y0 - 1, y0 + 1, ...
        if 0 <= y <= 255:
            pr, pg, pb = _yuy2_pixel(y, d, e)
            if pr == r and pg == g and pb == b:
                return int(y)
    return -1


@njit(cache=True, nogil=True)
def _chroma_search(
    r0: int, g0: int, b0: int, r1: int, g1: int, b1: int, u0: int, v0: int, y0: int, y1: int
) -> tuple[int, int, int, int]:
    """The chroma near ``(u0, v0)`` (and each pixel's luma) that gives both pixels, or lumas
    of -1."""
    for du in _CHROMA_STEPS:
        u = u0 + du
        if u < 0 or u > 255:
            continue
        for dv in _CHROMA_STEPS:
            v = v0 + dv
            if v < 0 or v > 255:
                continue
            ya = _luma_for(r0, g0, b0, y0, u - 128, v - 128)
            if ya < 0:
                continue
            yb = _luma_for(r1, g1, b1, y1, u - 128, v - 128)
            if yb >= 0:
                return u, v, ya, yb
    return u0, v0, -1, -1


@njit(cache=True, nogil=True)
def _yuy2_of(rgb: Any, ri: int, bi: int, luma: Any, chroma: Any, limit: int) -> int:
    """The YUY2 samples that give ``rgb`` (red in channel ``ri``, blue in ``bi``): luma
    H x W, chroma H x W (U of each pixel pair, then V, side by side). Returns how many pixel
    pairs no samples near the estimate give exactly (they keep the estimate); once more than
    ``limit`` are missed, stops there (the rest left unset)."""
    h, w, _ = rgb.shape
    half = w // 2
    missed = 0
    for i in range(h):
        for p in range(half):
            j = 2 * p
            r0, g0, b0 = np.int64(rgb[i, j, ri]), np.int64(rgb[i, j, 1]), np.int64(rgb[i, j, bi])
            r1 = np.int64(rgb[i, j + 1, ri])
            g1 = np.int64(rgb[i, j + 1, 1])
            b1 = np.int64(rgb[i, j + 1, bi])
            # the formula solved for the pair's chroma and each pixel's luma, in floating point
            # (each floor of the formula taken as half a step); the search starts there
            rg = 128.0 * (r0 + r1 - g0 - g1) + 384.0  # 256 x (R - G), R + 1 and G - 0.5
            bg = 128.0 * (b0 + b1 - g0 - g1) + 384.0
            df = (617.0 * bg - 208.0 * rg) * (1.0 / 359272.0)
            ef = (616.0 * rg - 100.0 * bg) * (1.0 / 359272.0)
            u0 = np.int64(df + 256.5) - 128  # rounded (the offset keeps it positive)
            v0 = np.int64(ef + 256.5) - 128
            base = 100.0 * df + 208.0 * ef - 128.0
            y0 = np.int64((256.0 * g0 + base) * (1.0 / 298.0) + 16.5 + 256.0) - 256
            y1 = np.int64((256.0 * g1 + base) * (1.0 / 298.0) + 16.5 + 256.0) - 256
            d0, e0 = u0 - 128, v0 - 128
            ya = _luma_for(r0, g0, b0, y0, d0, e0)  # nearly always the estimate itself
            yb = _luma_for(r1, g1, b1, y1, d0, e0) if ya >= 0 else -1
            if ya < 0 or yb < 0:  # a clamped colour, say: search the chroma nearby
                u, v, ya, yb = _chroma_search(r0, g0, b0, r1, g1, b1, u0, v0, y0, y1)
            else:
                u, v = u0, v0
            found = ya >= 0
            if found:
                luma[i, j] = ya
                luma[i, j + 1] = yb
                chroma[i, p] = u
                chroma[i, half + p] = v
            if not found:
                missed += 1
                if missed > limit:
                    return missed
                luma[i, j] = min(max(y0, 0), 255)
                luma[i, j + 1] = min(max(y1, 0), 255)
                chroma[i, p] = min(max(u0, 0), 255)
                chroma[i, half + p] = min(max(v0, 0), 255)
    return missed


@njit(cache=True, nogil=True)
def _yuy2_rebuild(luma: Any, chroma: Any, ri: int, bi: int, out: Any) -> None:
    h, w = luma.shape
    half = w // 2
    for i in range(h):
        for j in range(w):
            p = j >> 1
            r, g, b = _yuy2_pixel(
                np.int64(luma[i, j]),
                np.int64(chroma[i, p]) - 128,
                np.int64(chroma[i, half + p]) - 128,
            )
            out[i, j, ri] = r
            out[i, j, 1] = g
            out[i, j, bi] = b


def _yuy2_order(rgb: npt.NDArray[np.uint8]) -> int:
    """0 (red first) or 1 (blue first) when nearly every sampled pixel pair of ``rgb`` is a
    YUY2 pair converted the way librealsense converts it, else -1."""
    h, w = rgb.shape[:2]
    band = np.ascontiguousarray(rgb[:: max(1, h // 8)])
    limit = int((1.0 - _MIN_MATCH) * band.shape[0] * (w // 2))
    for order in (0, 1):
        luma = np.empty(band.shape[:2], np.uint8)
        chroma = np.empty(band.shape[:2], np.uint8)
        if _yuy2_of(band, 2 * order, 2 - 2 * order, luma, chroma, limit) <= limit:
            return order
    return -1


def model_of(rgb: npt.NDArray[np.uint8]) -> tuple[int, int, int]:
    """The model :func:`encode` codes ``rgb`` with: ``(model, phase, rule)``, ``model`` 1 for
    a Bayer pattern (``phase`` its red site, ``2 * row parity + column parity``; ``rule`` the
    green one), 0 for the planar model."""
    h, w = rgb.shape[:2]
    if h < 8 or w < 8 or h % 2 or w % 2:
        return _PLANAR, 0, 0
    order = _yuy2_order(rgb)
    if order >= 0:
        return _YUY2, order, 0
    # bands of 4 rows starting on even rows (the pattern's phase kept), every 16th row
    bands = np.concatenate([rgb[t : t + 4] for t in range(0, h - 3, 4 * _SAMPLE_ROWS)])
    tried = 2 * (len(bands) // 4) * (w - 2)
    best = (1.0, 0, 0)
    for phase in range(4):
        for rule in _RULES:
            share = _misses(bands, phase >> 1, phase & 1, rule) / tried
            if share < best[0]:
                best = (share, phase, rule)
            if share < 0.01:
                break
        if best[0] < 0.01:
            break
    if best[0] > 1.0 - _MIN_MATCH:
        return _PLANAR, 0, 0
    return _BAYER, best[1], best[2]


def _section(data: bytes) -> bytes:
    return struct.pack("<I", len(data)) + data


def _jpegls_encode(image: npt.NDArray[np.uint8]) -> bytes:
    import imagecodecs

    image = np.ascontiguousarray(image)
    # room for noise, which JPEG-LS makes larger (its own estimate can fall short)
    return bytes(imagecodecs.jpegls_encode(image, out=2 * image.size + 4096))


def _jpegls_size(data: bytes) -> tuple[int, int, int]:
    """Height, width and components of a JPEG-LS image, read from its frame header before
    anything is decoded."""
    if data[:2] != b"\xff\xd8":
        raise ValueError("its planes are not a JPEG-LS image")
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            raise ValueError("its planes' JPEG-LS markers are damaged")
        marker = data[pos + 1]
        (length,) = struct.unpack_from(">H", data, pos + 2)
        if marker == 0xF7:  # the JPEG-LS frame header
            if pos + 10 > len(data):
                break
            bits, h, w, n = struct.unpack_from(">BHHB", data, pos + 4)
            if bits != 8:
                raise ValueError(f"its planes are {bits}-bit, expected 8-bit")
            return h, w, n
        pos += 2 + length
    raise ValueError("its planes' JPEG-LS image has no frame header")


def _jpegls_decode(data: bytes, shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    import imagecodecs

    found = _jpegls_size(data)
    if found != (*shape, 1):
        raise ValueError(f"its planes are {found[:2]} x {found[2]}, expected {shape} x 1")
    try:
        image = np.asarray(imagecodecs.jpegls_decode(data))
    except Exception as exc:  # the library's own errors: damaged data
        raise ValueError(f"its planes do not decode: {exc}") from None
    if image.shape != shape or image.dtype != np.uint8:
        raise ValueError(f"its planes are {image.dtype} {image.shape}, expected uint8 {shape}")
    return image


def _planes(mosaic: npt.NDArray[np.uint8], ry: int, rx: int) -> npt.NDArray[np.uint8]:
    """The four sites of the pattern as planes stacked top to bottom: red, the green beside
    red, the green beside blue, blue."""
    return np.vstack(
        [
            mosaic[ry::2, rx::2],
            mosaic[ry::2, 1 - rx :: 2],
            mosaic[1 - ry :: 2, rx::2],
            mosaic[1 - ry :: 2, 1 - rx :: 2],
        ]
    )


def _unplanes(planes: npt.NDArray[np.uint8], h: int, w: int, ry: int, rx: int) -> Any:
    mosaic = np.empty((h, w), np.uint8)
    q = h // 2
    mosaic[ry::2, rx::2] = planes[:q]
    mosaic[ry::2, 1 - rx :: 2] = planes[q : 2 * q]
    mosaic[1 - ry :: 2, rx::2] = planes[2 * q : 3 * q]
    mosaic[1 - ry :: 2, 1 - rx :: 2] = planes[3 * q :]
    return mosaic


def _rebuild(mosaic: npt.NDArray[np.uint8], ry: int, rx: int, rule: int) -> Any:
    out = np.empty((*mosaic.shape, 3), np.uint8)
    _rebuild_rows(mosaic, out, ry, rx, rule, 0, 2)
    return out


def encode(rgb: npt.NDArray[np.uint8], check: bool = False) -> bytes:
    """``rgb`` (H x W x 3 uint8) coded losslessly (the model chosen by :func:`model_of`).
    ``check``: decode the coded planes and compare them with the planes given (what the
    model rebuilds from them is exact by construction); ``ValueError`` if they differ."""
    import zstandard

    rgb = np.ascontiguousarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.size == 0:
        raise ValueError(f"expected an H x W x 3 uint8 image, got {rgb.dtype} {rgb.shape}")
    h, w = rgb.shape[:2]
    model, phase, rule = model_of(rgb)
    if model == _BAYER:
        ry, rx = phase >> 1, phase & 1
        mosaic = _mosaic_of(rgb, ry, rx)
        planes = _planes(mosaic, ry, rx)
        residual = rgb - _rebuild(mosaic, ry, rx, rule)  # wraps: modulo 256
    elif model == _YUY2:
        ri, bi = 2 * phase, 2 - 2 * phase
        planes = np.empty((2 * h, w), np.uint8)  # luma above, U and V side by side below
        _yuy2_of(rgb, ri, bi, planes[:h], planes[h:], h * w)
        rebuilt = np.empty_like(rgb)
        _yuy2_rebuild(planes[:h], planes[h:], ri, bi, rebuilt)
        residual = rgb - rebuilt
    else:
        g = rgb[..., 1]
        planes = np.vstack([g, rgb[..., 0] - g, rgb[..., 2] - g])  # modulo 256
        residual = None
    rest = b""
    if residual is not None and residual.any():
        rest = zstandard.ZstdCompressor(level=3).compress(residual.tobytes())
    coded = _jpegls_encode(planes)
    if check and not np.array_equal(_jpegls_decode(coded, planes.shape), planes):
        raise ValueError("JPEG-LS did not give the colour planes back exactly")
    head = _HEAD.pack(_MAGIC, _VERSION, model, phase, rule, h, w)
    return head + _section(coded) + _section(rest)


def decode(data: bytes, shape: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """The H x W x 3 image :func:`encode` coded, of ``shape`` (height, width). Raises
    ``ValueError`` naming what is wrong for damaged data or another shape."""
    import zstandard

    data = bytes(data)
    if len(data) < _HEAD.size:
        raise ValueError("its colour image is cut short")
    magic, version, model, phase, rule, h, w = _HEAD.unpack_from(data, 0)
    if magic != _MAGIC or version != _VERSION:
        raise ValueError("its colour image is not a pcdcodec lossless RGB image")
    if (h, w) != tuple(shape):
        raise ValueError(f"its colour image is {(h, w)}, expected {tuple(shape)}")
    if (
        model not in (_PLANAR, _BAYER, _YUY2)
        or phase > (3 if model == _BAYER else 1)
        or rule not in _RULES
    ):
        raise ValueError(f"its colour image has an unknown model ({model}, {phase}, {rule})")
    if model != _PLANAR and (h % 2 or w % 2):
        raise ValueError(f"a Bayer or YUY2 colour image must have an even size, not {(h, w)}")
    pos = _HEAD.size
    parts = []
    for _ in range(2):
        if pos + 4 > len(data):
            raise ValueError("its colour image is cut short")
        (n,) = struct.unpack_from("<I", data, pos)
        if pos + 4 + n > len(data):
            raise ValueError("its colour image is cut short")
        parts.append(data[pos + 4 : pos + 4 + n])
        pos += 4 + n
    if pos != len(data):
        raise ValueError("its colour image has bytes after its end")
    if model == _BAYER:
        ry, rx = phase >> 1, phase & 1
        mosaic = _unplanes(_jpegls_decode(parts[0], (2 * h, w // 2)), h, w, ry, rx)
        rgb: npt.NDArray[np.uint8] = _rebuild(mosaic, ry, rx, rule)
    elif model == _YUY2:
        planes = _jpegls_decode(parts[0], (2 * h, w))
        rgb = np.empty((h, w, 3), np.uint8)
        _yuy2_rebuild(planes[:h], planes[h:], 2 * phase, 2 - 2 * phase, rgb)
    else:
        planes = _jpegls_decode(parts[0], (3 * h, w))
        g = planes[:h]
        rgb = np.stack([planes[h : 2 * h] + g, g, planes[2 * h :] + g], axis=-1)
    if parts[1]:
        try:
            rest = zstandard.ZstdDecompressor().decompress(parts[1], max_output_size=3 * h * w)
        except zstandard.ZstdError as exc:
            raise ValueError(f"its colour residual does not decompress: {exc}") from None
        if len(rest) != 3 * h * w:
            raise ValueError(f"its colour residual has {len(rest)} bytes, expected {3 * h * w}")
        rgb += np.frombuffer(rest, np.uint8).reshape(h, w, 3)  # modulo 256
    return rgb
