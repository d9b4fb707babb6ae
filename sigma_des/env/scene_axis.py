"""The tasks' array helpers over a leading scene axis (``SwarmVec``'s batched control plane).

Each is the one-scene helper of :mod:`sigma_des.env.tasks` (or
:func:`~sigma_des.agents.formation.formation_slots`) with the same operations on
``(S, n, ...)`` arrays, so every element is the same bits (``tests/env/test_batched.py``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

__all__ = ["formation_targets_many", "nearest_many", "slot_offsets", "velocity_many"]

Array = NDArray[np.float64]


def nearest_many(pos: Array) -> tuple[Array, Array, NDArray[np.intp]]:
    """``tasks.base.nearest`` of every scene of ``(S, n, k)`` positions (the same operations)."""
    diff = pos[:, None, :, :] - pos[:, :, None, :]
    dist = np.sqrt((diff**2).sum(-1))
    n = pos.shape[1]
    dist[:, np.arange(n), np.arange(n)] = np.inf
    j = np.argmin(dist, axis=2)
    s = np.arange(pos.shape[0])[:, None]
    i = np.arange(n)[None, :]
    return diff[s, i, j], dist[s, i, j], j


def velocity_many(obs: Array) -> Array:
    """``tasks.base.velocity`` of ``(S, n, 12)`` states: ``(S, n, 2)``."""
    return np.stack([obs[..., 0] * np.cos(obs[..., 5]), obs[..., 0] * np.sin(obs[..., 5])],
                    axis=-1)


@lru_cache(maxsize=64)
def slot_offsets(n: int, d: float, theta: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The V-slot offsets ``(dx, dy)`` of ranks ``0..n-1`` behind the leader (the
    arithmetic of :func:`~sigma_des.agents.formation.formation_slots`), read-only."""
    rank = np.arange(n)  # followers 1, 2, ... in node order (leader 0)
    row = np.ceil(rank / 2.0)
    side = np.where(rank % 2 == 1, 1.0, -1.0)
    dx = -row * d * math.cos(theta)
    dy = side * row * d * math.sin(theta)
    dx.setflags(write=False)
    dy.setflags(write=False)
    return dx, dy


def formation_targets_many(obs: Array, d: float, theta: float) -> Array:
    """``(S, n, 3)`` V-slots behind leader 0 and its altitude, per scene (``formation_slots``'
    arithmetic, the cos/sin of each leader heading with ``math`` as there)."""
    S, n = obs.shape[:2]
    dx, dy = slot_offsets(n, d, theta)
    psi = obs[:, 0, 5]
    c = np.array([math.cos(p) for p in psi])[:, None]
    sn = np.array([math.sin(p) for p in psi])[:, None]
    out = np.empty((S, n, 3))
    out[..., 0] = obs[:, 0, 9][:, None] + c * dx - sn * dy
    out[..., 1] = obs[:, 0, 10][:, None] + sn * dx + c * dy
    out[..., 2] = obs[:, 0, 11][:, None]
    return out
