"""Where ``depthac``'s decode time goes, step by step, on a frame of every depth set.

Run: ``python scripts/depthac_profile.py [--rounds 25] [--sets sample,spot]`` (one thread: the
coder is single-threaded, and libjxl is asked for one thread).

A compiled loop cannot be stopped half way, so each step is timed as the difference between
variants of the decode loop, all run on the same frame and interleaved round by round (the
best of ``--rounds`` each, so a busy neighbour process lands on every variant alike):

The frame of each set is the middle one of three spread over it. Then:

* a ladder over the pixels that does the decoder's work without the range decoder, the
  decoded values known in advance: the working arrays (**setup**), the walk over the pixels
  with the decoder's stores (**pixel loop**), plus the hole-mask context of every pixel
  (**hole-mask context**), plus prediction and the residual's contexts at every valid pixel
  (**prediction and contexts**); the real decoder minus the last rung is the cost of the
  **binary decisions** (the range decoder with everything that waits on its bits);
* a replay of the frame's decisions alone, in order, each with its recorded model, that splits
  the decisions: the real decoding step; the same with the bit known (no jump on the
  unpredictable bit: the **mispredicted branches**); without the probability update
  (**adaptation**); without the byte-wise **renormalisation**; and the replay loop itself
  (**range arithmetic** is the rest). What the decisions cost in the decoder beyond their
  replay is the **loop waiting on the bits**: each pixel's context needs the previous pixel's
  decoded value, so the work around the decisions cannot overlap them.

Every variant is checked: the ladder's output and the replay's bits equal the real decode's.
The tables give ms per frame and ns per pixel, the decisions per pixel by kind, and
``depthac`` against JPEG XL effort 2 measured in the same rounds.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import pcdcodec
from pcdcodec.bench.sequences import ALL_DEPTH_SETS, load_frames, set_present
from pcdcodec.depth import _depthac_kernels as kern  # the loops under study
from pcdcodec.depth import _depthac_model as model  # their model and coder
from pcdcodec.depth import read_header

_U = np.uint64
# Kinds of decision, in the trace.
TABLE, MASK, ZERO, SIGN, EXP, MANT = range(6)
KINDS = ("table", "mask", "zero", "sign", "exponent", "mantissa")


@njit(cache=False, error_model="numpy")
def trace_decode(buf: Any, out_img: Any, models: Any, kinds: Any, bits: Any, arrays: Any) -> Any:
    """The lossless decoder (``decode_image``, near = 0) recording each decision's model, kind
    and bit, and leaving its packed working array (see ``model._VALID``) in ``arrays``; returns
    the count."""
    h, w = out_img.shape
    n = buf.size
    code = (
        (np.int64(buf[1]) << 24)
        | (np.int64(buf[2]) << 16)
        | (np.int64(buf[3]) << 8)
        | np.int64(buf[4])
    )
    use_table = (buf[0] & 1) != 0
    code_mask = (buf[0] & 2) != 0
    rng = model._MASK32
    pos = 5
    probs = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int32)
    table = np.zeros(65536, dtype=np.int64)
    t = 0

    def rec(i: int, kind: int, bit: int, t: int) -> int:
        models[t] = i
        kinds[t] = kind
        bits[t] = bit
        return t + 1

    if use_table:
        ntable = 0
        for j in range(16):
            bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, model._M_HDR + j)
            t = rec(model._M_HDR + j, TABLE, bit, t)
            ntable = (ntable << 1) | bit
        ntable += 1
        prev = 0
        pgap = 0
        for i in range(ntable):
            g = model._gap_ctx(pgap)
            bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, model._M_TZERO + g)
            t = rec(model._M_TZERO + g, TABLE, bit, t)
            gap = 0
            if bit:
                k = 0
                while k < 15:
                    mi = model._M_TEXP + g * 16 + k
                    bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, mi)
                    t = rec(mi, TABLE, bit, t)
                    if bit == 0:
                        break
                    k += 1
                gap = 1
                for j in range(k - 1, -1, -1):
                    mi = model._M_TMANT + k * 16 + j
                    bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, mi)
                    t = rec(mi, TABLE, bit, t)
                    gap = (gap << 1) | bit
            v = prev + gap + 1
            table[i] = v
            prev = v
            pgap = gap
    else:
        for i in range(65536):
            table[i] = i
    st = w + 2 * model._PAD
    px = arrays
    last = 0
    mlut = model._MASK_LUT
    glut = model._G_LUT
    elut = model._E_LUT
    for y in range(h):
        o0 = (y + model._PAD) * st + model._PAD
        r1, r2 = model._mask_row_start(px, o0, st)
        wb = 0
        for x in range(w):
            o = o0 + x
            if code_mask:
                mc = mlut[(r2 << 7) | (r1 << 2) | wb]
                bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, model._M_MASK + mc)
                t = rec(model._M_MASK + mc, MASK, bit, t)
                r1 = ((r1 << 1) & 31) | ((px[o - st + 3] >> 31) & 1)
                r2 = ((r2 << 1) & 7) | ((px[o - 2 * st + 2] >> 31) & 1)
                wb = ((wb << 1) | bit) & 3
                if bit == 0:
                    out_img[y, x] = 0
                    continue
            p, ctx, q, ew, en = model._predict(px, o, st, last, glut, elut)
            zc, sc = model._coding_ctx(ctx, q, ew, en)
            nz, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, zc)
            t = rec(zc, ZERO, nz, t)
            e = 0
            if nz:
                neg, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, sc)
                t = rec(sc, SIGN, neg, t)
                e0 = model._M_EXP + ctx * model._EXP
                k = 0
                while k < 15:
                    bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, e0 + k)
                    t = rec(e0 + k, EXP, bit, t)
                    if bit == 0:
                        break
                    k += 1
                m0 = model._M_MANT + (ctx // model._PERCLASS) * 256 + k * 16
                m = 1
                for j in range(k - 1, -1, -1):
                    bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, m0 + j)
                    t = rec(m0 + j, MANT, bit, t)
                    m = (m << 1) | bit
                e = -m if neg else m
            v = p + e
            px[o] = (e << 32) | model._VALID | v
            out_img[y, x] = table[v]
            last = v
    return t


@njit(cache=False, error_model="numpy")
def setup_only(h: int, w: int) -> int:
    """The decoder's allocations: models, value table, the padded packed working array."""
    probs = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int32)
    table = np.zeros(65536, dtype=np.int64)
    st = w + 2 * model._PAD
    px = np.zeros((h + model._PAD) * st + model._PAD, dtype=np.int64)
    return probs[0] + table[1] + px[2]


@njit(cache=False, error_model="numpy")
def ladder(out_img: Any, known: Any, table: Any, code_mask: bool, stage: int, work: Any) -> int:
    """The decoder's pixel loop with the decoded values known: stage 0 stores only, 1 adds the
    hole-mask context, 2 adds prediction and coding contexts. ``work`` (the packed working
    array) starts zeroed; ``known`` holds its final state."""
    h, w = out_img.shape
    st = w + 2 * model._PAD
    mlut = model._MASK_LUT
    glut = model._G_LUT
    elut = model._E_LUT
    acc = 0
    last = 0
    for y in range(h):
        o0 = (y + model._PAD) * st + model._PAD
        r1, r2 = model._mask_row_start(work, o0, st)
        wb = 0
        for x in range(w):
            o = o0 + x
            bit = (known[_U(o)] >> 31) & 1
            if code_mask:
                if stage >= 1:
                    acc += mlut[_U((r2 << 7) | (r1 << 2) | wb)]
                    r1 = ((r1 << 1) & 31) | ((work[_U(o - st + 3)] >> 31) & 1)
                    r2 = ((r2 << 1) & 7) | ((work[_U(o - 2 * st + 2)] >> 31) & 1)
                    wb = ((wb << 1) | bit) & 3
                if bit == 0:
                    out_img[_U(y), _U(x)] = 0
                    continue
            if stage >= 2:
                p, ctx, q, ew, en = model._predict(work, o, st, last, glut, elut)
                zc, sc = model._coding_ctx(ctx, q, ew, en)
                acc += p + zc + sc
            state = known[_U(o)]
            v = state & model._INDEX
            work[_U(o)] = state
            out_img[_U(y), _U(x)] = table[_U(v)]
            last = v
    return acc


@njit(cache=False, error_model="numpy")
def replay(buf: Any, models: Any, bits: Any, count: int, mode: int) -> tuple[int, int]:
    """The frame's decisions alone, in order. mode 0: the real decoding step; 1: the bit is
    known (selects, no jump on it); 2: and no adaptation; 3: and no renormalisation; 4: only
    the loop over the trace. Returns the sum of the bits (modes 0-1 must give the trace's) and
    the final code value (returned so that no step of the arithmetic is optimised away)."""
    n = buf.size
    code = (
        (np.int64(buf[1]) << 24)
        | (np.int64(buf[2]) << 16)
        | (np.int64(buf[3]) << 8)
        | np.int64(buf[4])
    )
    rng = model._MASK32
    pos = 5
    probs = np.full(model._NMODELS, model._STATE_INIT, dtype=np.int32)
    rate = model._RATE_LUT
    total = 0
    if mode == 0:
        for t in range(count):
            bit, code, rng, pos = model._dec(code, rng, pos, buf, n, probs, models[_U(t)])
            total += bit
        return total, code
    if mode == 4:
        for t in range(count):
            total += models[_U(t)] + bits[_U(t)]
        return total, code
    for t in range(count):
        i = models[_U(t)]
        one = bits[_U(t)] != 0
        s = probs[_U(i)]
        p = s & 0xFFFF
        bound = (rng >> 16) * p
        code = code - bound if one else code
        rng = rng - bound if one else bound
        if mode == 1:
            c = s >> 16
            r = rate[_U(c)]
            c = (c + 1 if c < 24 else c) << 16
            probs[_U(i)] = c | ((p - (p >> r)) if one else (p + ((65536 - p) >> r)))
        if mode <= 2:
            while rng < model._TOP:
                byte = np.int64(buf[_U(pos)]) if pos < n else np.int64(0)
                pos += 1
                code = ((code << 8) | byte) & model._MASK32
                rng <<= 8
        # mode 3: no byte loop; the range runs down to 0, which changes no instruction's time
        total += 1 if one else 0
    return total, code + rng + pos


def best_of(fns: dict[str, Callable[[], Any]], rounds: int) -> dict[str, float]:
    """Best seconds of each callable, the callables interleaved round by round."""
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(rounds):
        for name, fn in fns.items():
            start = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - start)
    return best


def profile(depth: np.ndarray[Any, Any], rounds: int) -> dict[str, Any]:
    import imagecodecs

    codec = pcdcodec.get_codec("depthac")
    data = codec.encode(depth)
    header = read_header(data)
    body = np.frombuffer(data, np.uint8)[
        header.header_size : header.header_size + header.body_length
    ].copy()
    h, w = depth.shape
    st = w + 2 * model._PAD
    size = (h + model._PAD) * st + model._PAD
    worst = 40 * h * w + 2**20
    models = np.zeros(worst, np.int64)
    kinds = np.zeros(worst, np.uint8)
    bits = np.zeros(worst, np.uint8)
    known = np.zeros(size, np.int64)
    out = np.empty((h, w), np.uint16)
    count = trace_decode(body, out, models, kinds, bits, known)
    np.testing.assert_array_equal(out, depth)
    code_mask = bool(body[0] & 2)
    table = np.zeros(65536, np.int64)
    table[(known & model._INDEX)[(known & model._VALID) != 0]] = depth[depth > 0]
    if not body[0] & 1:
        table[:] = np.arange(65536)

    def run_ladder(stage: int) -> Callable[[], Any]:
        def fn() -> Any:
            work = np.zeros(size, np.int64)
            return ladder(out, known, table, code_mask, stage, work)

        return fn

    for stage in range(3):
        out[:] = 0
        run_ladder(stage)()
        np.testing.assert_array_equal(out, depth)
    for mode in (0, 1):
        assert replay(body, models, bits, count, mode)[0] == int(bits[:count].sum())
    jxl = imagecodecs.jpegxl_encode(depth, lossless=True, effort=2, numthreads=1)
    img = np.empty((h, w), np.uint16)
    fns: dict[str, Callable[[], Any]] = {
        "decode": lambda: kern.decode_image(body, img, 0),
        "setup": lambda: setup_only(h, w),
        "loop": run_ladder(0),
        "mask": run_ladder(1),
        "predict": run_ladder(2),
        "replay": lambda: replay(body, models, bits, count, 0),
        "known": lambda: replay(body, models, bits, count, 1),
        "noadapt": lambda: replay(body, models, bits, count, 2),
        "norenorm": lambda: replay(body, models, bits, count, 3),
        "trace": lambda: replay(body, models, bits, count, 4),
        "codec decode": lambda: codec.decode(data),
        "jxl decode": lambda: imagecodecs.jpegxl_decode(jxl, numthreads=1),
        "codec encode": lambda: codec.encode(depth),
        "jxl encode": lambda: imagecodecs.jpegxl_encode(
            depth, lossless=True, effort=2, numthreads=1
        ),
    }
    for fn in fns.values():
        fn()
    t = best_of(fns, rounds)
    # The time of the zeroed work arrays is the ladder's own and is not in the steps.
    zeros = best_of({"z": lambda: np.zeros((3, size), np.int32)}, rounds)["z"]
    steps = {
        "setup": t["setup"],
        "pixel loop and stores": t["loop"] - zeros,
        "hole-mask context": t["mask"] - t["loop"],
        "prediction and contexts": t["predict"] - t["mask"],
        "binary decisions": t["decode"] - t["setup"] - (t["predict"] - zeros),
        "  range arithmetic": t["norenorm"] - t["trace"],
        "  renormalisation": t["noadapt"] - t["norenorm"],
        "  adaptation": t["known"] - t["noadapt"],
        "  mispredicted bit branches": t["replay"] - t["known"],
        "  (decisions replayed alone)": t["replay"] - t["trace"],
        "  (the loop waiting on the bits)": (t["decode"] - t["setup"] - t["predict"] + zeros)
        - (t["replay"] - t["trace"]),
        "decode (kernel)": t["decode"],
    }
    per_kind = np.bincount(kinds[:count], minlength=len(KINDS)) / depth.size
    return {
        "steps": steps,
        "times": t,
        "decisions": dict(zip(KINDS, per_kind.tolist(), strict=True)),
        "bytes": len(data),
        "jxl bytes": len(jxl),
        "holes": float((depth == 0).mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=25, help="best of this many, interleaved")
    parser.add_argument("--sets", default="", help="comma-separated sets (default: every one)")
    args = parser.parse_args()
    names = [s for s in (args.sets.split(",") if args.sets else ALL_DEPTH_SETS)]
    results: dict[str, dict[str, Any]] = {}
    shapes: dict[str, tuple[int, int]] = {}
    for name in names:
        if not set_present(name):
            print(f"{name}: not present, skipped", file=sys.stderr)
            continue
        frames = load_frames(name, 3)
        depth = frames[len(frames) // 2]  # mid-sequence: the sample is TUM's first frames
        shapes[name] = depth.shape
        results[name] = profile(depth, args.rounds)
        print(f"{name}: done", file=sys.stderr)

    def table(title: str, rows: list[str], value: Callable[[str, str], str]) -> None:
        print(f"\n{title}")
        print("| step | " + " | ".join(results) + " |")
        print("|---|" + "---|" * len(results))
        for row in rows:
            print(f"| {row} | " + " | ".join(value(name, row) for name in results) + " |")

    steps = list(next(iter(results.values()))["steps"])
    table(
        "depthac decode, per step: ms per frame / ns per pixel (best of "
        f"{args.rounds}, interleaved, one thread)",
        steps,
        lambda n, r: (
            f"{results[n]['steps'][r] * 1e3:.2f} / "
            f"{results[n]['steps'][r] * 1e9 / (shapes[n][0] * shapes[n][1]):.1f}"
        ),
    )
    table(
        "decisions per pixel, by kind",
        [*KINDS, "all"],
        lambda n, r: (
            f"{sum(results[n]['decisions'].values()):.3f}"
            if r == "all"
            else f"{results[n]['decisions'][r]:.3f}"
        ),
    )
    ops = ["codec encode", "jxl encode", "codec decode", "jxl decode"]
    table(
        "depthac against JPEG XL effort 2 (imagecodecs, numthreads=1), ms per frame",
        [*ops, "encode / jxl", "decode / jxl", "size", "ratio", "jxl ratio", "holes"],
        lambda n, r: _cell(results[n], shapes[n], r),
    )


def _cell(res: dict[str, Any], shape: tuple[int, int], row: str) -> str:
    t = res["times"]
    if row == "encode / jxl":
        return f"{t['codec encode'] / t['jxl encode']:.2f}"
    if row == "decode / jxl":
        return f"{t['codec decode'] / t['jxl decode']:.2f}"
    if row == "size":
        return f"{shape[1]}x{shape[0]}"
    if row == "ratio":
        return f"{shape[0] * shape[1] * 2 / res['bytes']:.2f}"
    if row == "jxl ratio":
        return f"{shape[0] * shape[1] * 2 / res['jxl bytes']:.2f}"
    if row == "holes":
        return f"{res['holes'] * 100:.0f} %"
    return f"{t[row] * 1e3:.2f}"


if __name__ == "__main__":
    main()
