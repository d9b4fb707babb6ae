"""The engine benchmark's normalised figures: the reference baseline and the targets.

Machines differ, so ``experiments/bench_engine.py`` scales every CPU-s/s figure by the
SimPy baseline measured in the same run (:func:`normalise`, :func:`reference_row`) and
checks each cohort row against issue 27's target (:func:`target_of`); see
``lab/record/BENCHMARKS.md``, "How to run".
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from sigma_lab.studies.engine_case import Case

__all__ = ["REF_CPU_PER_SIM_S", "REF_NODES", "REF_SIM_S", "normalise", "reference_row",
           "target_of"]

#: The reference machine of the speed targets (issue 27, lab/record/BENCHMARKS.md): there the
#: in-repo SimPy baseline (:mod:`sigma_lab.reference.process_model`) costs this many CPU
#: seconds per simulated second at ``REF_NODES`` nodes, restricted scenario, ``REF_SIM_S``
#: simulated seconds. A figure measured here is scaled by ``REF_CPU_PER_SIM_S / b``, ``b``
#: the baseline of the same benchmark run, so machines of different speed compare.
REF_CPU_PER_SIM_S = 10.0
REF_NODES = 1000
REF_SIM_S = 2.0


def target_of(case: Case, n: int) -> float:
    """The issue's real-time target (times real time, normalised) of a case; NaN: none.

    N = 1 000 full scenario BiDES: 20x (10x for a run of 1 s or less, fixed costs
    included); N = 10 000 full BiDES: 2x; restricted loop N = 1 000: 50x. Only
    cohort cases of the ``main`` role carry one.
    """
    if case.impl != "cohort" or case.role != "main":
        return math.nan
    if case.scenario == "full" and case.method == "bides":
        if n == 1000:
            return 10.0 if case.sim_s <= 1.0 else 20.0
        if n == 10000:
            return 2.0
    if case.scenario == "restricted" and case.method == "none" and n == 1000:
        return 50.0
    return math.nan


def reference_row(
    rows: Iterable[dict[str, Any]], n: int = REF_NODES, sim_s: float = REF_SIM_S
) -> dict[str, Any] | None:
    """The baseline row that normalises the run: ``n`` nodes, restricted, ``sim_s`` s."""
    for r in rows:
        if (r["impl"], r["scenario"], r["n"], r["sim_s"]) == ("baseline", "restricted", n, sim_s):
            return r
    return None


def normalise(rows: list[dict[str, Any]], ref: dict[str, Any] | None) -> float:
    """Fill ``cpu_per_sim_s_norm`` and ``x_realtime_norm`` of every row; return the factor.

    The factor is ``REF_CPU_PER_SIM_S / ref["cpu_per_sim_s"]`` (NaN without a reference
    row: the columns stay NaN): a machine where the baseline is 3x slower than on the
    reference machine has its figures divided by 3.
    """
    if ref is None or not ref["cpu_per_sim_s"] > 0:
        return math.nan
    factor = REF_CPU_PER_SIM_S / float(ref["cpu_per_sim_s"])
    for r in rows:
        norm = float(r["cpu_per_sim_s"]) * factor
        r["cpu_per_sim_s_norm"] = norm
        r["x_realtime_norm"] = 1.0 / norm if norm > 0 else math.nan
    return factor
