"""The GA's fitness, eq. (13): ``r = D T / s`` with exact DTW, and the fit metrics R² / RMS.

``D`` is the exact dynamic-time-warping distance (metrics/dtw.py: Euclidean
local cost, steps (1,0), (0,1), (1,1); eq. (14) with the cumulative ``D^e`` on
the right-hand side) between the logged and the simulated trajectory, summed
over the replay windows (within a Sakoe–Chiba band, ``tune.band``: see
spec.py for why); a trajectory point is the vector of the
``tune.channels`` state columns in SI units (rad, rad/s, m). ``T`` is the
replayed flight time and ``s`` the logged flight distance (path length, floored
at 1 m so a hover log does not divide by ~0). Lower is better.

Exact, not FastDTW: our windows are ~50 samples, where exact DTW costs
microseconds, and Wu & Keogh (2020, the paper's ref. [33]) show FastDTW is
both approximate and slower than exact (banded) DTW at such sizes; an
approximate distance would also make the fitness depend on FastDTW's radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sigma_des.metrics.dtw import dtw_rows
from sigma_des.tuning.flightlog import STATE_COLUMNS
from sigma_des.tuning.replay import Windows

__all__ = ["FitnessSpec", "fitness", "fit_metrics", "MIN_DISTANCE"]

MIN_DISTANCE = 1.0
_WRAPPED = ("phi", "psi")


@dataclass(frozen=True)
class FitnessSpec:
    """What the fitness compares.

    Attributes:
        channels: state columns of a DTW point.
        duration: replayed flight time T (s).
        distance: logged flight distance s (m), already floored.
        band: Sakoe–Chiba band (samples; -1 = unconstrained DTW).
    """

    channels: tuple[str, ...]
    duration: float
    distance: float
    band: int = -1

    @classmethod
    def of(cls, win: Windows, channels: tuple[str, ...], band: int = -1) -> FitnessSpec:
        """T and s of the replayed windows."""
        d = np.diff(win.obs[:, :, 9:12], axis=1)
        s = float(np.sqrt((d * d).sum(axis=2)).sum())
        return cls(channels, win.count * win.steps * win.dt, max(s, MIN_DISTANCE), band)


def _aligned(log: NDArray[np.float64], sim: NDArray[np.float64],
             channels: tuple[str, ...]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Selected channels of log and sim; wrapped angles of sim taken nearest the log."""
    idx = [STATE_COLUMNS.index(c) for c in channels]
    a = np.broadcast_to(log[..., idx], sim[..., idx].shape)
    b = sim[..., idx].copy()
    for j, c in enumerate(channels):
        if c in _WRAPPED:
            d = b[..., j] - a[..., j]
            b[..., j] = a[..., j] + (d + np.pi) % (2 * np.pi) - np.pi
    return np.ascontiguousarray(a), b


def fitness(win: Windows, sim: NDArray[np.float64], spec: FitnessSpec) -> NDArray[np.float64]:
    """``r = D T / s`` per candidate; ``inf`` where a replay left the finite numbers.

    Args:
        win: the logged windows (``obs`` is ``(S, M + 1, 12)``).
        sim: ``(P, S, M + 1, 12)`` replayed observations.
        spec: channels, T and s.
    """
    p_n, s_n = sim.shape[0], sim.shape[1]
    a, b = _aligned(win.obs[None], sim, spec.channels)
    ok = np.isfinite(b.reshape(p_n, -1)).all(axis=1)
    b = np.where(np.isfinite(b), b, 0.0)
    m, d = a.shape[2], a.shape[3]
    dist = dtw_rows(a.reshape(p_n * s_n, m, d), b.reshape(p_n * s_n, m, d), spec.band)
    total = dist.reshape(p_n, s_n).sum(axis=1)
    r = total * spec.duration / spec.distance
    return np.where(ok & np.isfinite(r), r, np.inf)


def fit_metrics(win: Windows, sim: NDArray[np.float64],
                channels: tuple[str, ...]) -> dict[str, dict[str, float]]:
    """RMS error and R² per channel, sample by sample (window starts excluded).

    ``R² = 1 - sum (y - y_sim)^2 / sum (y - mean y)^2`` over all replayed samples
    of the channel, the "degree of fit" of response-function fitting.

    Args:
        win: logged windows.
        sim: ``(S, M + 1, 12)`` one candidate's replay.
        channels: columns to score.
    """
    out: dict[str, dict[str, float]] = {}
    a, b = _aligned(win.obs, sim, channels)
    for j, c in enumerate(channels):
        y = a[:, 1:, j].ravel()
        e = y - b[:, 1:, j].ravel()
        ss_tot = float(((y - y.mean()) ** 2).sum())
        ss_res = float((e * e).sum())
        rms = float(np.sqrt(np.mean(e * e)))
        r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")
        out[c] = {"rms": rms if np.isfinite(rms) else float("inf"),
                  "r2": r2 if np.isfinite(r2) else float("-inf")}
    return out
