"""Centred moving-window statistics (truncated at the ends), by cumulative sums: O(N) for any window; and
the runs of True in a boolean mask."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def centred_bounds(m: int, n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Half-open ``[lo, hi)`` of the ``n``-sample window centred on each of ``m`` samples, cut at both ends."""
    i = np.arange(m)
    return np.clip(i - n // 2, 0, m), np.clip(i - n // 2 + n, 0, m)


def moving_variance(x: ArrayLike, n: int) -> FloatArray:
    """Population variance of ``x`` (N,) over the centred ``n``-sample window (fewer samples at the ends)."""
    x = np.asarray(x, dtype=np.float64)
    lo, hi = centred_bounds(len(x), n)
    xc = x - x.mean()  # centred first: the cumulative sums then keep their precision
    c1 = np.concatenate([[0.0], np.cumsum(xc)])
    c2 = np.concatenate([[0.0], np.cumsum(xc * xc)])
    k = (hi - lo).astype(np.float64)
    mean = (c1[hi] - c1[lo]) / k
    return np.maximum((c2[hi] - c2[lo]) / k - mean * mean, 0.0)


def true_runs(mask: ArrayLike, min_samples: int = 1) -> NDArray[np.int64]:
    """(K, 2) half-open ``[start, end)`` sample ranges of the runs of True in ``mask`` at least ``min_samples`` long."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, dtype=bool).astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    keep = (ends - starts) >= min_samples
    return np.column_stack([starts[keep], ends[keep]]).astype(np.int64)
