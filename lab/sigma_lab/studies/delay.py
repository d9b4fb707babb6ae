"""The delay study's conditions and statistics (``experiments/train_under_delay.py``).

A condition is ``perfect`` (true current state, ideal network) or ``<method>@<ms>ms``
(host links with normal(L, L/5) latency and Bernoulli loss, the policy observing that
method's aligned view). Per delay cell, :func:`paired_cells` compares the policies
trained under that cell with those trained with perfect information, both evaluated
under it, seed by seed: means with 95 % t intervals and one-sided paired tests.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

__all__ = ["cells", "ci95", "env_kwargs", "paired_cells", "perfect_rows"]


def cells(delays: list[float], methods: list[str]) -> list[str]:
    """Condition names: ``perfect`` then ``<method>@<ms>ms`` per delay cell."""
    return ["perfect"] + [f"{m}@{round(d * 1000)}ms" for d in delays for m in methods]


def env_kwargs(cond: str, nodes: int, max_steps: int, loss: float) -> dict[str, Any]:
    """SwarmVec arguments of a condition (see :func:`cells`), on the ``tight`` task; the
    scenes' runs collect no simulator metrics (``metrics=False``: the same episodes,
    faster)."""
    sc: dict[str, Any] = {"nodes": nodes}
    if cond == "perfect":
        return {"task": "tight", "method": "none", "max_steps": max_steps,
                "perfect_info": True, "scenario": sc, "metrics": False}
    method, ms = cond.split("@")
    lat = float(ms.removesuffix("ms")) / 1000.0
    sc["net.host_link.latency"] = {"dist": "normal", "mean": lat, "std": lat / 5}
    sc["net.host_link.loss"] = {"p": loss}
    return {"task": "tight", "method": method, "max_steps": max_steps, "perfect_info": False,
            "scenario": sc, "metrics": False}


def ci95(x: np.ndarray) -> float:
    """Half-width of the 95 % t interval of the mean (0 for one value)."""
    n = len(x)
    if n < 2:
        return 0.0
    return float(stats.t.ppf(0.975, n - 1) * x.std(ddof=1) / np.sqrt(n))


def paired_cells(evals: list[dict[str, Any]], conds: list[str], seeds: list[int]
                 ) -> list[dict[str, Any]]:
    """Per delay cell: both trainings under that delay, CI and the paired tests.

    Args:
        evals: rows ``{trained, seed, evaluated, fitness}``; the hand-written
            controllers under seed -1 (``untrained``, ``naive``, ``extrapolating``).
        conds: :func:`cells` (``perfect`` first).
        seeds: the training seeds to pair.
    """
    fit = {(e["trained"], e["seed"], e["evaluated"]): e["fitness"] for e in evals}
    rows = []
    for cell in conds[1:]:
        if any((cell, s, cell) not in fit or ("perfect", s, cell) not in fit
               for s in seeds):  # not trained under it, or no perfect-trained policy to pair
            continue
        d = np.array([fit[(cell, s, cell)] for s in seeds])
        p = np.array([fit[("perfect", s, cell)] for s in seeds])
        diff = d - p
        row: dict[str, Any] = {
            "cell": cell, "n_seeds": len(seeds),
            "delay_trained_mean": float(d.mean()), "delay_trained_ci95": ci95(d),
            "perfect_trained_mean": float(p.mean()), "perfect_trained_ci95": ci95(p),
            "diff_mean": float(diff.mean()), "diff_ci95": ci95(diff),
            "t_p_greater": float("nan"), "wilcoxon_p_greater": float("nan")}
        if len(seeds) >= 2 and np.ptp(diff) > 0:
            row["t_p_greater"] = float(stats.ttest_rel(d, p, alternative="greater").pvalue)
        if len(seeds) >= 2 and np.any(diff != 0):
            row["wilcoxon_p_greater"] = float(
                stats.wilcoxon(d, p, alternative="greater").pvalue)
        for name in ("untrained", "naive", "extrapolating"):
            row[f"{name}_fitness"] = fit.get((name, -1, cell), float("nan"))
        rows.append(row)
    return rows


def perfect_rows(evals: list[dict[str, Any]], seeds: list[int], where: str = "perfect"
                 ) -> list[dict[str, Any]]:
    """Every policy evaluated under ``where``: the hand-written ones (seed -1) and, per
    training condition, the mean ± 95 % CI over ``seeds`` of its policies."""
    rows: list[dict[str, Any]] = []
    per: dict[str, list[float]] = {}
    for e in evals:
        if e["evaluated"] != where:
            continue
        if e["seed"] == -1:
            rows.append({"policy": e["trained"], "mean": e["fitness"], "ci95": 0.0, "n": 1,
                         "seed_mean": False})
        elif e["seed"] in seeds:
            per.setdefault(e["trained"], []).append(e["fitness"])
    for name, v in per.items():
        x = np.array(v)
        rows.append({"policy": f"trained {name}", "mean": float(x.mean()), "ci95": ci95(x),
                     "n": len(x), "seed_mean": True})
    return rows
