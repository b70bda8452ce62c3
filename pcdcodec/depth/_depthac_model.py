"""The model and the coder that ``depthac``'s encoder and decoder share (numba, cached on disk).

The adaptive binary range coder, the layout of the model array, the prediction and contexts of
a pixel, and the coding of the value table and of a residual. Every decision the bitstream
holds is made here the same way on both sides; ``_depthac_kernels`` walks the pixels. Any change
here is a format change and must keep the golden frames decoding.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

# -- adaptive binary range coder ----------------------------------------------------------
# A bit is coded with a 16-bit probability of 0. Each model adapts at a rate set by how often
# it was used: fast at first, settling at 1/2**5.
_PROB_INIT = 32768
_TOP = 1 << 24
_MASK32 = 0xFFFFFFFF

# Model layout: offsets into one probability array.
_NCLASS = 5  # which neighbours are valid
_NGBIN = 8  # gradient activity bins
_NEBIN = 6  # neighbour error bins
_PERCLASS = _NGBIN * _NEBIN
_NCTX = _NCLASS * _PERCLASS
_EXP = 15  # unary exponent models per context (exponents 0..15)
_M_ZERO = 0
_M_SIGN = _M_ZERO + _NCTX
_M_EXP = _M_SIGN + _NCTX
_M_MANT = _M_EXP + _NCTX * _EXP  # (exponent, bit) models, per class
_M_MASK = _M_MANT + _NCLASS * 16 * 16
_NMASKCTX = 1024
_M_HDR = _M_MASK + _NMASKCTX  # 16 models for the table length
_NGAPCTX = 6
_M_TZERO = _M_HDR + 16  # table gaps: zero flag, exponent, mantissa
_M_TEXP = _M_TZERO + _NGAPCTX
_M_TMANT = _M_TEXP + _NGAPCTX * 16
_M_QZERO = _M_TMANT + 16 * 16  # zero flag and sign per (gradient triple, error bin)
_NQE = 4
_M_QSIGN = _M_QZERO + 730 * _NQE
_NMODELS = _M_QSIGN + 730 * 9
assert 2 * _NMODELS <= 65536  # a decision, 2 * model + bit, fits a uint16

# Contexts of quantised gradient triples (9 levels each); the last one means no triple.
_NBIAS = 9 * 9 * 9 + 1
_NOBIAS = _NBIAS - 1

#: Status codes of the decoder; 0 is success.
OK = 0
ERR_TABLE = 1
ERR_INDEX = 2
ERR_LENGTH = 3
ERR_FLAGS = 4
ERR_ARRAYS = 5  # working arrays of the wrong size (a caller's error, not the stream's)

_G_LUT = np.array([0, 1, 2, 3, 3, 4, 4, 4, 4] + [5] * 8 + [6] * 16, dtype=np.int64)  # < 33
_E_LUT = np.array([0, 1, 2, 3, 3, 4, 4, 4, 4], dtype=np.int64)  # < 9


# Adaptation shift by use count (0..24); a model's state packs its count above its 16-bit
# probability (which stays within 1..65535), so one load and one store update it.
_RATE_LUT = np.array([1] + [2] * 2 + [3] * 5 + [4] * 16 + [5], dtype=np.int64)
_STATE_INIT = _PROB_INIT

# Array indices in the loops are cast to unsigned: numba then skips its negative-index
# wraparound, a third of the loops' time. Every index is non-negative by construction (padded
# arrays, checked stream values), which the casts do not change.
_U = np.uint64

# Typed (not literal) constants for calls: numba compiles a function once per distinct set of
# argument types, and a literal argument (``0``, ``4``) is a type of its own. Passing these
# keeps every helper at one compiled version, which is most of the first use's compile time.
_B0 = np.int64(0)
_B1 = np.int64(1)


@njit(cache=True, inline="always", error_model="numpy")
def _enc(
    low: int, rng: int, pos: int, out: Any, probs: Any, i: int, bit: int
) -> tuple[int, int, int]:
    # Branch-free on the bit (selects, not jumps): the bits are what the model cannot predict.
    s = probs[_U(i)]
    p = s & 0xFFFF
    c = s >> 16
    bound = (rng >> 16) * p
    r = _RATE_LUT[_U(c)]
    c = (c + 1 if c < 24 else c) << 16
    one = bit != 0
    low += bound if one else 0
    rng = rng - bound if one else bound
    probs[_U(i)] = c | ((p - (p >> r)) if one else (p + ((65536 - p) >> r)))
    if low > _MASK32:
        # Carry into the bytes already written; it cannot pass the first one.
        low &= _MASK32
        j = pos - 1
        while out[_U(j)] == 255:
            out[_U(j)] = 0
            j -= 1
        out[_U(j)] += 1
    while rng < _TOP:
        out[_U(pos)] = low >> 24
        pos += 1
        low = (low << 8) & _MASK32
        rng <<= 8
    return low, rng, pos


@njit(cache=True, inline="always", error_model="numpy")
def _dec(
    code: int, rng: int, pos: int, buf: Any, n: int, probs: Any, i: int
) -> tuple[int, int, int, int]:
    s = probs[_U(i)]
    p = s & 0xFFFF
    c = s >> 16
    bound = (rng >> 16) * p
    r = _RATE_LUT[_U(c)]
    c = (c + 1 if c < 24 else c) << 16
    if code < bound:
        rng = bound
        probs[_U(i)] = c | (p + ((65536 - p) >> r))
        bit = 0
    else:
        code -= bound
        rng -= bound
        probs[_U(i)] = c | (p - (p >> r))
        bit = 1
    while rng < _TOP:
        byte = np.int64(buf[_U(pos)]) if pos < n else np.int64(0)
        pos += 1
        code = ((code << 8) | byte) & _MASK32
        rng <<= 8
    return bit, code, rng, pos


#: Decisions the encoder models before it codes them (see :func:`code_decisions`): about
#: 128 KiB of them, so its memory stays a few frames' whatever the image.
DECISION_BLOCK = 1 << 16


@njit(cache=True, error_model="numpy")
def code_decisions(dec: Any, nd: int, state: Any, out: Any, probs: Any) -> Any:
    """Code the first ``nd`` decisions of ``dec`` (each ``2 * model + bit``) into ``out``.

    The encoder models a block of decisions, then codes it here, in one loop: the coder is
    compiled once, which is most of the encoder's first use. ``state`` holds the coder's
    ``low``, ``range`` and output position between blocks; ``out`` is returned, grown first
    when the block could overrun it (so the caller keeps the array returned).
    """
    low = state[_U(0)]
    rng = state[_U(1)]
    pos = state[_U(2)]
    # A decision costs at most 16 bits and the coder's rounding at most 1/150 bit more, so
    # ``2 * nd + nd // 64`` bytes bound a block, with room for the 4 flushed at the end.
    need = pos + 2 * nd + (nd >> 6) + 16
    if need > out.size:
        grown = np.empty(max(2 * out.size, need), dtype=np.uint8)
        for j in range(pos):
            grown[_U(j)] = out[_U(j)]
        out = grown
    for i in range(nd):
        d = np.int64(dec[_U(i)])
        low, rng, pos = _enc(low, rng, pos, out, probs, d >> 1, d & 1)
    state[_U(0)] = low
    state[_U(1)] = rng
    state[_U(2)] = pos
    return out


@njit(cache=True, error_model="numpy")
def finish_coding(state: Any, out: Any) -> Any:
    """Flush the coder after the last block (:func:`code_decisions`); returns the bytes."""
    low = state[_U(0)]
    pos = state[_U(2)]
    for _ in range(4):
        out[_U(pos)] = low >> 24
        pos += 1
        low = (low << 8) & _MASK32
    return out[:pos]


@njit(cache=True, nogil=True, error_model="numpy")
def fresh_models() -> Any:
    """Every model at its initial state."""
    probs = np.empty(_NMODELS, dtype=np.int32)
    for i in range(_NMODELS):
        probs[_U(i)] = _STATE_INIT
    return probs


@njit(cache=True, error_model="numpy")
def _dec_called(
    code: int, rng: int, pos: int, buf: Any, n: int, probs: Any, i: int
) -> tuple[int, int, int, int]:
    """:func:`_dec` as a call, for the value table's decisions: a copy of the decoder inlined at
    each of their sites cost a quarter of a second of compiling, for a few thousand decisions
    a frame where the pixels make hundreds of thousands."""
    return _dec(code, rng, pos, buf, n, probs, i)


# -- shared modelling ---------------------------------------------------------------------


# Each pixel's state in one int64 of the padded working array: the residual above bit 32, a
# valid bit at 31, and the index below it. One load gives a neighbour's validity, index and
# residual (the loop's time goes on instructions, and three arrays cost three times the loads).
_VALID = np.int64(1) << 31
_INDEX = _VALID - 1

_Q9_LUT = np.array(
    [0] * 3 + [1] * 5 + [2] * 2 + [3, 4, 5] + [6] * 2 + [7] * 5 + [8] * 3, dtype=np.int64
)
_PAD = 2  # rows above and columns on each side of the padded working arrays


@njit(cache=True, error_model="numpy")
def _q9(d: int) -> Any:
    """Quantise a signed index gradient to 9 levels (0..8, 4 = zero): 0, 1, 2-3, 4-8, 9+."""
    if d > 11:
        return 8
    if d < -11:
        return 0
    return _Q9_LUT[_U(d + 11)]


def _mask_lut() -> Any:
    """Mask-bit context from the bit windows kept while walking a row.

    The context holds ten causal mask bits, from its low bit: west, west-west, north,
    north-west, north-east, north-west-west, north-east-east, north-north,
    north-north-west, north-north-east.

    The key holds, from its low bit: west and west-west (2 bits), the row above from two
    columns left to two right (5 bits, leftmost highest), and the row two above from one
    column left to one right (3 bits, leftmost highest).
    """
    lut = np.zeros(1024, dtype=np.int64)
    for key in range(1024):
        wb = key & 3
        r1 = (key >> 2) & 31
        r2 = key >> 7
        lut[key] = (
            wb
            | (((r1 >> 2) & 1) << 2)
            | (((r1 >> 3) & 1) << 3)
            | (((r1 >> 1) & 1) << 4)
            | (((r1 >> 4) & 1) << 5)
            | ((r1 & 1) << 6)
            | (((r2 >> 1) & 1) << 7)
            | (((r2 >> 2) & 1) << 8)
            | ((r2 & 1) << 9)
        )
    return lut


_MASK_LUT = _mask_lut()


@njit(cache=True, error_model="numpy")
def _mask_row_start(px: Any, o: int, s: int) -> tuple[int, int]:
    """Bit windows of the two rows above for the first pixel of a row (see :func:`_mask_lut`)."""
    n = o - s
    nn = n - s
    r1 = (
        (_bit_valid(px[_U(n - 2)]) << 4)
        | (_bit_valid(px[_U(n - 1)]) << 3)
        | (_bit_valid(px[_U(n)]) << 2)
        | (_bit_valid(px[_U(n + 1)]) << 1)
        | _bit_valid(px[_U(n + 2)])
    )
    r2 = (
        (_bit_valid(px[_U(nn - 1)]) << 2)
        | (_bit_valid(px[_U(nn)]) << 1)
        | _bit_valid(px[_U(nn + 1)])
    )
    return r1, r2


@njit(cache=True, inline="always", error_model="numpy")
def _bit_valid(state: int) -> int:
    """1 if the packed pixel ``state`` is valid, else 0."""
    return (state >> 31) & 1


@njit(cache=True, error_model="numpy")
def _absdiff(a: int, b: int) -> int:
    return a - b if a > b else b - a


@njit(cache=True, inline="always", error_model="numpy")
def _predict(
    px: Any, o: int, s: int, last: int, glut: Any, elut: Any
) -> tuple[int, int, int, int, int]:
    """Prediction, model context, gradient-triple context and the west and north residuals at
    flat position ``o`` of the packed working array ``px``.

    The array is padded with invalid pixels, so no neighbour lookup leaves it. The branches
    set the prediction, the gradient activity ``g``, the error sum ``e`` and the neighbour
    class; the context is formed once, after them (one exit keeps the compiled loop small).
    """
    n = o - s
    pa = px[_U(o - 1)]
    pb = px[_U(n)]
    pc = px[_U(n - 1)]
    va = (pa & _VALID) != 0
    vb = (pb & _VALID) != 0
    a = pa & _INDEX
    b = pb & _INDEX
    ea = pa >> 32
    eb = pb >> 32
    e = (ea if ea > 0 else -ea) + (eb if eb > 0 else -eb)
    q = _NOBIAS
    if va and vb and (pc & _VALID) != 0:
        c = pc & _INDEX
        # The median edge detector as a clamp (no jumps): a + b - c kept within [min, max].
        p = min(max(a + b - c, min(a, b)), max(a, b))
        g = _absdiff(a, c) + _absdiff(b, c)
        pd = px[_U(n + 1)]
        if (pd & _VALID) != 0:
            d = pd & _INDEX
            g += _absdiff(b, d)
            q = (_q9(d - b) * 9 + _q9(b - c)) * 9 + _q9(c - a)
            cls = 0
        else:
            g += g >> 1
            q = (4 * 9 + _q9(b - c)) * 9 + _q9(c - a)
            cls = 1
    elif va and vb:
        p = (a + b) >> 1
        g = 2 * _absdiff(a, b)
        cls = 2
    elif va:
        p = a
        pw = px[_U(o - 2)]
        g = 2 * _absdiff(a, pw & _INDEX) if (pw & _VALID) != 0 else 0
        e *= 2
        cls = 3
    elif vb:
        p = b
        pn = px[_U(n - s)]
        g = 2 * _absdiff(b, pn & _INDEX) if (pn & _VALID) != 0 else 0
        e *= 2
        cls = 3
    else:
        pd = px[_U(n + 1)]
        vd = (pd & _VALID) != 0
        p = pd & _INDEX if vd else last
        g = 0
        e = 1 if vd else 0
        cls = 4
    gbin = glut[_U(g)] if g < 33 else 7
    ebin = elut[_U(e)] if e < 9 else 5
    return p, (cls * _NGBIN + gbin) * _NEBIN + ebin, q, ea, eb


@njit(cache=True, inline="always", error_model="numpy")
def _coding_ctx(ctx: int, q: int, ew: int, en: int) -> tuple[int, int]:
    """Models of the zero flag and of the sign, from the west and north residuals."""
    if q == _NOBIAS:
        return _M_ZERO + ctx, _M_SIGN + ctx
    eb = ctx % _NEBIN
    sg = (0 if ew == 0 else (1 if ew > 0 else 2)) * 3 + (0 if en == 0 else (1 if en > 0 else 2))
    return _M_QZERO + q * _NQE + (eb if eb < _NQE else _NQE - 1), _M_QSIGN + q * 9 + sg


@njit(cache=True, error_model="numpy")
def _gap_ctx(pgap: int) -> int:
    if pgap < 2:
        return pgap
    if pgap < 4:
        return 2
    if pgap < 16:
        return 3
    return 4 if pgap < 64 else 5


@njit(cache=True, inline="always", error_model="numpy")
def _clamp_index(v: int) -> int:
    if v < 1:
        return 1
    return v if v < 65535 else 65535


# -- shared pieces of the bitstream (both body versions) ------------------------------------


@njit(cache=True, error_model="numpy")
def write_table(
    dec: Any, nd: int, rank: Any, ntable: int, state: Any, out: Any, probs: Any
) -> tuple[int, Any]:
    """Append the decisions of the value table to ``dec`` from ``nd``: its length, then each
    entry's gap to the previous one. A block of more than :data:`DECISION_BLOCK` is coded
    (:func:`code_decisions`) before the next entry, so ``dec`` needs room for the block and
    48 more. Returns the decisions left in ``dec`` and the output array."""
    for j in range(16):
        dec[_U(nd)] = 2 * (_M_HDR + j) + ((ntable - 1) >> (15 - j) & 1)
        nd += 1
    prev = _B0
    pgap = _B0
    for v in range(1, 65536):
        if rank[_U(v)] == 0:
            continue
        if nd > DECISION_BLOCK:
            out = code_decisions(dec, nd, state, out, probs)
            nd = _B0
        gap = v - prev - 1
        g = _gap_ctx(pgap)
        if gap == 0:
            dec[_U(nd)] = 2 * (_M_TZERO + g)
            nd += 1
        else:
            dec[_U(nd)] = 2 * (_M_TZERO + g) + 1
            nd += 1
            k = 0
            while (gap >> (k + 1)) != 0:
                k += 1
            for j in range(k):
                dec[_U(nd)] = 2 * (_M_TEXP + g * 16 + j) + 1
                nd += 1
            if k < 15:
                dec[_U(nd)] = 2 * (_M_TEXP + g * 16 + k)
                nd += 1
            for j in range(k - 1, -1, -1):
                dec[_U(nd)] = 2 * (_M_TMANT + k * 16 + j) + ((gap >> j) & 1)
                nd += 1
        pgap = gap
        prev = v
    return nd, out


@njit(cache=True, error_model="numpy")
def read_table(
    code: int, rng: int, pos: int, buf: Any, n: int, probs: Any, table: Any
) -> tuple[int, int, int, int]:
    """Decode the value table into ``table``; returns its length, or minus an ``ERR_*`` status."""
    ntable = _B0
    for j in range(16):
        bit, code, rng, pos = _dec_called(code, rng, pos, buf, n, probs, _M_HDR + j)
        ntable = (ntable << 1) | bit
    ntable += 1
    prev = _B0
    pgap = _B0
    for i in range(ntable):
        g = _gap_ctx(pgap)
        bit, code, rng, pos = _dec_called(code, rng, pos, buf, n, probs, _M_TZERO + g)
        gap = 0
        if bit:
            k = 0
            while k < 15:
                bit, code, rng, pos = _dec_called(
                    code, rng, pos, buf, n, probs, _M_TEXP + g * 16 + k
                )
                if bit == 0:
                    break
                k += 1
            gap = 1
            for j in range(k - 1, -1, -1):
                bit, code, rng, pos = _dec_called(
                    code, rng, pos, buf, n, probs, _M_TMANT + k * 16 + j
                )
                gap = (gap << 1) | bit
        v = prev + gap + 1
        if v > 65535:
            return -ERR_TABLE, code, rng, pos
        table[_U(i)] = v
        prev = v
        pgap = gap
    if pos > n:
        return -ERR_LENGTH, code, rng, pos
    return ntable, code, rng, pos


@njit(cache=True, inline="always", error_model="numpy")
def write_residual(dec: Any, nd: int, zc: int, sc: int, ctx: int, e: int) -> int:
    """Append the decisions of a residual: zero flag, sign, unary exponent, mantissa bits."""
    if e == 0:
        dec[_U(nd)] = 2 * zc
        return nd + 1
    dec[_U(nd)] = 2 * zc + 1
    dec[_U(nd + 1)] = 2 * sc + (1 if e < 0 else 0)
    nd += 2
    m = -e if e < 0 else e
    k = 0
    while (m >> (k + 1)) != 0:
        k += 1
    e0 = _M_EXP + ctx * _EXP
    for j in range(k):
        dec[_U(nd)] = 2 * (e0 + j) + 1
        nd += 1
    if k < 15:
        dec[_U(nd)] = 2 * (e0 + k)
        nd += 1
    m0 = _M_MANT + (ctx // _PERCLASS) * 256 + k * 16
    for j in range(k - 1, -1, -1):
        dec[_U(nd)] = 2 * (m0 + j) + ((m >> j) & 1)
        nd += 1
    return nd


@njit(cache=True, inline="always", error_model="numpy")
def read_residual(
    code: int, rng: int, pos: int, buf: Any, n: int, probs: Any, zc: int, sc: int, ctx: int
) -> tuple[int, int, int, int]:
    """Decode a residual coded by :func:`write_residual`."""
    nz, code, rng, pos = _dec(code, rng, pos, buf, n, probs, zc)
    if not nz:
        return 0, code, rng, pos
    neg, code, rng, pos = _dec(code, rng, pos, buf, n, probs, sc)
    e0 = _M_EXP + ctx * _EXP
    k = 0
    while k < 15:
        bit, code, rng, pos = _dec(code, rng, pos, buf, n, probs, e0 + k)
        if bit == 0:
            break
        k += 1
    m0 = _M_MANT + (ctx // _PERCLASS) * 256 + k * 16
    m = 1
    for j in range(k - 1, -1, -1):
        bit, code, rng, pos = _dec(code, rng, pos, buf, n, probs, m0 + j)
        m = (m << 1) | bit
    return (-m if neg else m), code, rng, pos
