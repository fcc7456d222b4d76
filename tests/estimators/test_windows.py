"""Centred moving windows: the same at both ends (the PDR copy once took an off-centre window on the left)."""

import numpy as np

from estimators.windows import centred_bounds, moving_variance


def test_window_is_centred_and_truncated_symmetrically():
    lo, hi = centred_bounds(10, 4)
    assert (lo[0], hi[0]) == (0, 2) and (lo[-1], hi[-1]) == (7, 10)  # 2 samples at the left end, 3 at the right
    assert (lo[5], hi[5]) == (3, 7)


def test_moving_variance_equals_direct_computation():
    x = np.random.default_rng(0).normal(size=50) + 1e6  # a large offset must not cost precision
    got = moving_variance(x, 7)
    want = [np.var(x[max(i - 3, 0):min(i + 4, 50)]) for i in range(50)]
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)


def test_true_runs_are_half_open_and_filtered_by_length():
    from estimators.windows import true_runs

    mask = np.array([1, 1, 0, 1, 0, 0, 1, 1, 1], dtype=bool)
    assert true_runs(mask).tolist() == [[0, 2], [3, 4], [6, 9]]
    assert true_runs(mask, min_samples=2).tolist() == [[0, 2], [6, 9]]
    assert true_runs(np.zeros(4, bool)).shape == (0, 2)
