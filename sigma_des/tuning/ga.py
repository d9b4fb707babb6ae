"""The genetic algorithm of the paper's Fig. 6 on DEAP, with seeded operators.

Machinery from DEAP (``creator`` individuals with a minimising fitness, the
``Toolbox``, ``HallOfFame``, ``Statistics`` and ``Logbook``); the operators are
ours because DEAP's draw from Python's global ``random`` module, which the
project never uses (determinism: every draw here is a counter-based draw of
the stream ``tuning.ga`` keyed by generation, individual, gene and purpose):

- genes live in normalised coordinates ``u = (x - lower) / (upper - lower)``
  in [0, 1]; individual 0 of the first generation is the starting parameter
  set, the others are uniform in the bounds;
- selection: tournament of ``tune.tournament`` (ties: the lower index);
- crossover: the paper's arithmetic crossover, eq. (12), ``p = d x + (1 - d) y``,
  ``q = d y + (1 - d) x`` with one ``d`` uniform in [0, 1] per pair;
- mutation: Gaussian, ``tune.sigma`` of the bound width (shrinking by
  ``tune.sigma_decay`` per generation), per gene with probability
  ``tune.indpb``, clipped to the bounds;
- elitism: the best ``tune.elite`` go through unchanged.

Every generation's new individuals are scored together: one batched flight of
all of them (replay.py) and one batched DTW (fitness.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from deap import base, creator, tools
from numpy.typing import NDArray

from sigma_des.agents.params import AircraftParams
from sigma_des.agents.wind import WindConfig
from sigma_des.core.rng import RandomStreams, Stream
from sigma_des.errors import ConfigError
from sigma_des.tuning.fitness import FitnessSpec, fitness
from sigma_des.tuning.flightlog import FlightLog, resample
from sigma_des.tuning.replay import Windows, param_matrix, replay_batch, windows
from sigma_des.tuning.spec import TuneSpec, bounds, get_value, with_values

__all__ = ["TuneResult", "Evaluator", "run_ga", "tune", "cx_arithmetic"]

if not hasattr(creator, "TuneFitness"):
    creator.create("TuneFitness", base.Fitness, weights=(-1.0,))
    creator.create("TuneIndividual", list, fitness=creator.TuneFitness)

# Purposes of the GA's draws (last id of every draw).
_INIT, _TOUR, _CX, _DELTA, _MUT, _GENE, _STEP = range(7)


@dataclass
class TuneResult:
    """Outcome of one GA run.

    Attributes:
        names: gene names.
        lower, upper: their bounds.
        start, best: starting and fitted values, per gene.
        start_fitness, best_fitness: ``r`` of both on the tuning log.
        history: per generation ``{gen, evals, best, mean}``.
        evaluations: fitness evaluations in total.
        seconds: wall time of the GA (kept apart from the results).
    """

    names: tuple[str, ...]
    lower: list[float]
    upper: list[float]
    start: list[float]
    best: list[float]
    start_fitness: float
    best_fitness: float
    history: list[dict[str, float]] = field(default_factory=list)
    evaluations: int = 0
    seconds: float = 0.0

    def values(self) -> dict[str, float]:
        """Fitted values by name."""
        return dict(zip(self.names, self.best, strict=True))


class Evaluator:
    """Scores a batch of gene vectors with one batched replay (see module doc).

    Args:
        win: the tuning log's windows.
        base_params: the parameters genes are applied to.
        names: gene names.
        channels: DTW point columns.
        wind: replay wind (default still air).
        band: DTW Sakoe–Chiba band (samples; -1 = none).
    """

    def __init__(self, win: Windows, base_params: AircraftParams, names: tuple[str, ...],
                 channels: tuple[str, ...], wind: WindConfig | None = None,
                 band: int = -1) -> None:
        self.win = win
        self.base = base_params
        self.names = names
        self.spec = FitnessSpec.of(win, channels, band)
        self.wind = wind

    def params_of(self, x: NDArray[np.float64]) -> AircraftParams | None:
        """The parameter set of gene values ``x`` (None if it is not a valid aircraft)."""
        try:
            return with_values(self.base, dict(zip(self.names, map(float, x), strict=True)))
        except ConfigError:
            return None

    def __call__(self, xs: NDArray[np.float64]) -> NDArray[np.float64]:
        """``r`` of every row of ``xs`` (``(P, G)`` gene values); ``inf`` if invalid."""
        ps = [self.params_of(x) for x in xs]
        ok = [i for i, p in enumerate(ps) if p is not None]
        valid = [p for p in ps if p is not None]
        out = np.full(len(ps), np.inf)
        if ok:
            prms = param_matrix(valid, self.wind)
            out[ok] = fitness(self.win, replay_batch(self.win, prms), self.spec)
        return out


def cx_arithmetic(x: list[float], y: list[float], delta: float) -> tuple[list[float], list[float]]:
    """Eq. (12): ``p = d x + (1 - d) y``, ``q = d y + (1 - d) x``, in place."""
    for i, (a, b) in enumerate(zip(x, y, strict=True)):
        x[i], y[i] = delta * a + (1.0 - delta) * b, delta * b + (1.0 - delta) * a
    return x, y


def _tournament(pop: list[Any], k: int, rng: Stream, gen: int, n: int) -> list[Any]:
    picks = np.floor(rng.uniform(gen, np.arange(n)[:, None], np.arange(k)[None, :], _TOUR)
                     * len(pop)).astype(np.int64)
    fit = np.array([ind.fitness.values[0] for ind in pop])
    return [pop[int(row[np.argmin(fit[row])])] for row in picks]


def _u(rng: Stream, *ids: int) -> float:
    return float(np.asarray(rng.uniform(*ids)).ravel()[0])


def _vary(off: list[Any], spec: TuneSpec, rng: Stream, gen: int) -> None:
    g_n = len(off[0])
    for j in range(0, len(off) - 1, 2):
        if _u(rng, gen, j, 0, _CX) < spec.cxpb:
            cx_arithmetic(off[j], off[j + 1], _u(rng, gen, j, 0, _DELTA))
            del off[j].fitness.values, off[j + 1].fitness.values
    for j, ind in enumerate(off):
        if _u(rng, gen, j, 0, _MUT) >= spec.mutpb:
            continue
        hit = rng.uniform(gen, j, np.arange(g_n), _GENE) < spec.indpb
        sd = max(spec.sigma_min, spec.sigma * spec.sigma_decay ** (gen - 1))
        step = sd * rng.normal(gen, j, np.arange(g_n), _STEP)
        for g in np.flatnonzero(hit):
            ind[g] = float(min(1.0, max(0.0, ind[g] + step[g])))
        if hit.any() and ind.fitness.valid:
            del ind.fitness.values


def run_ga(score: Callable[[NDArray[np.float64]], NDArray[np.float64]], start: list[float],
           lower: list[float], upper: list[float], spec: TuneSpec
           ) -> tuple[list[float], float, list[dict[str, float]], int]:
    """Minimise ``score`` over the box; returns best values, its score, history, evaluations."""
    lo, hi = np.array(lower), np.array(upper)
    width = hi - lo
    rng = RandomStreams(spec.seed).stream("tuning.ga")
    tb = base.Toolbox()
    tb.register("clone", lambda ind: creator.TuneIndividual(list(ind)))

    def evaluate(inds: list[Any]) -> int:
        todo = [ind for ind in inds if not ind.fitness.valid]
        if todo:
            r = score(lo + np.array(todo, dtype=float) * width)
            for ind, v in zip(todo, r, strict=True):
                ind.fitness.values = (float(v),)
        return len(todo)

    g_n = len(start)
    u0 = rng.uniform(0, np.arange(spec.population)[:, None], np.arange(g_n)[None, :], _INIT)
    u0[0] = (np.array(start) - lo) / width
    pop = [creator.TuneIndividual([float(v) for v in row]) for row in u0]
    stats = tools.Statistics(lambda ind: ind.fitness.values[0])
    stats.register("best", np.min)
    stats.register("mean", lambda v: float(np.mean(np.where(np.isfinite(v), v, np.nan))))
    book = tools.Logbook()
    hof = tools.HallOfFame(1)
    evals = evaluate(pop)
    hof.update(pop)
    book.record(gen=0, evals=evals, **stats.compile(pop))
    for gen in range(1, spec.generations + 1):
        elite = tools.selBest(pop, spec.elite)
        parents = _tournament(pop, spec.tournament, rng, gen, spec.population - spec.elite)
        off = [tb.clone(p) for p in parents]
        for o, p in zip(off, parents, strict=True):
            o.fitness.values = p.fitness.values
        _vary(off, spec, rng, gen)
        n = evaluate(off)
        evals += n
        pop = [tb.clone(e) for e in elite] + off
        for p, e in zip(pop, elite, strict=False):
            p.fitness.values = e.fitness.values
        hof.update(pop)
        book.record(gen=gen, evals=n, **stats.compile(pop))
    best = hof[0]
    hist = [{k: float(rec[k]) for k in ("gen", "evals", "best", "mean")} for rec in book]
    return [float(v) for v in lo + np.array(best) * width], float(best.fitness.values[0]), \
        hist, evals


def tune(log: FlightLog, start: AircraftParams, spec: TuneSpec,
         wind: WindConfig | None = None) -> TuneResult:
    """Fit ``start``'s genes to ``log`` (paper's Fig. 6); deterministic in ``spec.seed``."""
    t0 = time.perf_counter()
    names, lo, hi = bounds(spec, start, log.kind)
    win = windows(resample(log, spec.rate), spec.segment)
    ev = Evaluator(win, start, names, spec.channels_of(log.kind), wind, spec.band)
    x0 = [get_value(start, g) for g in names]
    best, r, hist, n = run_ga(ev, x0, lo, hi, spec)
    r0 = float(ev(np.array([x0]))[0])
    return TuneResult(names=names, lower=lo, upper=hi, start=x0, best=best,
                      start_fitness=r0, best_fitness=r, history=hist, evaluations=n,
                      seconds=time.perf_counter() - t0)
