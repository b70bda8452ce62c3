"""What faster ways of coding ``depthac``'s residuals would cost in size, on every depth set.

A faster decoder needs fewer adaptive decisions per pixel. This script measures, without
writing a decoder, how many bytes the candidate models would take: it runs ``depthac``'s own
prediction and contexts over real frames, then adds up the ideal code length (−log2 of each
decision's probability at the moment it is coded) of each candidate, with adaptive models that
learn as the coder would. The first column checks the method: today's binary decisions,
counted this way, come within the value table's bytes of the real coded size.

Candidates (each against today's residual bytes):

* ``tokens``: one multi-symbol decision per valid pixel (0, ±1, ±2, ±3 and larger escapes,
  whose rest keeps today's exponent and mantissa bits), with today's zero-flag contexts;
* ``nz-token/q``: today's zero flag, then sign and magnitude of a non-zero residual (±1, ±2,
  ±3+) as one decision, by gradient triple (the pixel context without one);
* ``nz-token/q+signs``: the same by gradient triple and the neighbours' residual signs;
* ``nz-token/ctx``: the same by pixel context;
* ``two halves``: today's binary decisions with separate models for the top and bottom
  halves of the frame (what independent streams decoded side by side would cost);
* ``slower adaptation``: today's binary decisions whose models settle at a shift of 6 after
  96 uses instead of 5 after 24 (a gain in size at no cost in speed).

Run: ``python scripts/depthac_model_costs.py [--frames 3] [--sets sample,spot]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np
from numba import njit

from pcdcodec.bench.sequences import ALL_DEPTH_SETS, load_frames, set_present
from pcdcodec.depth import _depthac_kernels as kern  # the coder under study
from pcdcodec.depth import _depthac_model as model  # its model

_RATE = model._RATE_LUT
#: A slower final adaptation: shift 5 until 96 uses, then 6.
SLOW_RATES = np.concatenate([_RATE[:-1], np.full(72, 5), [6]]).astype(np.int64)
_NOBIAS = model._NOBIAS


@njit(cache=True)
def features(image: Any) -> tuple[Any, Any, int]:
    """Per valid pixel (context, triple, residual, west and north residuals), per pixel
    (mask context, mask bit), and the value table's length, as the encoder computes them."""
    h, w = image.shape
    pad = model._PAD
    st = w + 2 * pad
    px = np.zeros((h + pad) * st + pad, dtype=np.int64)  # the coder's packed pixel states
    rank = np.zeros(65536, dtype=np.int64)
    nvalid = 0
    for y in range(h):
        for x in range(w):
            v = image[y, x]
            rank[v] = 1
            if v != 0:
                px[(y + pad) * st + pad + x] = model._VALID
                nvalid += 1
    rank[0] = 0
    ntable = 0
    for v in range(1, 65536):
        if rank[v]:
            rank[v] = ntable + 1
            ntable += 1
    if not (nvalid > 0 and 2 * ntable <= nvalid):
        for v in range(65536):
            rank[v] = v + 1
    pix = np.zeros((nvalid, 5), dtype=np.int64)
    mask = np.zeros((h * w, 2), dtype=np.int64)
    last = 0
    k = 0
    for y in range(h):
        o0 = (y + pad) * st + pad
        r1, r2 = model._mask_row_start(px, o0, st)
        wb = 0
        for o in range(o0, o0 + w):
            vo = (px[o] >> 31) & 1
            mask[(y * w) + o - o0, 0] = model._MASK_LUT[(r2 << 7) | (r1 << 2) | wb]
            mask[(y * w) + o - o0, 1] = vo
            r1 = ((r1 << 1) & 31) | ((px[o - st + 3] >> 31) & 1)
            r2 = ((r2 << 1) & 7) | ((px[o - 2 * st + 2] >> 31) & 1)
            wb = ((wb << 1) | vo) & 3
            if vo == 0:
                continue
            v = rank[np.int64(image[y, o - o0])] - 1
            p, ctx, q, ew, en = model._predict(px, o, st, last, model._G_LUT, model._E_LUT)
            pix[k, 0] = ctx
            pix[k, 1] = q
            pix[k, 2] = v - p
            pix[k, 3] = ew
            pix[k, 4] = en
            px[o] = ((v - p) << 32) | model._VALID | v
            last = v
            k += 1
    return pix, mask, ntable


@njit(cache=True)
def _bit(state: Any, i: int, bit: int, rates: Any = _RATE) -> float:
    """Cost in bits of one binary decision with adaptive model ``i``; adapts it. ``rates`` is
    the adaptation shift by use count (today's by default; the last one stays)."""
    s = state[i]
    p = s & 0xFFFF
    c = s >> 16
    r = rates[c]
    c = min(c + 1, len(rates) - 1)
    if bit == 0:
        cost = -math.log2(p / 65536.0)
        p += (65536 - p) >> r
    else:
        cost = -math.log2(1.0 - p / 65536.0)
        p -= p >> r
    p = min(max(p, 1), 65535)
    state[i] = (c << 16) | p
    return cost


@njit(cache=True)
def _symbol(cdf: Any, count: Any, c: int, s: int, n: int) -> float:
    """Cost in bits of symbol ``s`` of an adaptive ``n``-symbol model ``c`` (15-bit cumulative
    frequencies, every symbol kept at 1 or more, adapting fast at first); adapts it."""
    cost = -math.log2((cdf[c, s + 1] - cdf[c, s]) / 32768.0)
    rate = 4 + (1 if count[c] > 15 else 0) + (1 if count[c] > 31 else 0)
    rate += 1 if count[c] > 63 else 0
    count[c] += 1
    for i in range(1, n):
        target = i if i <= s else 32768 - (n - i)
        cur = cdf[c, i]
        cdf[c, i] = (
            cur + ((target - cur) >> rate) if target >= cur else cur - ((cur - target) >> rate)
        )
    return cost


@njit(cache=True)
def _new_cdf(contexts: int, n: int) -> Any:
    cdf = np.zeros((contexts, n + 1), dtype=np.int64)
    for c in range(contexts):
        for i in range(n + 1):
            cdf[c, i] = (32768 * i) // n
    return cdf


@njit(cache=True)
def _sign_class(ew: int, en: int) -> int:
    return (0 if ew == 0 else (1 if ew > 0 else 2)) * 3 + (0 if en == 0 else (1 if en > 0 else 2))


@njit(cache=True)
def _rest_bits(state: Any, ctx: int, m: int, rates: Any = _RATE) -> float:
    """Today's exponent and mantissa bits of ``m`` ≥ 1."""
    bits = 0.0
    k = 0
    while (m >> (k + 1)) != 0:
        k += 1
    e0 = model._M_EXP + ctx * model._EXP
    for j in range(k):
        bits += _bit(state, e0 + j, 1, rates)
    if k < 15:
        bits += _bit(state, e0 + k, 0, rates)
    m0 = model._M_MANT + (ctx // model._PERCLASS) * 256 + k * 16
    for j in range(k - 1, -1, -1):
        bits += _bit(state, m0 + j, (m >> j) & 1, rates)
    return bits


@njit(cache=True)
def _zero_model(ctx: int, q: int) -> int:
    if q == _NOBIAS:
        return model._M_ZERO + ctx
    return model._M_QZERO + q * model._NQE + min(ctx % model._NEBIN, model._NQE - 1)


@njit(cache=True)
def binary_bytes(
    pix: Any, mask: Any, lo: int, hi: int, mlo: int, mhi: int, rates: Any = _RATE
) -> float:
    """Today's decisions for valid pixels ``lo:hi`` and mask bits ``mlo:mhi``, in bytes, with
    the adaptation shifts ``rates``."""
    state = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int64)
    bits = 0.0
    for i in range(mlo, mhi):
        bits += _bit(state, model._M_MASK + mask[i, 0], mask[i, 1], rates)
    for k in range(lo, hi):
        ctx, q, e, ew, en = pix[k, 0], pix[k, 1], pix[k, 2], pix[k, 3], pix[k, 4]
        if e == 0:
            bits += _bit(state, _zero_model(ctx, q), 0, rates)
            continue
        bits += _bit(state, _zero_model(ctx, q), 1, rates)
        sc = model._M_SIGN + ctx if q == _NOBIAS else model._M_QSIGN + q * 9 + _sign_class(ew, en)
        bits += _bit(state, sc, 1 if e < 0 else 0, rates)
        bits += _rest_bits(state, ctx, -e if e < 0 else e, rates)
    return bits / 8


@njit(cache=True)
def token_bytes(pix: Any) -> float:
    """One 9-symbol decision per valid pixel (0, ±1, ±2, ±3, ±4+), in bytes."""
    state = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int64)
    cdf = _new_cdf(730 * 4 + model._NCTX, 9)
    count = np.zeros(cdf.shape[0], dtype=np.int64)
    bits = 0.0
    for k in range(pix.shape[0]):
        ctx, q, e = pix[k, 0], pix[k, 1], pix[k, 2]
        c = q * 4 + min(ctx % model._NEBIN, 3) if q != _NOBIAS else 730 * 4 + ctx
        m = -e if e < 0 else e
        s = 0 if m == 0 else 2 * min(m, 4) - (1 if e > 0 else 0)
        bits += _symbol(cdf, count, c, s, 9)
        if m >= 4:
            bits += _rest_bits(state, ctx, m - 3)
    return bits / 8


@njit(cache=True)
def nonzero_token_bytes(pix: Any, variant: int) -> float:
    """Today's zero flag, then one 6-symbol decision (±1, ±2, ±3+) for a non-zero residual,
    by gradient triple (0), triple and signs (1) or pixel context (2), in bytes."""
    state = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int64)
    cdf = _new_cdf(730 * 9 + model._NCTX * 9, 6)
    count = np.zeros(cdf.shape[0], dtype=np.int64)
    bits = 0.0
    for k in range(pix.shape[0]):
        ctx, q, e, ew, en = pix[k, 0], pix[k, 1], pix[k, 2], pix[k, 3], pix[k, 4]
        bits += _bit(state, _zero_model(ctx, q), 0 if e == 0 else 1)
        if e == 0:
            continue
        if variant == 0:
            c = q if q != _NOBIAS else 730 + ctx
        elif variant == 1:
            c = q * 9 + _sign_class(ew, en) if q != _NOBIAS else 730 * 9 + ctx
        else:
            c = ctx
        m = -e if e < 0 else e
        bits += _symbol(cdf, count, c, 2 * (min(m, 3) - 1) + (1 if e < 0 else 0), 6)
        if m >= 3:
            bits += _rest_bits(state, ctx, m - 2)
    return bits / 8


def costs(depth: np.ndarray[Any, Any]) -> dict[str, float]:
    """Real size and each candidate's residual bytes for one frame."""
    pix, mask, _ = features(depth)
    real = len(kern.encode_image(depth, True, 0, np.zeros((0, 0), dtype=np.uint16)))
    h, w = depth.shape
    half = (h // 2) * w
    vhalf = int(mask[:half, 1].sum())
    nvalid = pix.shape[0]
    mask_bytes = binary_bytes(pix, mask, 0, 0, 0, mask.shape[0]) if nvalid < h * w else 0.0
    today = binary_bytes(pix, mask, 0, nvalid, 0, 0)
    halves = binary_bytes(pix, mask, 0, vhalf, 0, 0) + binary_bytes(pix, mask, vhalf, nvalid, 0, 0)
    return {
        "real": real,
        "counted": today + mask_bytes,
        "residual": today,
        "tokens": token_bytes(pix),
        "nz-token/q": nonzero_token_bytes(pix, 0),
        "nz-token/q+signs": nonzero_token_bytes(pix, 1),
        "nz-token/ctx": nonzero_token_bytes(pix, 2),
        "two halves": halves,
        "slower adaptation": binary_bytes(pix, mask, 0, nvalid, 0, 0, SLOW_RATES),
    }


def table(names: list[str], frames: int) -> dict[str, dict[str, float]]:
    """Each set's totals over ``frames`` frames (spot and the Azure Kinect have one)."""
    out: dict[str, dict[str, float]] = {}
    for name in names:
        total: dict[str, float] = {"frames": 0.0}
        for depth in load_frames(name, frames):
            total["frames"] += 1
            for key, value in costs(depth).items():
                total[key] = total.get(key, 0.0) + value
        out[name] = total
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=3, help="frames per set (default 3)")
    parser.add_argument("--sets", help="comma-separated depth sets (default: every one present)")
    args = parser.parse_args(argv)
    names = args.sets.split(",") if args.sets else [s for s in ALL_DEPTH_SETS if set_present(s)]
    columns = [
        "tokens",
        "nz-token/q",
        "nz-token/q+signs",
        "nz-token/ctx",
        "two halves",
        "slower adaptation",
    ]
    print("Residual bytes of each candidate over today's (1.000 = today's size; lower is smaller)")
    print("| set | real bytes | counted / real | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 3) + "|")
    for name, total in table(names, args.frames).items():
        row = [f"{total[c] / total['residual']:.3f}" for c in columns]
        print(
            f"| {name} | {total['real'] / total['frames']:.0f} | "
            f"{total['counted'] / total['real']:.3f} | " + " | ".join(row) + " |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
