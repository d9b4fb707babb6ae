"""The unconstrained DTW (computed by anti-diagonals) against the row-by-row recursion."""

from __future__ import annotations

import numpy as np

from sigma_des.metrics.dtw import dtw, dtw_rows


def test_hand_computed_case() -> None:
    # |a_i - b_j|: rows (0, 2), (1, 1), (2, 0); cumulative D: (0, 2), (1, 1), (3, 1)
    a = np.array([[0.0], [1.0], [2.0]])
    b = np.array([[0.0], [2.0]])
    assert dtw(a, b) == 1.0
    assert dtw(b, a) == 1.0
    # one point against a line: the sum of its distances to every point
    assert dtw(np.array([[0.0, 0.0]]), np.array([[3.0, 4.0], [0.0, 1.0]])) == 6.0


def test_empty_series() -> None:
    e = np.empty((0, 3))
    assert dtw(e, e) == 0.0
    assert dtw(e, np.zeros((2, 3))) == np.inf
    assert dtw(np.zeros((2, 3)), e) == np.inf


def _same(x: float, y: float) -> bool:
    return (x == y and np.signbit(x) == np.signbit(y)) or (np.isnan(x) and np.isnan(y))


def test_bit_identical_to_the_row_recursion() -> None:
    """The band-limited recursion with a band covering every cell is the row-by-row
    specification; the anti-diagonal order must give the same bits, NaN and inf
    included, for unequal lengths and any dimension."""
    rng = np.random.default_rng(27)
    for trial in range(300):
        n, m, d = (int(v) for v in (rng.integers(1, 30), rng.integers(1, 30), rng.integers(1, 4)))
        a = rng.normal(size=(n, d)) * 50.0
        b = rng.normal(size=(m, d)) * 50.0 + rng.normal()
        if trial % 7 == 0:
            a[rng.integers(0, n), 0] = np.nan
        if trial % 11 == 0:
            b[rng.integers(0, m), d - 1] = np.inf
        spec = dtw_rows(a[None], b[None], max(n, m))[0]
        got = dtw(a, b)
        assert isinstance(got, float)
        assert _same(got, spec), (trial, n, m, d, got, spec)
        assert _same(dtw_rows(a[None], b[None])[0], spec)


def test_per_node_trajectories() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 5, 3))
    b = rng.normal(size=(33, 5, 3))
    per_node = dtw(a, b)
    for i in range(5):
        assert per_node[i] == dtw_rows(a[None, :, i], b[None, :, i], 40)[0]
