"""Sparse depth made from dense depth, the way active depth sensors lose it.

Codecs behave differently on depth with many holes: a codec tuned on dense frames can lose to
plain run-length coders there. :func:`sparsify_depth` turns real dense frames into realistic
sparse ones, so codecs can be compared on both (``benchmarks/test_bench_depth_sets.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["sparsify_depth"]


def sparsify_depth(depth: np.ndarray[Any, Any], seed: int = 0) -> np.ndarray[Any, Any]:
    """Real depth with large regions removed the way active depth sensors lose them.

    Deterministic for a given ``seed``. Four physical causes are imitated, each on the image
    itself (so edges and surfaces stay the sensor's own):

    * **range limit**: everything beyond the 75th percentile of the valid depth is dropped
      (the projector's pattern is too faint far away);
    * **dark and shiny surfaces**: smooth blobs covering about a third of the view are
      dropped (a low-frequency random field, thresholded: absorbing or specular materials
      return no pattern);
    * **occlusion shadows**: on the far side of every depth step of more than 8 % a band of
      12 pixels is dropped (the projector does not see behind the near object's edge);
    * **edge speckle**: half the pixels within 2 pixels of a step are dropped at random
      (mixed pixels the sensor's filters reject).

    The result keeps 35–50 % of the pixels of a dense frame, like a RealSense looking at
    a cluttered scene with dark and glossy objects.
    """
    rng = np.random.default_rng(seed)
    d: np.ndarray[Any, Any] = np.asarray(depth)
    h, w = d.shape
    out: np.ndarray[Any, Any] = d.copy()
    valid = d > 0
    if not valid.any():
        return out
    drop = d > np.percentile(d[valid], 75)
    # A smooth random field: a coarse grid of noise, upsampled bilinearly.
    gh, gw = max(2, h // 60 + 2), max(2, w // 60 + 2)
    grid = rng.standard_normal((gh, gw))
    ys = np.linspace(0, gh - 1, h)
    xs = np.linspace(0, gw - 1, w)
    y0 = np.minimum(ys.astype(int), gh - 2)
    x0 = np.minimum(xs.astype(int), gw - 2)
    fy = (ys - y0)[:, None]
    fx = (xs - x0)[None, :]
    field = (
        grid[y0][:, x0] * (1 - fy) * (1 - fx)
        + grid[y0 + 1][:, x0] * fy * (1 - fx)
        + grid[y0][:, x0 + 1] * (1 - fy) * fx
        + grid[y0 + 1][:, x0 + 1] * fy * fx
    )
    drop |= field > np.quantile(field, 0.67)
    # Depth steps: the far side of a jump between horizontal neighbours.
    left = d[:, :-1].astype(np.float64)
    right = d[:, 1:].astype(np.float64)
    both = (left > 0) & (right > 0)
    far_right = both & (right > left * 1.08)
    far_left = both & (left > right * 1.08)
    step = np.zeros_like(valid)
    step[:, 1:] |= far_right
    step[:, :-1] |= far_left
    shadow = np.zeros_like(valid)
    for k in range(12):
        shadow[:, 1 + k :] |= far_right[:, : w - 1 - k]
    drop |= shadow
    near = step.copy()
    for k in (1, 2):
        near[:, k:] |= step[:, :-k]
        near[:, :-k] |= step[:, k:]
        near[k:, :] |= step[:-k, :]
        near[:-k, :] |= step[k:, :]
    drop |= near & (rng.random((h, w)) < 0.5)
    out[drop] = 0
    return out
