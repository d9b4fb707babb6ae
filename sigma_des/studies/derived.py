"""Metrics derived from one run's render-tick time series (the studies' extra columns)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sigma_des.plots import rate_series

__all__ = ["DERIVED_UNITS", "derived_metrics"]

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
