"""Bounded-error depthac on every depth test set, side by side with lossless depthac and jpegxl.

``taskset -c 1 pytest benchmarks/test_bench_bounded.py --benchmark-only`` adds rows
``depthac-0.5%`` and ``depthac-1%`` (``max_rel_error`` 0.005 and 0.01) to the depth test set
table of ``benchmarks/conftest.py``: ratio against raw uint16, median encode and decode ms per
frame and the times relative to jpegxl's measured in the same run. Every frame is checked
against its bound before it is timed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from benchmarks.test_bench_depth_sets import PRESENT, Prepared, prepare

CONFIGS: dict[str, dict[str, Any]] = {
    "depthac-0.5%": {"id": "depthac", "max_rel_error": 0.005},
    "depthac-1%": {"id": "depthac", "max_rel_error": 0.01},
    "depthac": {"id": "depthac"},
    "jpegxl": {"id": "jpegxl"},
}


def setup(label: str, sequence: str) -> Prepared:
    rel = CONFIGS[label].get("max_rel_error", 0.0)

    def within(back: Any, depth: Any) -> None:
        valid = depth > 0
        np.testing.assert_array_equal(back > 0, valid)
        err = np.abs(back[valid].astype(np.float64) - depth[valid])
        assert np.all(err <= rel * depth[valid])

    return prepare(CONFIGS[label], sequence, within)


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("label", CONFIGS)
def test_encode(benchmark: Any, label: str, sequence: str) -> None:
    benchmark.group = f"bounded depth encode {sequence}"
    codec, depths, encoded, info = setup(label, sequence)
    benchmark.extra_info.update(info, codec=label, sequence=sequence, kind="depthset", op="encode")
    frame = depths[len(depths) // 2]
    result = benchmark(codec.encode, frame)
    assert result == encoded[len(depths) // 2]


@pytest.mark.parametrize("sequence", PRESENT)
@pytest.mark.parametrize("label", CONFIGS)
def test_decode(benchmark: Any, label: str, sequence: str) -> None:
    benchmark.group = f"bounded depth decode {sequence}"
    codec, depths, encoded, info = setup(label, sequence)
    benchmark.extra_info.update(info, codec=label, sequence=sequence, kind="depthset", op="decode")
    index = len(depths) // 2
    result = benchmark(codec.decode, encoded[index])
    assert result.shape == depths[index].shape
