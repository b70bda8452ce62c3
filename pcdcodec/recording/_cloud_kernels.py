"""Compiled loops of packing a kept organized cloud (numba, cached on disk): one pass over
its points splits them into the corrections of x, y and z to a rebuild, the packed colours,
and whether any other byte is set. The cloud's bytes are the writer's own (a message it was
given), so the loops trust the shapes the caller checked."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

__all__ = ["split_points"]


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _u32(data: Any, words: Any, at: int) -> Any:
    """The little-endian uint32 at byte ``at``: from ``words`` (``data`` as uint32, one
    element when unusable) when ``at`` is aligned."""
    if words.shape[0] > 1 and (at & 3) == 0:
        return words[at >> 2]
    return np.uint32(
        np.uint32(data[at])
        | (np.uint32(data[at + 1]) << np.uint32(8))
        | (np.uint32(data[at + 2]) << np.uint32(16))
        | (np.uint32(data[at + 3]) << np.uint32(24))
    )


@njit(cache=True, nogil=True, error_model="numpy")
def split_points(
    data: Any,
    words: Any,
    step: int,
    offsets: Any,
    rest: Any,
    rest_words: Any,
    predicted: Any,
    depth: Any,
    max_ulps: int,
    diffs: Any,
    colours: Any,
) -> tuple[bool, int, int, int, bool]:
    """Compare each point's x, y and z (little-endian float32 bits at ``offsets[:3]`` of
    every ``step`` bytes of ``data``; ``words``: ``data`` as little-endian uint32 where its
    length allows, else one element) with ``predicted`` (3 x H x W uint32 bits): their
    differences, modulo 2**32, go to ``diffs`` (3 x H x W). Returns ``(fits, nonzero x,
    nonzero y, nonzero z, rest set)``: ``fits`` is false (and the pass stops) when a point
    with depth is more than ``max_ulps`` from the prediction. With ``offsets[3] >= 0`` the
    packed colour's r, g and b (stored b, g, r) go to ``colours`` (H x W x 3). ``rest set``:
    any byte at the ``rest`` offsets of a point, or any 4 at the ``rest_words`` offsets (read
    as one word, aligned), is not zero."""
    h, w = depth.shape
    n = h * w
    flat_depth = depth.reshape(n)
    flat_pred = predicted.reshape(3, n)
    flat_diffs = diffs.reshape(3, n)
    flat_colours = colours.reshape(n, 3)
    counts = np.zeros(3, np.int64)
    rest_set = False
    span = np.uint32(2 * max_ulps)
    near = np.uint32(max_ulps)
    n_rest = rest.shape[0]
    n_words = rest_words.shape[0]
    rgb = offsets[3]
    aligned = words.shape[0] > 1 and step % 4 == 0
    for axis in range(3):
        aligned = aligned and offsets[axis] % 4 == 0
    wstep = step >> 2
    wx, wy, wz = offsets[0] >> 2, offsets[1] >> 2, offsets[2] >> 2
    for k in range(n):
        base = k * step
        with_depth = flat_depth[k] != 0
        if aligned:  # x, y and z as words
            w0 = k * wstep
            dx = np.uint32(words[w0 + wx] - flat_pred[0, k])
            dy = np.uint32(words[w0 + wy] - flat_pred[1, k])
            dz = np.uint32(words[w0 + wz] - flat_pred[2, k])
            if with_depth and (
                np.uint32(dx + near) > span
                or np.uint32(dy + near) > span
                or np.uint32(dz + near) > span
            ):
                return False, 0, 0, 0, False
            flat_diffs[0, k] = dx
            flat_diffs[1, k] = dy
            flat_diffs[2, k] = dz
            counts[0] += dx != 0
            counts[1] += dy != 0
            counts[2] += dz != 0
        for axis in range(0 if not aligned else 3, 3):
            d = np.uint32(_u32(data, words, base + offsets[axis]) - flat_pred[axis, k])
            if with_depth and np.uint32(d + near) > span:
                return False, 0, 0, 0, False
            flat_diffs[axis, k] = d
            counts[axis] += d != 0
        if rgb >= 0:
            flat_colours[k, 0] = data[base + rgb + 2]
            flat_colours[k, 1] = data[base + rgb + 1]
            flat_colours[k, 2] = data[base + rgb]
        if not rest_set:
            for r in range(n_words):
                if words[(base + rest_words[r]) >> 2] != 0:
                    rest_set = True
            for r in range(n_rest):
                if data[base + rest[r]] != 0:
                    rest_set = True
    return True, counts[0], counts[1], counts[2], rest_set
