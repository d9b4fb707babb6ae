"""The engine benchmark's cases: plan, run one in a fresh process, compare, tabulate rows.

``experiments/bench_engine.py`` (a front end to :mod:`~sigma_lab.studies.engine_driver`,
whose report is :mod:`~sigma_lab.studies.engine_tables`) times the cohort engine, the
per-message engine and the process-per-message reference model
(:mod:`sigma_lab.reference.process_model`) for every node count; this module holds
what it runs: :func:`plan` (the cases of one N), :func:`run_fresh` (one case in a
fresh child process on the local executor, :mod:`sigma_des.pool`, so peak RSS
is per case), :func:`make_row` (one CSV row) and :func:`annotate` (speed-up ratios
and the metric checks). See ``lab/record/BENCHMARKS.md``.

For every node count N this measures, each case in a fresh child process (so
peak RSS is per case, single-threaded):

* on the *full* scenario (commands on, default settings), for each method of
  ``--methods``: the cohort engine (``engine="cohort"``, impl ``cohort``) and the
  per-message SimPy engine that is the executable specification
  (``engine="events"``, impl ``events``);
* on the *restricted* scenario (commands off; transport stream without loss,
  QoS 1, no faults: the defaults), method ``none``: ``cohort``, ``events`` and the
  baseline (``sigma_lab.reference.process_model.ProcessModel``: one SimPy process per
  message, ``simpy.Resource`` broker/links/cores) on the very same scenario and
  seed;

and reports wall seconds per simulated second, times real time, events per
wall second (engines: kernel events, the cohort core's message events included;
baseline: SimPy processes + timeouts + resource requests it created), the share
of events the compiled core ran from fan-out batches, peak RSS, the engine really
used (the cohort engine falls back to the per-message engine for features it does
not reproduce, see ``sigma_des.events.fast.support.unsupported``, or mid-run on
``CohortFallback``; the reason is recorded), and the speed-ups
cohort / events, cohort / baseline and events / baseline (ratios of wall seconds
per simulated second).

The per-message engine and the baseline are slow at large N, so at
N >= ``--large-n`` (1000) they simulate ``min(duration, --events-cap)`` and
``min(duration, --baseline-cap)`` (2 s each), and above ``--baseline-max-n``
(1000) the baseline is skipped with a note.

It also checks the metrics: cohort and events must be bit-identical on every
metric (max relative difference exactly 0), cohort and baseline must agree to
:data:`BASELINE_RTOL` on :data:`COMPARED` (two independent implementations of the
same model with the same keyed random draws; see lab/record/BENCHMARKS.md). Metrics
are only compared between runs of the same simulated duration: where
``--events-cap`` or ``--baseline-cap`` shortens a run, a cohort *twin* of that
duration is run as well. The exit status is 1 if a check fails.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple

from sigma_des import config
from sigma_des.pool import run_all
from sigma_lab.studies.engine_case import Case
from sigma_lab.studies.engine_norm import target_of

__all__ = ["ALL_METHODS", "BASELINE_RTOL", "COLUMNS", "COMPARED", "ENGINES", "NODES_PER_HOST",
           "THREAD_VARS", "Case", "Check", "Sim", "annotate", "baseline_estimate_s", "col",
           "make_row", "max_rel_diff", "overrides_for", "plan", "run_case", "run_fresh",
           "simulate"]

#: Physics nodes per host (the paper: 20 aircraft per PC).
NODES_PER_HOST = config.NODES_PER_HOST

#: Alignment methods (``--methods all``), as in ``sigma_des.config.METHODS``.
ALL_METHODS: tuple[str, ...] = config.METHODS

#: The two engines of ``sigma_des`` (scenario field ``engine``).
ENGINES: tuple[str, ...] = ("cohort", "events")

#: Metrics compared between the engines and the baseline, and written to the CSV:
#: (name, unit).
COMPARED: tuple[tuple[str, str], ...] = (
    ("latency_state_mean", "ms"),
    ("latency_state_p99", "ms"),
    ("latency_trigger_mean", "ms"),
    ("aoi_mean", "ms"),
    ("aoi_p99", "ms"),
    ("aoi_time_avg", "ms"),
    ("aoi_peak_mean", "ms"),
    ("trigger_rate_hz", ""),
    ("throughput_mbps", ""),
    ("deliveries_per_s", ""),
    ("snapshot_rate_hz", ""),
    ("spread_mean", ""),
    ("pos_err_mean", "m"),
)

#: Largest relative difference of a :data:`COMPARED` metric accepted between the
#: cohort engine and the baseline (floating point summation order; the observed
#: differences are ~1e-14).
BASELINE_RTOL = 1e-9

#: Baseline wall seconds per node and simulated second, for the skip note when no
#: baseline ran in this invocation (measured: ~29 s per simulated s at N = 1000).
BASELINE_S_PER_NODE = 0.025


def col(name: str, unit: str) -> str:
    """The CSV column of a compared metric: ``name_unit`` (just ``name`` without a unit)."""
    return f"{name}_{unit}" if unit else name


#: CSV columns, one row per case.
COLUMNS: tuple[str, ...] = (
    "n", "impl", "method", "scenario", "role", "engine_used", "fallback",
    "sim_s", "wall_s", "wall_per_sim_s", "x_realtime", "cpu_per_sim_s", "x_realtime_cpu",
    "load1", "cpu_per_sim_s_norm", "x_realtime_norm", "target_x",  # engine_norm
    "events", "events_per_s", "batched_share",  # engine_tables' "batched"
    "peak_rss_mb",
    "ratio_vs_events",
    "ratio_vs_baseline",
    *(col(n, u) for n, u in COMPARED),
    "max_rel_diff",
    "max_rel_diff_metric",
)

#: Thread-count variables set to 1: one core per case.
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


# ---------------------------------------------------------------- one case (child process)


def overrides_for(
    n: int,
    duration: float,
    restricted: bool,
    extra: Sequence[str] = (),
    impl: str = "baseline",
) -> list[str]:
    """The scenario of one case as ``key=value`` overrides (see ``sigma_des.config.load``).

    Args:
        n: number of nodes (``NODES_PER_HOST`` per host).
        duration: simulated seconds (warm-up ``min(1 s, duration/5)``).
        restricted: commands off (the scenario class the baseline supports).
        extra: further overrides (``--set``), applied before the engine.
        impl: ``cohort`` or ``events`` select that engine (last, so ``--set`` cannot
            change it); ``baseline`` leaves the scenario's engine field alone.
    """
    hosts = max(1, math.ceil(n / NODES_PER_HOST))
    warmup = min(1.0, 0.2 * duration)
    ov = [f"nodes={n}", f"hosts={hosts}", f"duration={duration!r}", f"warmup={warmup!r}"]
    if restricted:
        ov.append("commands.enabled=false")
    ov += list(extra)
    if impl in ENGINES:
        ov.append(f'engine="{impl}"')
    return ov


class Sim(NamedTuple):
    """What one simulation returns.

    Attributes:
        wall_s: wall seconds to build and run the model.
        events: event count (see the module docstring).
        metrics: every metric of the run.
        engine_used: ``cohort``, ``events`` or ``baseline``.
        fallback: why the cohort engine was not used ("" if it was or not asked for).
        cpu_s: CPU seconds of this process over the same span (``time.process_time``;
            on a shared machine the figure that descheduling does not inflate).
        batched: events the compiled core ran from batches (fan-out batches and channels).
        classes: the compiled core's events by class, batched or not, and why some were
            not (``sigma_des.events.fast.tally.breakdown``; empty without the core).
    """

    wall_s: float
    events: int
    metrics: dict[str, float]
    engine_used: str
    fallback: str
    cpu_s: float = math.nan
    batched: int = 0
    classes: dict[str, int] = {}  # noqa: RUF012 (a NamedTuple default, never mutated)


def simulate(impl: str, method: str, sc: Any) -> Sim:
    """Build and run one simulation.

    For the engines this does what ``sigma_des.api.run_method`` does without the
    fidelity metrics (whose ideal run would be timed too), through the same
    :func:`~sigma_des.events.cohort.execute`: the engine of ``sc.engine``; a mid-run
    ``CohortFallback`` re-runs the whole simulation on the per-message engine, and
    the wall time includes the aborted attempt (what a user of the cohort engine pays).
    """
    import time

    if impl in ENGINES:
        from sigma_des.events.cohort import execute
        from sigma_des.events.fast.tally import breakdown
        from sigma_des.factory import make_behaviour, make_dynamics

        if sc.engine != impl:
            raise ValueError(f"impl {impl!r} but scenario engine {sc.engine!r}")
        t0, c0 = time.perf_counter(), time.process_time()
        run, out, eng = execute(sc.run_spec(), method, lambda: make_dynamics(sc),
                                lambda: make_behaviour(sc))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        core = getattr(run.core, "S", None)  # the compiled core's state, if it ran
        classes = breakdown(core) if core is not None else {}
        return Sim(wall, int(run.kernel.events), dict(out["metrics"]), eng["used"],
                   eng["fallback"], cpu, classes.get("batched", 0), classes)
    if impl == "baseline":
        from sigma_lab.reference.process_model import ProcessModel, check_supported

        check_supported(sc, method)
        t0, c0 = time.perf_counter(), time.process_time()
        model = ProcessModel(sc)
        metrics = model.run()
        return Sim(time.perf_counter() - t0, model.sim_events, metrics, "baseline", "",
                   time.process_time() - c0)
    raise ValueError(f"unknown impl {impl!r}")


def run_case(
    impl: str, method: str, overrides: list[str], cpu: int | None = None
) -> dict[str, Any]:
    """Run one case in this process; return timing, counts, peak RSS and metrics.

    A two-node run of the same kind, past the first command tick (:func:`warm_duration`),
    goes first, untimed, so that one-off costs (imports, numba kernels loaded) are not
    timed; the core's kernels it never reaches are loaded then too (``MethodRun.
    load_kernels``). ``kernels_loaded``: those the timed run still loaded (0 expected).
    """
    import resource

    from sigma_des.jitcache import loaded_specialisations

    if cpu is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})
    from sigma_des.errors import ConfigError

    load = config.load
    sc = load(overrides=overrides)
    try:
        warm = load(overrides=[*overrides, "nodes=2", "hosts=1",
                               f"duration={warm_duration(sc)!r}", "warmup=0.0"])
    except ConfigError:  # e.g. a fault naming a node >= 2: no warm-up then
        warm = None
    if warm is not None:
        simulate(impl, method, warm)
        if impl == "cohort":  # the kernels a tiny run never reaches (commands, rollbacks)
            from sigma_des.events.cohort import make_run
            from sigma_des.factory import make_behaviour, make_dynamics

            make_run(warm.run_spec(), method, make_dynamics(warm),
                     make_behaviour(warm))[0].load_kernels()
    held = loaded_specialisations()
    sim = simulate(impl, method, sc)
    kernels = loaded_specialisations() - held
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB
    return {
        "load1": os.getloadavg()[0],
        "sim_s": sc.duration,
        "wall_s": sim.wall_s,
        "cpu_s": sim.cpu_s,
        "events": sim.events,
        "batched": sim.batched,
        "classes": sim.classes,
        "peak_rss_mb": rss_mb,
        "engine_used": sim.engine_used,
        "fallback": sim.fallback,
        "kernels_loaded": kernels,
        "metrics": {k: float(v) for k, v in sim.metrics.items()},
    }


def warm_duration(sc: Any) -> float:
    """:func:`run_case`'s warm-up length (s): past the first command tick, where the behaviour
    loads its kernels (≈ 25 ms; lab/record/BENCHMARKS.md, issue 27, fixed costs, session 16)."""
    return max(0.05, (sc.commands.every + 2) / sc.f_align)


#: Modules a forkserver imports once, so that each forked case starts with them loaded.
PRELOAD = [
    "sigma_des.events.engine",
    "sigma_des.events.cohort",
    "sigma_des.factory",
    "sigma_des.agents.registry",
    "sigma_lab.reference.process_model",
    "sigma_lab.studies.engine_bench",
]


def run_fresh(
    impl: str, method: str, overrides: list[str], cpu: int | None, start_method: str = "forkserver"
) -> dict[str, Any]:
    """:func:`run_case` in a fresh child process, so peak RSS and caches are per case.

    ``forkserver`` (default) forks every case from a server process that has only
    imported :data:`PRELOAD` (no case ever ran in it), which saves the ~1–2 s
    import per case; ``spawn`` starts a new interpreter per case. Either way the
    case's peak RSS includes the interpreter and the imported packages.
    """
    calls = [(impl, method, overrides, cpu)]
    [out] = run_all(run_case, calls, 1, start_method, fresh=True, preload=PRELOAD)
    return out  # type: ignore[no-any-return]


# ---------------------------------------------------------------- planning


def plan(
    n: int,
    methods: Sequence[str],
    duration: float,
    events_cap: float,
    baseline_cap: float | None,
    large_n: int,
) -> list[Case]:
    """The cases of one node count, in running order.

    Args:
        n: number of nodes.
        methods: methods timed on the full scenario.
        duration: simulated seconds of the cohort cases.
        events_cap: at ``n >= large_n`` the ``events`` cases simulate
            ``min(duration, events_cap)``.
        baseline_cap: the same for the baseline; None: no baseline at this N.
        large_n: where the caps start.
    """
    big = n >= large_n
    dur_e = min(duration, events_cap) if big else duration
    cases: list[Case] = []
    for m in methods:
        cases += [Case("cohort", m, "full", duration), Case("events", m, "full", dur_e)]
        if dur_e != duration:
            cases.append(Case("cohort", m, "full", dur_e, "twin"))
    cases += [
        Case("cohort", "none", "restricted", duration),
        Case("events", "none", "restricted", dur_e),
    ]
    twins = [dur_e]
    if baseline_cap is not None:
        dur_b = min(duration, baseline_cap) if big else duration
        cases.append(Case("baseline", "none", "restricted", dur_b))
        twins.append(dur_b)
    for d in sorted(set(twins) - {duration}, reverse=True):
        cases.append(Case("cohort", "none", "restricted", d, "twin"))
    return cases


def baseline_estimate_s(rows: Iterable[dict[str, Any]], n: int, sim_s: float) -> float:
    """Estimated baseline wall seconds at ``n`` nodes for ``sim_s`` simulated seconds.

    Linear in N from the largest baseline case measured so far, else from
    :data:`BASELINE_S_PER_NODE`.
    """
    done = [r for r in rows if r["impl"] == "baseline"]
    per_node = BASELINE_S_PER_NODE
    if done:
        last = max(done, key=lambda r: r["n"])
        per_node = last["wall_per_sim_s"] / last["n"]
    return per_node * n * sim_s


# ---------------------------------------------------------------- reporting


def rel_diff(a: float, b: float) -> float:
    """``|a - b| / max(|a|, |b|)``: 0 if equal or both NaN, inf if only one is NaN."""
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if math.isnan(a) or math.isnan(b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def max_rel_diff(
    a: dict[str, float], b: dict[str, float], names: Iterable[str]
) -> tuple[float, str]:
    """Largest relative difference between two metric dicts over ``names``, and where.

    A metric missing on one side counts as NaN (so it differs unless both lack it).
    The metric name is "" when every difference is 0.
    """
    worst, where = 0.0, ""
    for name in names:
        d = rel_diff(a.get(name, math.nan), b.get(name, math.nan))
        if d > worst:
            worst, where = d, name
    return worst, where


def make_row(case: Case, n: int, res: dict[str, Any]) -> dict[str, Any]:
    """One CSV row (plus the private key ``_metrics``: every metric of the run)."""
    wall = res["wall_s"]
    sim = res["sim_s"]
    cpu = res.get("cpu_s", math.nan)
    row: dict[str, Any] = {
        "n": n,
        "impl": case.impl,
        "method": case.method,
        "scenario": case.scenario,
        "role": case.role,
        "engine_used": res["engine_used"],
        "fallback": res["fallback"],
        "sim_s": sim,
        "wall_s": wall,
        "wall_per_sim_s": wall / sim,
        "x_realtime": sim / wall,
        "cpu_per_sim_s": cpu / sim,
        "x_realtime_cpu": sim / cpu if cpu > 0 else math.nan,
        "load1": res.get("load1", math.nan),
        "cpu_per_sim_s_norm": math.nan, "x_realtime_norm": math.nan,  # engine_norm
        "target_x": target_of(case, n),
        "events": res["events"],
        "events_per_s": res["events"] / wall,
        "batched_share": res.get("batched", 0) / max(1, res["events"]),
        "peak_rss_mb": res["peak_rss_mb"],
        "ratio_vs_events": "",
        "ratio_vs_baseline": "",
        "max_rel_diff": "",
        "max_rel_diff_metric": "",
        "_metrics": res["metrics"],
        "_classes": res.get("classes", {}),
    }
    for name, unit in COMPARED:
        row[col(name, unit)] = res["metrics"].get(name, math.nan)
    return row


class Check(NamedTuple):
    """One metric comparison between a cohort run and an events or baseline run."""

    n: int
    scenario: str
    method: str
    other: str
    sim_s: float
    diff: float
    metric: str
    ok: bool


def annotate(rows: list[dict[str, Any]]) -> list[Check]:
    """Fill the ratio and difference columns of ``rows``; return the metric checks.

    Per (N, method, scenario): ``ratio_vs_events`` on the cohort rows and
    ``ratio_vs_baseline`` on the cohort and events rows are the other case's wall
    seconds per simulated second divided by this row's (this row's speed-up; per
    simulated second, so valid where a cap shortened the other case).
    ``max_rel_diff`` on an events or baseline row compares it with the cohort row
    of the same simulated duration: over every metric for events (must be 0.0),
    over :data:`COMPARED` for the baseline (must be <= :data:`BASELINE_RTOL`).
    """
    groups: dict[tuple[int, str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["n"], r["method"], r["scenario"]), []).append(r)
    checks: list[Check] = []
    for (n, method, scenario), rs in groups.items():
        main = {r["impl"]: r for r in rs if r["role"] == "main"}
        cohort_at = {r["sim_s"]: r for r in rs if r["impl"] == "cohort"}
        for impl, targets in (("events", ("cohort",)), ("baseline", ("cohort", "events"))):
            other = main.get(impl)
            if other is None:
                continue
            for r in rs:
                if r["impl"] in targets:
                    r[f"ratio_vs_{impl}"] = other["wall_per_sim_s"] / r["wall_per_sim_s"]
            twin = cohort_at.get(other["sim_s"])
            if twin is None:
                continue
            if impl == "events":
                names: Iterable[str] = sorted(set(twin["_metrics"]) | set(other["_metrics"]))
                tol = 0.0
            else:
                names = [nm for nm, _u in COMPARED]
                tol = BASELINE_RTOL
            diff, where = max_rel_diff(twin["_metrics"], other["_metrics"], names)
            other["max_rel_diff"], other["max_rel_diff_metric"] = diff, where
            checks.append(
                Check(n, scenario, method, impl, other["sim_s"], diff, where, diff <= tol)
            )
    return checks
