"""Compiled helper of the float32 value-table layout (numba, cached on disk)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

#: Slots of the open-addressing table: four times the most distinct values a table may hold.
_SLOTS = 1 << 18


@njit(cache=True, nogil=True, error_model="numpy")
def distinct_values(bits: Any, limit: int) -> tuple[Any, Any, int]:
    """The distinct values of ``bits`` (uint32, 1-D) in order of first appearance.

    Returns ``(values, first, status)``: ``first[i]`` is the position in ``values`` of
    ``bits[i]``. ``status`` is 0 on success, 1 when there are more than ``limit`` (≤ 65536)
    distinct values, and 2 when the hash probes pass a linear bound (keys built to collide),
    so the caller falls back to sorting.
    """
    mask = _SLOTS - 1
    keys = np.zeros(_SLOTS, dtype=np.uint32)
    slot_pos = np.zeros(_SLOTS, dtype=np.int32)  # 0 = empty, else 1 + position in values
    values = np.empty(limit, dtype=np.uint32)
    first = np.empty(bits.size, dtype=np.int32)
    n = 0
    probes = 0
    budget = 64 * bits.size + 1024
    for i in range(bits.size):
        k = bits[i]
        s = np.int64((np.uint64(k) * np.uint64(0x9E3779B1)) >> np.uint64(14)) & mask
        while slot_pos[s] != 0 and keys[s] != k:
            s = (s + 1) & mask
            probes += 1
        if probes > budget:
            return values[:0], first[:0], 2
        if slot_pos[s] == 0:
            if n == limit:
                return values[:0], first[:0], 1
            keys[s] = k
            values[n] = k
            n += 1
            slot_pos[s] = n
        first[i] = slot_pos[s] - 1
    return values[:n], first, 0
