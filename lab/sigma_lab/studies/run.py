"""Running a paper study: every variant × seed × method label, on the local executor.

A study script (``experiments/scale_200.py`` and its siblings) names its *variants*
(a variant is one scenario family, e.g. one transport or one fault: a function
building its scenario for a seed) and, per variant, its method labels
(:class:`~sigma_lab.studies.model.MethodSpec`); :func:`run_study` runs every
(variant, seed) case with :func:`sigma_des.api.compare`, in this process or on
``--jobs`` worker processes of :func:`sigma_des.pool.run_all`, and derives
the time-series metrics of every run.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace

from sigma_des.api import Results, compare
from sigma_des.config import Scenario, load, with_overrides
from sigma_des.pool import run_all
from sigma_lab.studies.derived import derived_metrics
from sigma_lab.studies.model import MethodSpec, RunRecord, Study

__all__ = ["known", "load_scenario", "run_case", "run_study", "scenario_for"]

#: One finished method label: (variant, its spec, the results holding it).
Done = tuple[str, MethodSpec, Results]


def run_case(
    variant: str, sc: Scenario, specs: Sequence[MethodSpec], progress: bool = False
) -> list[Done]:
    """Run every method spec of one variant and seed (specs sharing overrides share a run)."""
    out: list[Done] = []
    groups: dict[tuple[str, ...], list[MethodSpec]] = {}
    for s in specs:
        groups.setdefault(s.overrides, []).append(s)
    for overrides, group in groups.items():
        scv = with_overrides(sc, overrides)
        res = compare(scv, methods=[s.method for s in group], progress=progress)
        for s in group:
            out.append((variant, s, res))
    order = {s.label: i for i, s in enumerate(specs)}
    out.sort(key=lambda x: order[x[1].label])
    return out


def run_study(
    name: str,
    args: argparse.Namespace,
    variants: Mapping[str, Callable[[int], Scenario]],
    specs: Mapping[str, Sequence[MethodSpec]],
) -> Study:
    """Run every variant × seed × method label and derive time-series metrics.

    Args:
        name: the study name.
        args: parsed arguments (seeds, jobs, progress).
        variants: variant name -> function building its scenario for a seed.
        specs: variant name -> its method labels.

    Returns:
        The study with one :class:`RunRecord` per variant × seed × label.
    """
    study = Study(name, args)
    cases: list[tuple[str, Scenario, tuple[MethodSpec, ...], bool]] = []
    parallel = args.jobs > 1 and len(variants) * len(args.seeds) > 1
    for v, build in variants.items():
        for seed in args.seeds:
            sc = build(seed)
            if v not in study.variants:
                study.variants[v] = sc
            # progress bars only when the cases run here, one after another
            cases.append((v, sc, tuple(specs[v]), bool(args.progress) and not parallel))
    t0 = time.perf_counter()
    done: list[list[Done]] = run_all(
        run_case, cases, args.jobs if parallel else 1, start_method="spawn"
    )
    study.wall_s = time.perf_counter() - t0
    for case_out in done:
        for variant, spec, res in case_out:
            rec = RunRecord(variant, res.scenario.seed, spec.label, res, spec)
            rec.derived = derived_metrics(res.timeseries[spec.method], res.methods[spec.method])
            study.records.append(rec)
    return study


def scenario_for(base: Scenario, seed: int) -> Scenario:
    """``base`` with another root seed."""
    return replace(base, seed=seed)


def known(overrides: Iterable[str]) -> list[str]:
    """The overrides whose top-level key is a :class:`Scenario` field (others dropped).

    Lets a script pin optional parts of the model (e.g. ``fidelity.enabled``) that an
    older or newer version of the package may not have.
    """
    names = {f.name for f in dataclasses.fields(Scenario)}
    return [o for o in overrides if o.split("=", 1)[0].split(".", 1)[0].strip() in names]


def load_scenario(path: str | None, overrides: Iterable[str]) -> Callable[[int], Scenario]:
    """A per-seed scenario builder: ``load(path, overrides)`` with ``seed`` set.

    Overrides naming a top-level key the scenario does not have are dropped (see
    :func:`known`).
    """
    base = load(path, known(overrides))
    return lambda seed: scenario_for(base, seed)
