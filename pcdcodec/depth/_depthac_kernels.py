"""Compiled loops of the ``depthac`` depth codec (numba, cached on disk).

The bitstream is described in ``docs/format.md`` ("depthac body"). Encoder and decoder share
one model: every context, prediction and probability update below happens identically on both
sides, so any change here is a format change and must keep the golden frames decoding.

The decoder reads untrusted bytes. numba does not check array bounds, so every index derived
from the stream is checked before use: the value table is bounded by 65,535 entries, decoded
indices by the table, byte reads by the body length (reads past the end give zeros and make
the frame fail), and every loop is bounded by the image size, so it cannot hang.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from ._depthac_model import (
    _B0,
    _E_LUT,
    _G_LUT,
    _M_MASK,
    _MASK32,
    _MASK_LUT,
    _PAD,
    _U,
    _VALID,
    DECISION_BLOCK,
    ERR_ARRAYS,
    ERR_FLAGS,
    ERR_INDEX,
    ERR_LENGTH,
    OK,
    _bit_valid,
    _clamp_index,
    _coding_ctx,
    _dec,
    _mask_row_start,
    _predict,
    code_decisions,
    finish_coding,
    fresh_models,
    read_residual,
    read_table,
    write_residual,
    write_table,
)

# -- encoder ------------------------------------------------------------------------------


@njit(cache=True, nogil=True, error_model="numpy")
def encode_image(image: Any, allow_table: bool, near: int, recon: Any) -> Any:
    """Encode a 2-D uint16 image; returns the body as a uint8 array.

    With ``near`` = 0 the coding is lossless. With ``near`` > 0 the image holds level indices
    (0 = hole, no value table is used) and each residual is quantised with step
    ``2 * near + 1`` inside the prediction loop: the decoder's value, written to ``recon``,
    is within ``near`` of the input at every valid pixel (clamped to 1..65535).
    """
    h, w = image.shape
    px = np.zeros((h + _PAD) * (w + 2 * _PAD) + _PAD, dtype=np.int64)
    return encode_into(image, allow_table, near, recon, px, np.empty(65536, dtype=np.int64))


@njit(cache=True, nogil=True, error_model="numpy")
def encode_into(image: Any, allow_table: bool, near: int, recon: Any, px: Any, rank: Any) -> Any:
    """:func:`encode_image` with its working arrays given (see :func:`decode_into`): ``px``,
    int64 of :func:`working_size`, zero where it pads the image, and ``rank``, int64 of 65536
    entries of any content. Arrays of other sizes raise ``ValueError``."""
    h, w = image.shape
    npix = h * w
    glut = _G_LUT
    elut = _E_LUT
    st = w + 2 * _PAD
    if px.size != (h + _PAD) * st + _PAD or rank.size != 65536:
        raise ValueError("depthac's working arrays do not fit the frame")
    for v in range(65536):
        rank[_U(v)] = 0
    nvalid = _B0
    for y in range(h):
        o = (y + _PAD) * st + _PAD
        for x in range(w):
            v = image[_U(y), _U(x)]
            rank[_U(v)] = 1
            if v != 0:
                px[_U(o + x)] = _VALID
                nvalid += 1
            else:
                px[_U(o + x)] = 0
    rank[_U(0)] = 0
    ntable = _B0
    for v in range(1, 65536):
        if rank[_U(v)] != 0:
            rank[_U(v)] = ntable + 1
            ntable += 1
    use_table = near == 0 and allow_table and nvalid > 0 and 2 * ntable <= nvalid
    step = 2 * near + 1

    # Decisions are modelled a block at a time and coded at the end of each (see
    # :func:`code_decisions`): once more than DECISION_BLOCK wait, before the next row. A pixel
    # makes at most 34 decisions, so a row then fits; the table codes its blocks likewise (at
    # most 32 decisions an entry, 16 for its length). A decision fits 16 bits (the models
    # number under 2**15). The output starts at a quarter byte per pixel (real depth needs a
    # tenth) and grows.
    row_worst = 34 * w
    dec = np.empty(DECISION_BLOCK + max(row_worst, 64), dtype=np.uint16)
    out = np.empty(npix // 4 + 4096, dtype=np.uint8)
    out[_U(0)] = (1 if use_table else 0) | (2 if nvalid < npix else 0)
    state = np.empty(3, dtype=np.int64)
    state[_U(0)] = 0
    state[_U(1)] = _MASK32
    state[_U(2)] = 1
    probs = fresh_models()
    nd = _B0
    if use_table:
        nd, out = write_table(dec, nd, rank, ntable, state, out, probs)
    else:
        for v in range(65536):
            rank[_U(v)] = v + 1
    # Indices and residuals are filled in as the pixels are modelled: the model reads only
    # causal ones, and the valid bits of all (the mask is known before it is coded).
    code_mask = nvalid < npix
    last = _B0
    mlut = _MASK_LUT
    for y in range(h):
        if nd > DECISION_BLOCK:
            out = code_decisions(dec, nd, state, out, probs)
            nd = _B0
        o0 = (y + _PAD) * st + _PAD
        r1, r2 = _mask_row_start(px, o0, st)
        wb = 0
        for o in range(o0, o0 + w):
            vo = _bit_valid(px[_U(o)])
            if code_mask:
                mc = mlut[_U((r2 << 7) | (r1 << 2) | wb)]
                dec[_U(nd)] = 2 * (_M_MASK + mc) + vo
                nd += 1
                r1 = ((r1 << 1) & 31) | _bit_valid(px[_U(o - st + 3)])
                r2 = ((r2 << 1) & 7) | _bit_valid(px[_U(o - 2 * st + 2)])
                wb = ((wb << 1) | vo) & 3
            if vo == 0:
                continue
            v = rank[np.int64(image[_U(y), _U(o - o0)])] - 1
            p, ctx, q, ew, en = _predict(px, o, st, last, glut, elut)
            zc, sc = _coding_ctx(ctx, q, ew, en)
            e = v - p
            if near > 0:
                e = (e + near) // step if e >= 0 else -((near - e) // step)
                v = _clamp_index(p + e * step)
                recon[y, o - o0] = v
            px[_U(o)] = (e << 32) | _VALID | v
            last = v
            nd = write_residual(dec, nd, zc, sc, ctx, e)
    out = code_decisions(dec, nd, state, out, probs)
    return finish_coding(state, out)


# -- decoder ------------------------------------------------------------------------------


def working_size(h: int, w: int) -> int:
    """The length of the packed working array that :func:`decode_into` takes for h×w."""
    return (h + _PAD) * (w + 2 * _PAD) + _PAD


@njit(cache=True, nogil=True, error_model="numpy")
def decode_image(buf: Any, out_img: Any, near: int) -> int:
    """Decode a body into ``out_img`` (uint16, h×w); returns ``OK`` or an ``ERR_*`` status.

    ``near`` must be the value the body was encoded with (see :func:`encode_image`).
    """
    h, w = out_img.shape
    px = np.zeros((h + _PAD) * (w + 2 * _PAD) + _PAD, dtype=np.int64)
    return decode_into(buf, out_img, near, px, np.empty(65536, dtype=np.int64))


@njit(cache=True, nogil=True, error_model="numpy")
def decode_into(buf: Any, out_img: Any, near: int, px: Any, table: Any) -> int:
    """:func:`decode_image` with its working arrays given, so that a caller decoding frame
    after frame reuses them (fresh memory costs page faults): ``px``, int64 of
    :func:`working_size`, zero where it pads the image (the decoder never writes there, and
    reads nothing of the image it has not written in this call), and ``table``, int64 of 65536
    entries of any content.
    """
    h, w = out_img.shape
    st = w + 2 * _PAD
    if px.size != (h + _PAD) * st + _PAD or table.size != 65536:
        return ERR_ARRAYS
    n = buf.size
    glut = _G_LUT
    elut = _E_LUT
    if n < 5:
        return ERR_LENGTH
    flags = buf[_U(0)]
    if flags > 3:
        return ERR_FLAGS
    use_table = (flags & 1) != 0
    code_mask = (flags & 2) != 0
    if near < 0 or near > 32767 or (use_table and near > 0):
        return ERR_FLAGS
    step = 2 * near + 1
    code = (
        (np.int64(buf[_U(1)]) << 24)
        | (np.int64(buf[_U(2)]) << 16)
        | (np.int64(buf[_U(3)]) << 8)
        | np.int64(buf[_U(4)])
    )
    rng = np.int64(_MASK32)
    pos = np.int64(5)
    probs = fresh_models()

    maxidx = 65535
    if use_table:
        ntable, code, rng, pos = read_table(code, rng, pos, buf, n, probs, table)
        if ntable < 0:
            return -ntable
        maxidx = ntable - 1
    else:
        for i in range(65536):
            table[_U(i)] = i

    last = _B0
    mlut = _MASK_LUT
    for y in range(h):
        if pos > n:
            return ERR_LENGTH
        o0 = (y + _PAD) * st + _PAD
        r1, r2 = _mask_row_start(px, o0, st)
        wb = 0
        for x in range(w):
            o = o0 + x
            if code_mask:
                mc = mlut[_U((r2 << 7) | (r1 << 2) | wb)]
                bit, code, rng, pos = _dec(code, rng, pos, buf, n, probs, _M_MASK + mc)
                r1 = ((r1 << 1) & 31) | _bit_valid(px[_U(o - st + 3)])
                r2 = ((r2 << 1) & 7) | _bit_valid(px[_U(o - 2 * st + 2)])
                wb = ((wb << 1) | bit) & 3
                if bit == 0:
                    out_img[_U(y), _U(x)] = 0
                    px[_U(o)] = 0
                    continue
            p, ctx, q, ew, en = _predict(px, o, st, last, glut, elut)
            zc, sc = _coding_ctx(ctx, q, ew, en)
            e, code, rng, pos = read_residual(code, rng, pos, buf, n, probs, zc, sc, ctx)
            v = p + e if near == 0 else _clamp_index(p + e * step)
            if v < 0 or v > maxidx or table[_U(v)] == 0:
                return ERR_INDEX
            px[_U(o)] = (e << 32) | _VALID | v
            out_img[_U(y), _U(x)] = table[_U(v)]
            last = v
    if pos != n:
        return ERR_LENGTH
    return OK
