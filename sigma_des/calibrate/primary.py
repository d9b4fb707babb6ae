"""A campaign's primary run: the most typical of the calibration setting's repeats.

``calibrate`` takes the step time, its host share and the scenario's own keys from one
run, the *primary*, and re-runs it to match the hops (:mod:`sigma_des.calibrate.match`).
Live runs of one setting differ by 10-20 % in state latency, so the primary's luck
travels into every prediction. Given several per-node runs of the first one's size and
hosts (*repeats*), the primary is the one whose mean AoI and mean state latency lie
closest to the repeats' medians (:func:`central`), whatever order they were given in;
one or two repeats: the first.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["CENTRAL_METRICS", "central", "primary_run"]

#: Metrics :func:`central` compares the repeats on.
CENTRAL_METRICS = ("aoi_mean", "latency_state_mean")

Figures = Mapping[str, Mapping[str, float]]


def _positive(x: Any) -> bool:
    return isinstance(x, int | float) and math.isfinite(x) and x > 0


def central(runs: Mapping[str, Figures], metrics: Sequence[str] = CENTRAL_METRICS) -> str:
    """The most typical of several runs of one setting.

    Args:
        runs: per run name (in the order given), per method, per metric, the value.
        metrics: the metrics compared.

    Returns:
        The name of the run whose values have the least summed ``|log x - median|``,
        the median of the runs' ``log x`` of each method and metric with a positive
        finite value in every run (a pair missing in some run is left out); the first run on
        ties, with two runs (equally far from their median) or when no pair is comparable.

    Raises:
        ValueError: ``runs`` is empty.
    """
    if not runs:
        raise ValueError("central() needs at least one run")
    names = list(runs)
    if len(names) <= 2:  # two runs are equally far from their median: the first
        return names[0]
    cost = dict.fromkeys(names, 0.0)
    pairs = {(m, k) for r in runs.values() for m in r for k in metrics}
    for m, k in sorted(pairs):
        xs = [runs[n].get(m, {}).get(k, math.nan) for n in names]
        if not all(_positive(x) for x in xs):
            continue
        logs = [math.log(x) for x in xs]
        srt = sorted(logs)
        mid = len(srt) // 2
        med = srt[mid] if len(srt) % 2 else 0.5 * (srt[mid - 1] + srt[mid])
        for n, lx in zip(names, logs, strict=True):
            cost[n] += abs(lx - med)
    return min(names, key=lambda n: (cost[n], names.index(n)))


def primary_run(runs: Sequence[Mapping[str, Any]]) -> tuple[int, str]:
    """The index of a campaign's primary run, and the rule that chose it.

    Args:
        runs: per run in the order given: ``name``, ``bundle``, ``nodes``, ``hosts`` and
            ``figures`` (per method, per metric, the live run's value).

    Returns:
        The most typical (:func:`central`) of the per-node runs of the first per-node
        run's nodes and hosts; the first run when none is per node.
    """
    node = [i for i, r in enumerate(runs) if not r["bundle"]]
    if not node:
        return 0, "the first run (none is per node)"
    first = runs[node[0]]
    reps = [i for i in node if (runs[i]["nodes"], runs[i]["hosts"])
            == (first["nodes"], first["hosts"])]
    if len(reps) <= 2:
        return reps[0], (f"the first per-node run ({len(reps)} of {first['nodes']} nodes on "
                         f"{first['hosts']} hosts: three or more pick the most typical)")
    name = central({runs[i]["name"]: runs[i].get("figures", {}) for i in reps})
    i = next(j for j in reps if runs[j]["name"] == name)
    return i, (f"the most typical of the {len(reps)} per-node runs of {first['nodes']} nodes "
               f"on {first['hosts']} hosts (mean AoI and state latency closest to their "
               "medians)")
