"""Per-node local clocks: offset, drift and optional NTP correction.

See docs/concepts/model.md, "Components and message flow" (Clocks).

The DES clock is true time ``t``; only HLC timestamps and live-mode measurements
read a node's local clock. Node ``i`` has an initial offset ``offset_i ~ N(0,
offset_std)`` and a drift ``drift_i ~ N(0, drift_ppm_std)`` in ppm, both drawn
once by node id. Without NTP::

    local_i(t) = t + offset_i + drift_i · 1e-6 · t

With NTP every ``ntp_period`` seconds, at each sync instant ``j · period``
(``j >= 1``) the clock error is reset to a residual ``e_ij ~ N(0,
ntp_residual_std)`` drawn by ``(node, j)`` and then grows with the drift::

    local_i(t) = t + e_ij + drift_i · 1e-6 · (t − j · period),  j = max{j : j·period <= t}

Before the first sync (``t < period``) the un-synchronised formula applies.
Stream keys: offset ``(node, 0)``, drift ``(node, 1)``, residual ``(node, 2, j)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError

__all__ = ["ClockSpec", "NodeClocks"]


def _nonneg(name: str, value: object, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(name, f"must be a number >= 0 ({unit}), got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise ConfigError(name, f"must be >= 0 {unit} (finite), got {value!r}")
    return v


@dataclass(frozen=True)
class ClockSpec:
    """Statistics of the node clocks.

    Attributes:
        offset_std: standard deviation of the initial offset, seconds.
        drift_ppm_std: standard deviation of the drift rate, ppm.
        ntp_period: NTP synchronisation period, seconds (0 = no NTP).
        ntp_residual_std: standard deviation of the error left by a sync, seconds.
    """

    offset_std: float = 0.0
    drift_ppm_std: float = 0.0
    ntp_period: float = 0.0
    ntp_residual_std: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset_std", _nonneg("offset_std", self.offset_std, "s"))
        object.__setattr__(
            self, "drift_ppm_std", _nonneg("drift_ppm_std", self.drift_ppm_std, "ppm")
        )
        object.__setattr__(
            self, "ntp_period", _nonneg("ntp_period", self.ntp_period, "s; 0 = no NTP")
        )
        object.__setattr__(
            self, "ntp_residual_std", _nonneg("ntp_residual_std", self.ntp_residual_std, "s")
        )


#: the ids of the offset and drift draws, as a column
_OFFSET_DRIFT = np.array([[0], [1]], dtype=np.int64)


class NodeClocks:
    """The local clocks of ``n`` nodes.

    Args:
        spec: clock statistics.
        stream: stream of the clock draws.
        n: number of nodes (ids ``0 … n-1``).

    Attributes:
        offset: ``(n,)`` initial offsets, seconds.
        drift_ppm: ``(n,)`` drift rates, ppm.
    """

    def __init__(self, spec: ClockSpec, stream: Stream, n: int) -> None:
        if n < 0:
            raise ValueError(f"clocks: n must be >= 0, got {n}")
        self.spec = spec
        self.stream = stream
        self.n = int(n)
        # both draws in one call: row j is stream.normal(ids, j), the same bits
        z = stream.normal(np.arange(self.n, dtype=np.int64)[None, :], _OFFSET_DRIFT)
        self.offset: NDArray[np.float64] = spec.offset_std * z[0]
        self.drift_ppm: NDArray[np.float64] = spec.drift_ppm_std * z[1]

    def sync_index(self, t: ArrayLike) -> NDArray[np.int64]:
        """Index ``j`` of the last NTP sync at or before ``t`` (0 = none yet)."""
        ta = np.asarray(t, dtype=np.float64)
        period = self.spec.ntp_period
        if period == 0.0:
            return np.zeros(ta.shape, dtype=np.int64)
        j = np.floor(ta / period).astype(np.int64)
        # Make j exactly max{j : j * period <= t} despite rounding of t / period.
        j = np.where(j * period > ta, j - 1, j)
        j = np.where((j + 1) * period <= ta, j + 1, j)
        return np.maximum(j, 0)

    def local_time(self, node: ArrayLike, t: ArrayLike) -> float | NDArray[np.float64]:
        """Reading of node ``node``'s clock at true time ``t``.

        Args:
            node: node id(s) in ``0 … n-1``.
            t: true time(s) in seconds; broadcast with ``node``.

        Returns:
            A float if both arguments are scalars, else an array of their
            broadcast shape.
        """
        scalar = np.ndim(node) == 0 and np.ndim(t) == 0
        nd = np.atleast_1d(np.asarray(node, dtype=np.int64))
        ta = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if nd.size and (nd.min() < 0 or nd.max() >= self.n):
            raise IndexError(f"clocks: node ids must be in [0, {self.n}), got {node!r}")
        nd, ta = np.broadcast_arrays(nd, ta)
        drift = self.drift_ppm[nd] * 1e-6
        if self.spec.ntp_period == 0.0:
            out = ta + self.offset[nd] + drift * ta
        else:
            j = self.sync_index(ta)
            synced = j >= 1
            resid = self.spec.ntp_residual_std * self.stream.normal(nd, 2, j)
            since = ta - j * self.spec.ntp_period
            out = np.where(
                synced,
                ta + resid + drift * since,
                ta + self.offset[nd] + drift * ta,
            )
        return float(out[0]) if scalar else out

    def error(self, node: ArrayLike, t: ArrayLike) -> float | NDArray[np.float64]:
        """Clock error ``local_time(node, t) − t`` in seconds."""
        local = self.local_time(node, t)
        if isinstance(local, float):
            return local - float(t)  # type: ignore[arg-type]
        return local - np.asarray(t, dtype=np.float64)
