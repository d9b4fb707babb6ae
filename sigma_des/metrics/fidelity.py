"""Swarm fidelity (docs/concepts/metrics.md): how the swarm flew compared with an ideal run.

The engine logs every node's true position at ``log_rate`` Hz of *physics* time
(interpolating between frames, as :func:`sigma_des.agents.ideal.fly` does for the
ideal run: zero latency, perfect alignment). Two figures compare a run with the
ideal one:

* formation error at time t: the mean over nodes of the distance between a node's
  offset from the swarm centroid and its offset in the ideal run (shape error,
  independent of where the whole swarm is); reported as mean and max over time;
* DTW distance of each node's trajectory to its ideal trajectory, normalised as
  the paper does (``r = D·T/s``, see :mod:`sigma_des.metrics.dtw`), averaged over
  (at most ``dtw_nodes`` evenly spread) nodes.

Both are taken over the physics time that both the run and the ideal run cover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.validate import require, require_positive
from sigma_des.metrics.samples import Samples

__all__ = [
    "FidelitySpec", "Rows", "TrajectoryLog", "add_fidelity", "fidelity", "formation_error",
]

#: Samples per block of :func:`formation_error` (bounds its temporaries to a few MB).
BLOCK = 256


@dataclass(frozen=True)
class FidelitySpec:
    """Swarm fidelity against an ideal run (zero latency, perfect alignment).

    Attributes:
        enabled: fly the ideal run and compute formation error and DTW.
        log_rate: trajectory sampling rate (Hz of physics time; the paper: 30 Hz).
        dtw_nodes: DTW is averaged over at most this many evenly spread nodes.
    """

    enabled: bool = True
    log_rate: float = 30.0
    dtw_nodes: int = 50

    def __post_init__(self) -> None:
        require_positive(self, "log_rate")
        require(self.dtw_nodes >= 1, "dtw_nodes", f"must be >= 1, got {self.dtw_nodes}")


class Rows(Protocol):
    """A ``(T, n, 3)`` position log that hands out blocks of samples: a numpy array, or
    a reader over a file (:meth:`TrajectoryLog.rows`, the ideal-run cache's entries),
    so that :func:`fidelity` never needs the whole log in memory."""

    @property
    def shape(self) -> tuple[int, ...]:
        """``(T, n, 3)``."""
        ...

    def __len__(self) -> int: ...

    def __getitem__(self, rows: slice, /) -> NDArray[np.float64]:
        """Samples ``rows`` (a slice without step) as an array."""
        ...


class LogRows:
    """:class:`Rows` over a :class:`TrajectoryLog`'s store, read a block at a time."""

    def __init__(self, pos: Samples, shape: tuple[int, ...]) -> None:
        self._pos = pos
        self._per = int(np.prod(shape))
        self.shape: tuple[int, ...] = (len(pos) // self._per, *shape)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, rows: slice, /) -> NDArray[np.float64]:
        start, stop, _ = rows.indices(len(self))
        k = max(0, stop - start)
        return self._pos.read(start * self._per, k * self._per).reshape(k, *self.shape[1:])


class TrajectoryLog:
    """Positions at ``j / log_rate`` s of physics time, interpolated between frames.

    The positions are kept contiguously (:class:`~sigma_des.metrics.samples.Samples`,
    8 bytes a value: ``24 n`` bytes a sample) and :meth:`arrays` returns them without
    the copy a stack of per-sample arrays would make.

    Args:
        log_rate: samples per second.
        initial: ``(n, 3)`` positions at physics time 0.
    """

    def __init__(self, log_rate: float, initial: NDArray[np.float64]) -> None:
        self.rate = log_rate
        self.times: list[float] = [0.0]
        self._shape = initial.shape
        self.pos = Samples()
        self.pos.extend(initial)
        self._prev_t = 0.0
        self._prev = initial.copy()
        self._j = 1

    def add(self, t: float, pos: NDArray[np.float64]) -> None:
        """The swarm was at ``pos`` at physics time ``t`` (frames in order)."""
        span = t - self._prev_t
        while self._j / self.rate <= t + 1e-12:
            tj = self._j / self.rate
            w = (tj - self._prev_t) / span if span > 0 else 1.0
            self.times.append(tj)
            self.pos.extend((1.0 - w) * self._prev + w * pos)
            self._j += 1
        self._prev_t = t
        self._prev = pos.copy()

    def arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(times (T,), positions (T, n, 3))``."""
        return np.asarray(self.times), self.pos.values().reshape(-1, *self._shape)

    def rows(self) -> LogRows:
        """The positions as :class:`Rows`: the same values as :meth:`arrays`, read a
        block at a time from the store (which spills to disk on long runs)."""
        return LogRows(self.pos, self._shape)


def fidelity(
    pos: Rows, ideal: Rows, period: float, dtw_nodes: int
) -> tuple[dict[str, float], NDArray[np.float64]]:
    """Formation error and normalised DTW of ``pos`` against ``ideal`` (both ``(T, n, 3)``).

    Both are read :data:`BLOCK` samples at a time (arrays, or readers over files): what
    is kept whole is the formation error per sample and the DTW nodes' positions
    (``dtw_nodes`` of ``n``), so a long run's logs need not fit in memory.

    Returns:
        (metrics, formation error per common sample).
    """
    t = min(len(pos), len(ideal))
    if t < 2:
        return {
            "formation_err_mean": math.nan,
            "formation_err_max": math.nan,
            "dtw_r": math.nan,
        }, np.empty(0)
    from sigma_des.metrics.dtw import dtw, dtw_normalised  # numba: compiled on first use

    n = pos.shape[1]
    pick = np.unique(np.linspace(0, n - 1, min(n, dtw_nodes)).round().astype(int))
    err = np.empty(t)
    a = np.empty((t, pick.size, *pos.shape[2:]))
    b = np.empty((t, pick.size, *pos.shape[2:]))
    for s in range(0, t, BLOCK):  # formation_error's own blocks: the same bits
        e = min(s + BLOCK, t)
        x, y = pos[s:e], ideal[s:e]
        err[s:e] = formation_error(x, y)
        a[s:e], b[s:e] = x[:, pick], y[:, pick]
    # over the physics time both runs cover (a run whose triggers slowed down, like a
    # stalled Lock-Step, flies less; its trigger rate reports that, not its DTW)
    d = np.asarray(dtw(a, b))
    r = np.asarray(dtw_normalised(d, period, (t - 1) * period))
    return {
        "formation_err_mean": float(err.mean()),
        "formation_err_max": float(err.max()),
        "dtw_r": float(r.mean()),
    }, err


def add_fidelity(
    out: dict[str, Any],
    times: NDArray[np.float64],
    pos: Rows,
    ideal: Rows,
    spec: FidelitySpec,
) -> None:
    """Add the fidelity of a run's trajectory to its result dict (``metrics``, ``fidelity``).

    Args:
        out: the run's result dict (:meth:`~sigma_des.metrics.collector.Collector.finish`).
        times: the trajectory's sample times (s of physics time).
        pos: its positions ``(T, n, 3)``, sampled at ``spec.log_rate`` Hz (an array,
            or :meth:`TrajectoryLog.rows`: read a block at a time).
        ideal: the ideal run's positions at the same rate (an array or :class:`Rows`).
        spec: the fidelity settings.
    """
    fid, err = fidelity(pos, ideal, 1.0 / spec.log_rate, spec.dtw_nodes)
    out["metrics"].update(fid)
    out["fidelity"] = {"t": times[: len(err)], "formation_err": err}


def formation_error(
    a: NDArray[np.float64], b: NDArray[np.float64], block: int = BLOCK
) -> NDArray[np.float64]:
    """Per sample, the mean over nodes of the distance between the two shapes.

    ``a`` and ``b`` are ``(T, n, 3)``; a node's shape vector is its offset from the
    swarm centroid of its sample. Every sample's figure depends on that sample only,
    so the samples are taken ``block`` at a time: the temporaries (three ``(block, n,
    3)`` arrays) stay a few MB instead of three copies of the whole log, with the same
    numpy reductions per sample, hence the same bits.
    """
    t = len(a)
    err = np.empty(t)
    for s in range(0, t, block):
        x, y = a[s : s + block], b[s : s + block]
        shape_a = x - x.mean(axis=1, keepdims=True)
        shape_b = y - y.mean(axis=1, keepdims=True)
        err[s : s + block] = np.linalg.norm(shape_a - shape_b, axis=2).mean(axis=1)
    return err
