#!/usr/bin/env python
"""Benchmark the sigma_des engine against an idiomatic process-per-message SimPy model.

For every node count N this measures, each case in a fresh child process (so
peak RSS is per case, single-threaded):

* the engine (``MethodRun``) for each method of ``--methods`` on the full
  scenario (commands on, default settings);
* the engine with method ``none`` on the *restricted* scenario (commands off;
  transport stream without loss, QoS 1, no faults: the defaults), and
* the baseline (``baseline_process_model.ProcessModel``: one SimPy process per
  message, ``simpy.Resource`` broker/links/cores) on the very same restricted
  scenario and seed;

and reports wall seconds per simulated second, times real time, events per
wall second (engine: kernel events; baseline: SimPy processes + timeouts +
resource requests it created), peak RSS, the speed ratio engine / baseline on
the identical restricted scenario, and the engine's and the baseline's metrics
side by side (they implement the same model with the same keyed random draws,
so they should agree; see docs/BENCHMARKS.md).

Examples::

    python experiments/bench_engine.py                      # N = 10,100,200,1000, 5 s each
    python experiments/bench_engine.py --quick --out q.csv  # N = 10,50, 1 s (tests)
    python experiments/bench_engine.py --nodes 200 --set compute.step_time=0.0008

Timing figures depend on the machine; nothing here asserts on them.
"""

from __future__ import annotations

import argparse
import csv
import math
import multiprocessing as mp
import os
import platform
import subprocess
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

#: Physics nodes per host (the paper: 20 aircraft per PC).
NODES_PER_HOST = 20

#: Metrics compared between the engine (method none) and the baseline: (name, unit).
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
    ("messages_per_s", ""),
    ("snapshot_rate_hz", ""),
    ("spread_mean", ""),
    ("pos_err_mean", "m"),
)


def _col(name: str, unit: str) -> str:
    return f"{name}_{unit}" if unit else name


#: CSV columns, one row per (N, case).
COLUMNS: tuple[str, ...] = (
    "n",
    "impl",
    "method",
    "scenario",
    "sim_s",
    "wall_s",
    "wall_per_sim_s",
    "x_realtime",
    "events",
    "events_per_s",
    "peak_rss_mb",
    "ratio_vs_baseline",
    *(_col(n, u) for n, u in COMPARED),
    "max_rel_diff",
    "max_rel_diff_metric",
)

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


# ---------------------------------------------------------------- one case (child process)


def overrides_for(
    n: int, duration: float, restricted: bool, extra: list[str] | tuple[str, ...] = ()
) -> list[str]:
    """The scenario of one case as ``key=value`` overrides (see ``sigma_des.config.load``)."""
    hosts = max(1, math.ceil(n / NODES_PER_HOST))
    warmup = min(1.0, 0.2 * duration)
    ov = [f"nodes={n}", f"hosts={hosts}", f"duration={duration!r}", f"warmup={warmup!r}"]
    if restricted:
        ov.append("commands.enabled=false")
    return ov + list(extra)


def _simulate(impl: str, method: str, sc: Any) -> tuple[float, int, dict[str, float]]:
    """Build and run one simulation; return (wall seconds, events, metrics)."""
    import time

    if impl == "engine":
        from sigma_des.events.engine import MethodRun
        from sigma_des.factory import make_behaviour, make_dynamics

        t0 = time.perf_counter()
        run = MethodRun(sc, method, make_dynamics(sc), make_behaviour(sc))
        out = run.run()
        return time.perf_counter() - t0, int(run.kernel.events), dict(out["metrics"])
    if impl == "baseline":
        from baseline_process_model import ProcessModel, check_supported

        check_supported(sc, method)
        t0 = time.perf_counter()
        model = ProcessModel(sc)
        metrics = model.run()
        return time.perf_counter() - t0, model.sim_events, metrics
    raise ValueError(f"unknown impl {impl!r}")


def run_case(
    impl: str, method: str, overrides: list[str], cpu: int | None = None
) -> dict[str, Any]:
    """Run one case in this process; return timing, counts, peak RSS and metrics.

    A 0.05 s two-node run of the same kind goes first, untimed, so that one-off
    costs (lazy imports, numba JIT/cache loading of the dynamics) are not counted
    as simulation time.
    """
    import resource

    if cpu is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})
    from sigma_des.config import load
    from sigma_des.errors import ConfigError

    sc = load(overrides=overrides)
    try:
        warm = load(overrides=[*overrides, "nodes=2", "hosts=1", "duration=0.05", "warmup=0.0"])
    except ConfigError:  # e.g. a fault naming a node >= 2: no warm-up then
        warm = None
    if warm is not None:
        _simulate(impl, method, warm)
    wall, events, metrics = _simulate(impl, method, sc)
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB
    return {
        "sim_s": sc.duration,
        "wall_s": wall,
        "events": events,
        "peak_rss_mb": rss_mb,
        "metrics": {k: float(v) for k, v in metrics.items()},
    }


#: Modules a forkserver imports once, so that each forked case starts with them loaded.
PRELOAD = [
    "sigma_des.events.engine",
    "sigma_des.factory",
    "sigma_des.agents.registry",
    "baseline_process_model",
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
    ctx = mp.get_context(start_method)
    if start_method == "forkserver":
        ctx.set_forkserver_preload(PRELOAD)
    with ctx.Pool(1, maxtasksperchild=1) as pool:
        return pool.apply(run_case, (impl, method, overrides, cpu))  # type: ignore[no-any-return]


# ---------------------------------------------------------------- reporting


def _rel(a: float, b: float) -> float:
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if math.isnan(a) or math.isnan(b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def make_row(n: int, impl: str, method: str, scenario: str, res: dict[str, Any]) -> dict[str, Any]:
    wall = res["wall_s"]
    sim = res["sim_s"]
    row: dict[str, Any] = {
        "n": n,
        "impl": impl,
        "method": method,
        "scenario": scenario,
        "sim_s": sim,
        "wall_s": wall,
        "wall_per_sim_s": wall / sim,
        "x_realtime": sim / wall,
        "events": res["events"],
        "events_per_s": res["events"] / wall,
        "peak_rss_mb": res["peak_rss_mb"],
        "ratio_vs_baseline": "",
        "max_rel_diff": "",
        "max_rel_diff_metric": "",
    }
    for name, unit in COMPARED:
        row[_col(name, unit)] = res["metrics"].get(name, math.nan)
    return row


def _fmt(x: Any, spec: str) -> str:
    if x == "" or x is None:
        return "-"
    return format(x, spec)


def speed_table(rows: list[dict[str, Any]], methods: list[str]) -> str:
    """One line per N: engine per method, engine none (restricted), baseline, ratio."""
    by_n: dict[int, dict[tuple[str, str, str], dict[str, Any]]] = {}
    for r in rows:
        by_n.setdefault(r["n"], {})[r["impl"], r["method"], r["scenario"]] = r
    head = ["N"]
    for m in methods:
        head += [f"eng[{m}] s/s", "xRT", "ev/s", "RSS MB"]
    head += ["eng[none*] s/s", "xRT", "ev/s", "RSS MB"]
    head += ["base[none*] s/s", "xRT", "ev/s", "RSS MB", "sim s", "ratio"]
    lines = [head]
    for n, cases in sorted(by_n.items()):
        line = [str(n)]
        keys = [("engine", m, "full") for m in methods] + [("engine", "none", "restricted")]
        keys.append(("baseline", "none", "restricted"))
        for key in keys:
            c = cases.get(key)
            if c is None:
                line += ["-"] * 4
            else:
                line += [
                    _fmt(c["wall_per_sim_s"], ".3f"),
                    _fmt(c["x_realtime"], ".2f"),
                    _fmt(c["events_per_s"], ",.0f"),
                    _fmt(c["peak_rss_mb"], ".0f"),
                ]
        bl = cases.get(("baseline", "none", "restricted"))
        line += [
            _fmt(bl["sim_s"], "g") if bl else "-",
            _fmt(bl["ratio_vs_baseline"], ".2f") + "x" if bl else "-",
        ]
        lines.append(line)
    return _align(lines)


def metric_table(rows: list[dict[str, Any]]) -> str:
    """One line per N: engine (method none) vs baseline on the restricted scenario."""
    by_n: dict[int, dict[str, dict[str, Any]]] = {}
    for r in rows:
        if r["scenario"] == "restricted":
            by_n.setdefault(r["n"], {})[r["impl"]] = r
    show = (
        "latency_state_mean",
        "latency_state_p99",
        "aoi_mean",
        "trigger_rate_hz",
        "throughput_mbps",
    )
    head = ["N"]
    for name in show:
        head += [f"{name} eng", "base"]
    head += ["max rel diff (all)", "in"]
    lines = [head]
    for n, c in sorted(by_n.items()):
        e, b = c.get("engine"), c.get("baseline")
        if e is None or b is None:
            continue
        line = [str(n)]
        for name in show:
            col = _col(name, dict(COMPARED)[name])
            line += [f"{e[col]:.6f}", f"{b[col]:.6f}"]
        line += [f"{b['max_rel_diff']:.1e}", b["max_rel_diff_metric"]]
        lines.append(line)
    return _align(lines)


def _align(lines: list[list[str]]) -> str:
    w = [max(len(r[i]) for r in lines) for i in range(len(lines[0]))]
    return "\n".join("  ".join(c.rjust(w[i]) for i, c in enumerate(r)) for r in lines)


def _machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=HERE,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    import simpy

    return (
        f"{cpu}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, "
        f"SimPy {simpy.__version__}; commit {commit or '?'}"
    )


# ---------------------------------------------------------------- main


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", default="10,100,200,1000", help="comma-separated node counts")
    p.add_argument("--duration", type=float, default=5.0, help="simulated seconds per case")
    p.add_argument("--methods", default="bides", help="engine methods to time on the full scenario")
    p.add_argument(
        "--baseline",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also run the process-per-message SimPy baseline (and the engine twin)",
    )
    p.add_argument(
        "--baseline-cap",
        type=float,
        default=2.0,
        help="at N >= --large-n the baseline and its engine twin simulate min(duration, this)",
    )
    p.add_argument("--large-n", type=int, default=1000, help="see --baseline-cap")
    p.add_argument("--quick", action="store_true", help="tiny run: N = 10,50, 1 s (for tests)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override applied to every case (repeatable)",
    )
    p.add_argument("--cpu", type=int, default=None, help="pin every case to this CPU")
    p.add_argument(
        "--start-method",
        choices=("forkserver", "spawn"),
        default="forkserver",
        help="how each case's fresh process is started (default: forkserver)",
    )
    p.add_argument("--out", type=Path, default=None, help="write the rows to this CSV file")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration = "10,50", 1.0
    a.node_list = [int(x) for x in str(a.nodes).split(",") if x.strip()]
    a.method_list = [m.strip() for m in a.methods.split(",") if m.strip()]
    return a


def main(argv: list[str] | None = None) -> int:
    a = parse_args(argv)
    for var in _THREAD_VARS:  # one core per case: no BLAS/numba worker threads
        os.environ.setdefault(var, "1")
    print(f"sigma_des engine benchmark  ({_machine()})")
    print(
        f"scenario: defaults + {NODES_PER_HOST} nodes/host, duration {a.duration:g} s "
        f"(warm-up {min(1.0, 0.2 * a.duration):g} s); overrides: {a.set or 'none'}"
    )
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    if a.baseline:
        from baseline_process_model import Unsupported, check_supported

        from sigma_des.config import load

        try:
            check_supported(load(overrides=overrides_for(10, a.duration, True, a.set)))
        except Unsupported as err:
            notes.append(f"no baseline: {err}")
            a.baseline = False
    for n in a.node_list:
        for m in a.method_list:
            res = run_fresh(
                "engine", m, overrides_for(n, a.duration, False, a.set), a.cpu, a.start_method
            )
            rows.append(make_row(n, "engine", m, "full", res))
            print(f"  N={n:<5} engine {m:<8} full        {res['wall_s']:8.2f} s wall", flush=True)
        if not a.baseline:
            continue
        dur = a.duration
        if n >= a.large_n and a.baseline_cap < dur:
            dur = a.baseline_cap
            notes.append(
                f"N={n}: the baseline and its engine twin simulate {dur:g} s instead of "
                f"{a.duration:g} s (--baseline-cap; the baseline would take minutes)"
            )
        ov = overrides_for(n, dur, True, a.set)
        e = make_row(
            n,
            "engine",
            "none",
            "restricted",
            run_fresh("engine", "none", ov, a.cpu, a.start_method),
        )
        print(f"  N={n:<5} engine none     restricted  {e['wall_s']:8.2f} s wall", flush=True)
        b = make_row(
            n,
            "baseline",
            "none",
            "restricted",
            run_fresh("baseline", "none", ov, a.cpu, a.start_method),
        )
        print(f"  N={n:<5} baseline none   restricted  {b['wall_s']:8.2f} s wall", flush=True)
        b["ratio_vs_baseline"] = b["wall_per_sim_s"] / e["wall_per_sim_s"]
        e["ratio_vs_baseline"] = b["ratio_vs_baseline"]
        diffs = {nm: _rel(e[_col(nm, u)], b[_col(nm, u)]) for nm, u in COMPARED}
        worst = max(diffs, key=lambda nm: diffs[nm])
        b["max_rel_diff"], b["max_rel_diff_metric"] = diffs[worst], worst
        rows += [e, b]
        for r in rows:
            if r["n"] == n and r["impl"] == "engine" and r["scenario"] == "full":
                r["ratio_vs_baseline"] = b["wall_per_sim_s"] / r["wall_per_sim_s"]
    print()
    print(
        "Speed (s/s = wall seconds per simulated second, xRT = times real time, "
        "ev/s = events per wall second;"
    )
    print(
        "none* = method none on the restricted scenario, identical for engine and baseline; "
        "ratio = engine speed / baseline speed on it)"
    )
    print(speed_table(rows, a.method_list))
    if a.baseline:
        print()
        print(
            "Metrics, engine vs baseline (method none, restricted scenario, same seed;"
            " ms, Hz, Mbps)"
        )
        print(metric_table(rows))
    for note in notes:
        print("note:", note)
    if a.out is not None:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        with a.out.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS)
            w.writeheader()
            for r in rows:
                w.writerow(r)
        print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
