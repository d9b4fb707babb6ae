"""Dynamic time warping distance between trajectories, and the paper's normalisation.

``dtw(a, b)`` is the classic DTW (Sakoe & Chiba 1978) with Euclidean local cost
and steps (1,0), (0,1), (1,1): the minimum over monotone alignments of the summed
point distances, in metres. For ``(T, n, 3)`` swarm trajectories it returns one
distance per node.

Normalisation ``r = D T / s``. Our interpretation: ``D`` is the DTW distance,
``T`` the sampling period of the trajectories (1/30 s in the paper) and ``s`` the
duration they cover, so ``r = D / (number of samples)`` up to one sample: the
mean per-sample deviation in metres, comparable across run lengths and rates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = ["dtw", "dtw_normalised", "dtw_rows"]


@njit(cache=True)
def _dtw_banded(a: np.ndarray, b: np.ndarray, band: int) -> float:
    """Exact DTW restricted to the Sakoe–Chiba band ``|i - j| <= band`` (cells outside: inf)."""
    n, m = a.shape[0], b.shape[0]
    prev = np.full(m + 1, np.inf)
    cur = np.full(m + 1, np.inf)
    prev[0] = 0.0
    for i in range(1, n + 1):
        cur[:] = np.inf
        lo = max(1, i - band)
        hi = min(m, i + band)
        for j in range(lo, hi + 1):
            d = 0.0
            for k in range(a.shape[1]):
                e = a[i - 1, k] - b[j - 1, k]
                d += e * e
            best = prev[j - 1]
            if prev[j] < best:
                best = prev[j]
            if cur[j - 1] < best:
                best = cur[j - 1]
            cur[j] = math.sqrt(d) + best
        prev, cur = cur, prev
    return float(prev[m])


@njit(cache=True)
def _dtw(a: np.ndarray, b: np.ndarray) -> float:
    """Exact unconstrained DTW, computed one anti-diagonal ``i + j = s`` at a time.

    Every cell gets the very operations of :func:`_dtw_banded` (the same squared
    differences summed in the same order, the same comparisons, one ``sqrt`` and one
    addition), hence the same bits; but the cells of an anti-diagonal do not depend on
    each other, so the compiler runs them in SIMD lanes instead of one long chain of
    dependent additions (the fidelity DTW of a 60 s run: ≈ 4× faster).
    """
    n, m, dims = a.shape[0], b.shape[0], a.shape[1]
    if n == 0 or m == 0:
        return 0.0 if n == m else np.inf
    at = np.ascontiguousarray(a.T)  # (dims, n)
    br = np.ascontiguousarray(b[::-1].T)  # (dims, m), reversed: b[s - i - 1] = br[m - s + i]
    # diagonals s-2, s-1 and s, indexed by i (0: row 0); d[i] is the cell (i, s - i)
    d2 = np.full(n + 1, np.inf)
    d1 = np.full(n + 1, np.inf)
    d0 = np.full(n + 1, np.inf)
    cost = np.empty(n)
    d2[0] = 0.0  # s = 0: the cell (0, 0)
    for s in range(2, n + m + 1):
        lo = max(1, s - m)
        hi = min(n, s - 1)
        d0[0] = np.inf  # (0, s): row 0 past the origin
        if s <= n:
            d0[s] = np.inf  # (s, 0): column 0 past the origin
        w = hi - lo + 1
        c = cost[:w]
        c[:] = 0.0
        for k in range(dims):
            x = at[k, lo - 1 : hi]
            y = br[k, m - s + lo : m - s + hi + 1]
            for t in range(w):
                e = x[t] - y[t]
                c[t] += e * e
        diag, up, left, out = d2[lo - 1 : hi], d1[lo - 1 : hi], d1[lo : hi + 1], d0[lo : hi + 1]
        for t in range(w):
            best = diag[t]
            if up[t] < best:
                best = up[t]
            if left[t] < best:
                best = left[t]
            out[t] = math.sqrt(c[t]) + best
        d2, d1, d0 = d1, d0, d2
    return float(d1[n])


def dtw(a: ArrayLike, b: ArrayLike) -> float | NDArray[np.float64]:
    """DTW distance of ``(T, d)`` trajectories, or per node for ``(T, n, d)`` ones."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim == 1:
        a, b = a[:, None], b[:, None]
    if a.ndim == 2:
        if a.shape[1] != b.shape[1]:
            raise ValueError(f"dtw: dimension mismatch {a.shape} vs {b.shape}")
        return float(_dtw(np.ascontiguousarray(a), np.ascontiguousarray(b)))
    if a.ndim != 3 or a.shape[1:] != b.shape[1:]:
        raise ValueError(f"dtw: shapes {a.shape} and {b.shape} are not (T, n, d) alike")
    return np.array([_dtw(np.ascontiguousarray(a[:, i]), np.ascontiguousarray(b[:, i]))
                     for i in range(a.shape[1])])


def dtw_normalised(d: float | NDArray[np.float64], period: float,
                   duration: float) -> float | NDArray[np.float64]:
    """The paper's ``r = D T / s`` (see module docstring): mean deviation per sample, m."""
    if period <= 0 or duration <= 0:
        raise ValueError("dtw_normalised: period and duration must be > 0")
    return d * period / duration


@njit(cache=True)
def _dtw_rows(a: np.ndarray, b: np.ndarray, band: int, out: np.ndarray) -> None:
    for r in range(a.shape[0]):
        out[r] = _dtw(a[r], b[r]) if band < 0 else _dtw_banded(a[r], b[r], band)


def dtw_rows(a: ArrayLike, b: ArrayLike, band: int = -1) -> NDArray[np.float64]:
    """Row-wise DTW of ``(R, T, d)`` and ``(R, T', d)`` stacks: one compiled call, ``(R,)``.

    Row ``r`` equals ``dtw(a[r], b[r])`` exactly (the same recursion); used to score a
    whole GA population at once (sigma_des/tuning). ``band >= 0`` restricts the
    alignment to the Sakoe–Chiba band ``|i - j| <= band`` (still exact within it;
    ``band = 0`` is the plain sum of point distances); ``-1`` is unconstrained.
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if a.ndim != 3 or b.ndim != 3 or a.shape[0] != b.shape[0] or a.shape[2] != b.shape[2]:
        raise ValueError(f"dtw_rows: shapes {a.shape} and {b.shape} are not (R, T, d) alike")
    if band >= 0 and abs(a.shape[1] - b.shape[1]) > band:
        raise ValueError(f"dtw_rows: band {band} cannot reach the end of lengths "
                         f"{a.shape[1]} and {b.shape[1]}")
    out = np.empty(a.shape[0])
    _dtw_rows(a, b, int(band), out)
    return out
