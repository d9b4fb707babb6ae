"""Counter-based random numbers inside numba kernels, bit-compatible with sigma_des.core.rng.

The kernels cannot call :class:`sigma_des.core.rng.Stream` (it is numpy code), so this
module re-implements its SplitMix64 mixing for scalars: ``uniform3(key, a, b, c)``
equals ``Stream.uniform(a, b, c)`` bit for bit when ``key`` is that stream's
``key`` (tested). Normals map that uniform through Acklam's inverse normal CDF,
so they equal ``Stream.normal`` (scipy's exact ``ndtri``) to ~1e-9 relative error
and are a pure function of (stream, node, frame,
channel) like every other draw in the project.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import cast

import numpy as np
from numba import njit

from sigma_des.core.rng import GOLDEN, S11, TWO53, finalise

_ONE = np.uint64(1)
_TWO_PI = 2.0 * math.pi
#: rng's own finaliser, compiled for one hash (the same bits as its array form)
_fin = cast(Callable[[np.uint64], np.uint64], njit(cache=True, inline="always")(finalise))


@njit(cache=True, inline="always")
def absorb(h: np.uint64, i: np.int64) -> np.uint64:
    """Mix one integer id into a running hash (one step of ``rng.mix``)."""
    return _fin(h ^ ((np.uint64(i) + _ONE) * GOLDEN))


@njit(cache=True, inline="always")
def to_uniform(h: np.uint64) -> float:
    """Final mix of a running hash and map to (0, 1), as ``Stream.uniform``."""
    z = _fin(h)
    return (float(z >> S11) + 0.5) * TWO53


@njit(cache=True)
def mix_column(h: np.uint64, ids: np.ndarray, tail: np.ndarray) -> np.ndarray:
    """``rng.mix(key, *prefix, ids, *tail)`` for a 1-d ``ids`` and scalar ``tail``, ``h``
    the hash of the key and the scalar prefix: the same SplitMix64 steps per element."""
    out = np.empty(ids.shape[0], dtype=np.uint64)
    for j in range(ids.shape[0]):
        z = absorb(h, ids[j])
        for t in tail:
            z = absorb(z, t)
        out[j] = _fin(z)
    return out


@njit(cache=True)
def mix_outer(h: np.uint64, a: np.ndarray, mid: np.ndarray, b: np.ndarray, tail: np.ndarray,
              a_is_row: bool) -> np.ndarray:
    """``rng.mix(key, *prefix, A, *mid, B, *tail)`` for a row ``(1, n)`` and a column
    ``(m, 1)`` (``A`` the row if ``a_is_row``, else the column; ``a``, ``b`` their
    values), scalar ``mid`` and ``tail``, ``h`` the hash of the key and the prefix:
    ``(m, n)``, the same SplitMix64 steps per element."""
    n = a.shape[0] if a_is_row else b.shape[0]
    m = b.shape[0] if a_is_row else a.shape[0]
    out = np.empty((m, n), dtype=np.uint64)
    for r in range(m):
        for c in range(n):
            z = absorb(h, a[c] if a_is_row else a[r])
            for t in mid:
                z = absorb(z, t)
            z = absorb(z, b[r] if a_is_row else b[c])
            for t in tail:
                z = absorb(z, t)
            out[r, c] = _fin(z)
    return out


@njit(cache=True)
def uniform_rows(key: np.uint64, kind: np.int64, subjects: np.ndarray, index: np.ndarray,
                 attempt: np.ndarray) -> np.ndarray:
    """``Stream.uniform(kind, subjects[None, :], index[:, None], attempt[:, None])``: row
    ``r`` keyed ``(kind, subject, index[r], attempt[r])``, an ``index`` or ``attempt`` of
    one element held for every row (a draw block's keys, uniforms of the same bits)."""
    m = max(index.shape[0], attempt.shape[0])
    n = subjects.shape[0]
    one_i = index.shape[0] == 1
    one_a = attempt.shape[0] == 1
    out = np.empty((m, n))
    h0 = absorb(key, kind)
    for c in range(n):
        h1 = absorb(h0, subjects[c])
        for r in range(m):
            h2 = absorb(h1, index[0] if one_i else index[r])
            out[r, c] = to_uniform(absorb(h2, attempt[0] if one_a else attempt[r]))
    return out


@njit(cache=True)
def uniform_grid(key: np.uint64, kind: np.int64, subjects: np.ndarray, index: np.ndarray,
                 attempt: np.ndarray) -> np.ndarray:
    """``Stream.uniform(kind, subjects, index[r], attempt[j])`` at ``[r, j]``: a grid of
    keys, ``(len(index), len(attempt), len(subjects))``, each row the bits of
    :func:`uniform_rows` of its key."""
    n = subjects.shape[0]
    out = np.empty((index.shape[0], attempt.shape[0], n))
    h0 = absorb(key, kind)
    for c in range(n):
        h1 = absorb(h0, subjects[c])
        for r in range(index.shape[0]):
            h2 = absorb(h1, index[r])
            for j in range(attempt.shape[0]):
                out[r, j, c] = to_uniform(absorb(h2, attempt[j]))
    return out


@njit(cache=True)
def uniform_tables(keys: np.ndarray, kinds: np.ndarray, widths: np.ndarray, first: np.int64,
                   rows: np.int64) -> np.ndarray:
    """The uniforms of several streams' draw blocks in one call: table ``t`` (stream key
    ``keys[t]``, kind ``kinds[t]``, subjects ``0 .. widths[t]-1``) holds ``rows`` indices
    from ``first`` on, attempt 0, as :func:`uniform_rows` draws them (the same bits),
    row-major at offset ``rows * sum(widths[:t])`` of the flat result."""
    out = np.empty(rows * widths.sum())
    off = 0
    for t in range(keys.shape[0]):
        w = widths[t]
        h0 = absorb(keys[t], kinds[t])
        for c in range(w):
            h1 = absorb(h0, np.int64(c))
            for r in range(rows):
                h2 = absorb(h1, first + r)
                out[off + r * w + c] = to_uniform(absorb(h2, np.int64(0)))
        off += rows * w
    return out


@njit(cache=True)
def uniform3(key: np.uint64, a: np.int64, b: np.int64, c: np.int64) -> float:
    """``Stream.uniform(a, b, c)`` for the stream whose key is ``key``."""
    return to_uniform(absorb(absorb(absorb(key, a), b), c))


# Acklam's rational approximation of the normal quantile (relative error < 1.15e-9).
_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)
_P_LOW = 0.02425


@njit(cache=True, inline="always")
def ndtri_fast(p: float) -> float:
    """Standard normal quantile of ``p`` in (0, 1) (Acklam 2003, rel. error < 1.15e-9).

    The central 95 % needs no logarithm, which makes it several times cheaper
    than Box–Muller per draw.
    """
    if p < _P_LOW or p > 1.0 - _P_LOW:
        q = math.sqrt(-2.0 * math.log(p if p < 0.5 else 1.0 - p))
        x = ((((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5])
             / ((((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0))
        return x if p < 0.5 else -x
    q = p - 0.5
    r = q * q
    return ((((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q
            / (((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0))


@njit(cache=True, inline="always")
def normal_at(h2: np.uint64, j: np.int64) -> float:
    """Standard normal with third id ``j`` from the partial hash ``h2 = mix(key, a, b)``.

    Equals ``Stream.normal(a, b, j)`` to ~1e-9 relative error (same uniform,
    approximate quantile function).
    """
    return ndtri_fast(to_uniform(absorb(h2, j)))


@njit(cache=True)
def normals(key: np.uint64, a: np.int64, b: np.int64, k: int) -> np.ndarray:
    """``k`` standard normals keyed by (a, b, 0..k-1) — for tests and Python callers."""
    h2 = absorb(absorb(key, a), b)
    out = np.empty(k)
    for j in range(k):
        out[j] = normal_at(h2, j)  # type: ignore[arg-type]
    return out
