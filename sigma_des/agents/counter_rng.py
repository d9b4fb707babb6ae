"""Counter-based random numbers inside numba kernels, bit-compatible with sigma_des.rng.

The kernels cannot call :class:`sigma_des.rng.Stream` (it is numpy code), so this
module re-implements its SplitMix64 mixing for scalars: ``uniform3(key, a, b, c)``
equals ``Stream.uniform(a, b, c)`` bit for bit when ``key`` is that stream's
``key`` (tested). Normals use Box–Muller on two such uniforms with sub-indices
``2j`` and ``2j + 1``; they are therefore a pure function of (stream, node, frame,
channel) like every other draw in the project, but not equal to ``Stream.normal``
(which uses an inverse CDF that numba cannot call).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_ONE = np.uint64(1)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO53 = 1.0 / 9007199254740992.0
_TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def _fin(z: np.uint64) -> np.uint64:
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@njit(cache=True, inline="always")
def absorb(h: np.uint64, i: np.int64) -> np.uint64:
    """Mix one integer id into a running hash (one step of ``rng.mix``)."""
    return _fin(h ^ ((np.uint64(i) + _ONE) * _GOLDEN))


@njit(cache=True, inline="always")
def to_uniform(h: np.uint64) -> float:
    """Final mix of a running hash and map to (0, 1), as ``Stream.uniform``."""
    z = _fin(h)
    return (float(z >> _S11) + 0.5) * _TWO53


@njit(cache=True)
def uniform3(key: np.uint64, a: np.int64, b: np.int64, c: np.int64) -> float:
    """``Stream.uniform(a, b, c)`` for the stream whose key is ``key``."""
    return to_uniform(absorb(absorb(absorb(key, a), b), c))


@njit(cache=True, inline="always")
def normal_pair(h2: np.uint64, j: np.int64) -> tuple[float, float]:
    """Two independent standard normals from the partial hash ``h2`` of (node, frame).

    Uses the uniforms with third id ``2j`` and ``2j + 1`` (Box–Muller).
    """
    u1 = to_uniform(absorb(h2, 2 * j))
    u2 = to_uniform(absorb(h2, 2 * j + 1))
    rad = math.sqrt(-2.0 * math.log(u1))
    ang = _TWO_PI * u2
    return rad * math.cos(ang), rad * math.sin(ang)


@njit(cache=True)
def normals(key: np.uint64, a: np.int64, b: np.int64, k: int) -> np.ndarray:
    """``k`` standard normals keyed by (a, b, channel) — for tests and Python callers."""
    h2 = absorb(absorb(key, a), b)
    out = np.empty(k)
    for j in range((k + 1) // 2):
        z0, z1 = normal_pair(h2, j)
        out[2 * j] = z0
        if 2 * j + 1 < k:
            out[2 * j + 1] = z1
    return out
