"""The node step time of a live run: ``compute.step_time`` and ``compute.host_share``.

From the hosts' per-node publish rows (``state_pub`` in ``messages.csv.gz``):

* each job's **service** is its publish minus the time it got one of the host's
  ``cores_per_host`` cores (replayed FCFS, :func:`~sigma_des.calibrate.dequeue.job_services`;
  the DES adds the wait for a core itself); ``compute.step_time`` is a lognormal with
  the services' mean and standard deviation;
* ``compute.host_share`` is the share of the services' variance common to one host and
  frame: the intraclass correlation (one-way random-effects ANOVA, :func:`icc`) of
  their normal scores (``Φ⁻¹`` of the mid-ranks), grouped by (method, host, frame).
  That is the copula's ρ (:func:`sigma_des.events.jobs.step_draws` correlates the normal
  scores of two nodes of one host and frame by ρ), whatever the marginal. It is clamped
  to ``[0, HOST_SHARE_CAP]``: a negative estimate (nodes of one host less alike than
  any two) has no copula, and a share near 1 would make the node component vanish on
  the evidence of one run.

Hosts whose states arrived but who left no per-node rows are refused (``strict``) or
warned about; never silently replaced by the base scenario's step time.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from sigma_des.calibrate.dequeue import job_services
from sigma_des.config import Scenario
from sigma_des.errors import ConfigError
from sigma_des.events.spec import ComputeSpec
from sigma_des.net.latency import Dist

__all__ = ["HOST_SHARE_CAP", "MIN_SAMPLES", "fit_compute", "host_share", "icc",
           "publish_costs"]

#: Fewer samples than this in a fit is warned about (the fit uses them all the same).
MIN_SAMPLES = 20
#: Largest ``compute.host_share`` a calibration writes.
HOST_SHARE_CAP = 0.95


def icc(values: ArrayLike, groups: ArrayLike) -> float:
    """Intraclass correlation ICC(1) of ``values`` grouped by ``groups`` (one-way
    random-effects ANOVA, unequal group sizes).

    ``(MSB - MSW) / (MSB + (n0 - 1) MSW)`` with ``MSB = SSB / (g - 1)``,
    ``MSW = SSW / (N - g)`` and ``n0 = (N - Σ n_i² / N) / (g - 1)``: the share of the
    variance that lies between groups, corrected for the within-group variance the
    group means still carry.

    Args:
        values: the observations.
        groups: a group label per observation.

    Returns:
        The estimate (may be negative); NaN with fewer than two groups, no group of two,
        or no variance at all.
    """
    x = np.asarray(values, dtype=np.float64)
    codes = pd.factorize(pd.Series(np.asarray(groups)))[0] if x.size else np.zeros(0, int)
    n_i = np.bincount(codes).astype(np.float64) if x.size else np.zeros(0)
    g, n = n_i.size, float(x.size)
    if g < 2 or n - g < 1:
        return float("nan")
    means = np.bincount(codes, weights=x) / n_i
    ssb = float(np.sum(n_i * (means - x.mean()) ** 2))
    ssw = float(np.sum((x - means[codes]) ** 2))
    msb, msw = ssb / (g - 1), ssw / (n - g)
    n0 = (n - float(np.sum(n_i**2)) / n) / (g - 1)
    den = msb + (n0 - 1.0) * msw
    return (msb - msw) / den if den > 0 else float("nan")


def host_share(pub: pd.DataFrame) -> float:
    """ICC of the normal scores of ``pub["cost"]`` grouped by (method, host, frame).

    The scores are ``Φ⁻¹(rank / (n + 1))`` of the services rounded to 1 ns (mid-ranks
    for ties).

    Args:
        pub: per-node rows with ``host``, ``frame``, ``cost`` (and ``method``, if several).

    Returns:
        The estimate of the copula's ρ (unclamped; NaN where :func:`icc` is).
    """
    from scipy.special import ndtri
    from scipy.stats import rankdata

    # to the ns: services are differences of timestamps, and equal timings must tie
    c = np.round(pub["cost"].to_numpy(dtype=np.float64), 9)
    if c.size < 2:
        return float("nan")
    z = ndtri(rankdata(c) / (c.size + 1.0))
    method = pub["method"].astype(str) if "method" in pub else ""
    key = method + "/" + pub["host"].astype(str) + "/" + pub["frame"].astype(str)
    return icc(z, key.to_numpy())


def publish_costs(msgs: pd.DataFrame, base: Scenario) -> pd.DataFrame:
    """The window's ``state_pub`` rows with ``raw`` = publish minus trigger receipt and
    ``cost`` = the job's service without its wait for one of the host's
    ``cores_per_host`` cores (:func:`~sigma_des.calibrate.dequeue.job_services`, replayed over
    the whole run per method, so jobs queued before the window count)."""
    pub = msgs[msgs["kind"] == "state_pub"]
    pub = pub[np.isfinite(pub["t_trig"]) & (pub["t_send"] >= pub["t_trig"])]
    host = pub["method"].astype(str) + "/" + pub["host"].astype(str)
    cost = job_services(host, pub["node"], pub["t_trig"], pub["t_send"], base.cores_per_host)
    pub = pub.assign(raw=pub["t_send"] - pub["t_trig"], cost=cost)
    return pub[(pub["t_send"] >= base.warmup) & (pub["t_send"] < base.duration)]


def _check_rows(pub: pd.DataFrame, states: pd.DataFrame, recording: bool, strict: bool,
                kept: str, warn: list[str]) -> None:
    """Refuse (``strict``) or warn about hosts whose states arrived without per-node rows."""
    if recording:
        warn.append(f"an MCAP recording has no per-node publish rows: {kept}")
        return
    sent = set(zip(states["method"], states["host"], strict=True))
    rows = set(zip(pub["method"], pub["host"], strict=True))
    missing = sorted(f"{m}/host{int(h)}" for m, h in sent - rows)
    if missing:
        msg = (f"no per-node publish rows (state_pub) from {', '.join(missing)} although "
               "their states arrived")
        if strict:
            raise ConfigError("state_pub", msg + "; rerun the live run, or pass "
                              "--allow-incomplete to fit without them")
        warn.append(msg + ("; fitted from the other hosts" if len(pub) else f"; {kept}"))


def fit_compute(base: Scenario, msgs: pd.DataFrame, states: pd.DataFrame, recording: bool,
                strict: bool, warn: list[str]) -> tuple[ComputeSpec, dict[str, Any]]:
    """``compute.step_time`` and ``compute.host_share`` from the per-node publish rows
    (see the module doc), refusing (``strict``) or warning when hosts whose states
    arrived left none; the report's figures in seconds."""
    pub = publish_costs(msgs, base)
    keep = base.compute.step_time
    kept = f"compute.step_time kept from the base scenario ({keep.dist}, mean " \
           f"{keep.mean_value() * 1e3:.3g} ms)"
    _check_rows(pub, states, recording, strict, kept, warn)
    cost = pub["cost"].to_numpy()
    if 0 < cost.size < MIN_SAMPLES:
        warn.append(f"only {cost.size} per-node publish rows (< {MIN_SAMPLES}) for the "
                    "step time")
    if not cost.size:
        return base.compute, {"step_time_mean_s": keep.mean_value(),
                              "step_time_std_s": keep.std, "step_time_host_share": float("nan"),
                              "host_share": base.compute.host_share, "step_time_samples": 0}
    mean, std = float(cost.mean()), float(cost.std()) if cost.size > 1 else 0.0
    share = host_share(pub)
    rho = float(np.clip(share, 0.0, HOST_SHARE_CAP)) if np.isfinite(share) else 0.0
    if not np.isfinite(share):
        warn.append("no host had two nodes' services in one frame: compute.host_share 0 "
                    "(independent nodes)")
    elif share != rho:
        warn.append(f"compute.host_share estimate {share:.3f} clamped to {rho:g} "
                    f"(allowed 0..{HOST_SHARE_CAP})")
    spec = ComputeSpec(step_time=Dist(dist="lognormal", mean=max(mean, 1e-7), std=std),
                       host_share=rho)
    return spec, {"step_time_mean_s": mean, "step_time_std_s": std,
                  "step_time_with_core_wait_mean_s": float(pub["raw"].mean()),
                  "step_time_host_share": share, "host_share": rho,
                  "step_time_samples": int(cost.size)}
