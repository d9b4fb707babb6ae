"""Metrics derived from one run's render-tick time series (the studies' extra columns).

:func:`derived_metrics` for every study; :func:`window_stats` (before / during / after a
fault window) and :func:`seed_means` for the fault study.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sigma_des.plots import rate_series

__all__ = ["DERIVED_UNITS", "derived_metrics", "seed_means", "window_stats"]

#: Units of the metrics derived here from the time series (see :func:`derived_metrics`).
DERIVED_UNITS: dict[str, str] = {
    "displacement_mean_ms": "ms",
    "displacement_max_ms": "ms",
    "f_trig_window_min_hz": "Hz",
    "f_trig_settled_hz": "Hz",
    "aligned_rate_hz": "Hz",
    "aligned_rate_std_hz": "Hz",
    "aoi_tick_mean_std_ms": "ms",
}


def derived_metrics(ts: dict[str, Any], m: dict[str, float]) -> dict[str, float]:
    """Metrics computed from one run's render-tick time series.

    * ``displacement_mean_ms`` / ``displacement_max_ms`` — the frame spread of the
      shown snapshot expressed as time (spread × the frame period in force at that
      tick): how far apart in simulated time the shown nodes are (the paper's
      "flicker" displacement).
    * ``f_trig_window_min_hz`` — lowest trigger rate in force during the measured
      window (taken from the time series; the engine's ``f_trig_min_hz`` ignores a
      rate set before the warm-up ended).
    * ``f_trig_settled_hz`` — median trigger rate over the last quarter of the run.
    * ``aligned_rate_hz`` / ``aligned_rate_std_hz`` — mean and standard deviation of
      the aligned frame's advance rate in 0.25 s windows (frames shown per second).
    * ``aoi_tick_mean_std_ms`` — standard deviation over render ticks of the
      per-tick mean AoI (how much the swarm's AoI wobbles over time).

    Args:
        ts: the run's per-render-tick arrays.
        m: the run's engine metrics (not read; kept for the studies' call sites).
    """
    t = np.asarray(ts["t"], dtype=float)
    out: dict[str, float] = {}
    if t.size == 0:
        return {k: math.nan for k in DERIVED_UNITS}
    f = np.asarray(ts["f_trig"], dtype=float)
    sp = np.asarray(ts["spread"], dtype=float)
    disp = sp / f * 1000.0
    out["displacement_mean_ms"] = float(disp.mean())
    out["displacement_max_ms"] = float(disp.max())
    out["f_trig_window_min_hz"] = float(f.min())
    out["f_trig_settled_hz"] = float(np.median(f[int(0.75 * f.size) :]))
    _, rate = rate_series(t, np.asarray(ts["aligned_frame"], dtype=float))
    out["aligned_rate_hz"] = float(rate.mean()) if rate.size else math.nan
    out["aligned_rate_std_hz"] = float(rate.std()) if rate.size else math.nan
    aoi = np.asarray(ts["aoi_mean"], dtype=float) * 1000.0
    aoi = aoi[~np.isnan(aoi)]
    out["aoi_tick_mean_std_ms"] = float(aoi.std()) if aoi.size else math.nan
    return out


def window_stats(ts: dict[str, Any], a: float, b: float) -> dict[str, float]:
    """AoI and aligned-frame rate before ``a``, in ``[a, b)`` and after ``b``.

    Also ``recovery_s``: time after ``b`` until the per-tick mean AoI is back within
    1.5× its pre-fault median (NaN if it never is, or the fault lasts to the end).
    """
    t = np.asarray(ts["t"], dtype=float)
    aoi = np.asarray(ts["aoi_mean"], dtype=float) * 1000.0
    fr = np.asarray(ts["aligned_frame"], dtype=float)
    out: dict[str, float] = {}
    for name, sel in (
        ("before", t < a),
        ("during", (t >= a) & (t < b)),
        ("after", t >= b + 0.5),
    ):
        tt, ff = t[sel], fr[sel]
        x = aoi[sel]
        x = x[~np.isnan(x)]
        out[f"aoi_{name}_ms"] = float(x.mean()) if x.size else math.nan
        out[f"aoi_max_{name}_ms"] = float(x.max()) if x.size else math.nan
        rate = (ff[-1] - ff[0]) / (tt[-1] - tt[0]) if tt.size > 1 else math.nan
        out[f"aligned_rate_{name}_hz"] = float(rate)
    pre = aoi[(t < a) & ~np.isnan(aoi)]
    out["recovery_s"] = math.nan
    if pre.size and b < t[-1]:
        ok = (t >= b) & (aoi <= 1.5 * np.median(pre))
        if ok.any():
            out["recovery_s"] = float(t[np.argmax(ok)] - b)
    return out


def seed_means(per_seed: list[dict[str, float]]) -> dict[str, float]:
    """Per key: the mean over seeds of the finite-or-infinite values (NaN: none left)."""
    out: dict[str, float] = {}
    for k in per_seed[0]:
        x = np.array([d[k] for d in per_seed], dtype=float)
        ok = x[~np.isnan(x)]
        out[k] = float(ok.mean()) if ok.size else math.nan
    return out
