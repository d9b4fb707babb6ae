#!/usr/bin/env python
"""Where one method run spends its CPU time: a cProfile of the engine, CPU-clocked.

Builds the scenario (defaults + ``--set`` overrides, 20 nodes per host), runs a
two-node 0.5 s warm-up of the same kind untimed (imports, numba cache loading, the
compiled core's kernels such a run never reaches: ``MethodRun.load_kernels``), then
profiles one run of ``--method`` with ``time.process_time`` as the profiler clock
(so time the process spends descheduled on a shared machine is not counted) and
prints the CPU seconds per simulated second and the top functions by own time with
their share. Compiled (numba) kernels appear as single entries (``advance`` = the
cohort core's event loop, ``loop.py:by handle`` where the engine calls it by handle,
without numba's dispatch; ``step_kernel`` = the aircraft step).

``--phases`` first times, unprofiled, the whole path of ``sigma_des.api.compare`` for
that method, split into set-up (scenario, ``make_run``: truth rings, network, draw
tables, the core's layout), the simulated seconds, and result assembly (the
collector's metrics, the truth's release, fidelity against the cached ideal run, the
results table): CPU, user and system seconds, page faults (first touch of memory) and
numba specialisations loaded per phase; the profile then covers that whole path.

Usage::

    python experiments/profile_run.py --nodes 1000 --duration 3 --method bides
    python experiments/profile_run.py --nodes 1000 --duration 1 --phases  # fixed costs
    python experiments/profile_run.py --quick      # 10 nodes, 0.3 s (tests)
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import re
import resource
import sys
import time
from collections.abc import Callable
from typing import Any

from sigma_des.jitcache import loaded_specialisations

#: the message core's entry points the engine calls by handle, without numba's dispatch,
#: as the profiler names them (built-ins of ``fast/handle.py``): shown as the loop's
BY_HANDLE = re.compile(r"<built-in method sigma_des\.events\.fast\.handle\.(\w+)>")


def _usage() -> tuple[float, float, float, int, int]:
    """(CPU, user, system seconds, minor page faults, numba specialisations) so far."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return (time.process_time(), r.ru_utime, r.ru_stime, r.ru_minflt, loaded_specialisations())


class Phases:
    """CPU, user, system seconds, page faults and specialisations, per named phase."""

    def __init__(self) -> None:
        self.rows: dict[str, list[float]] = {}
        self._last = _usage()

    def mark(self, name: str) -> None:
        """Charge everything since the previous mark to ``name``."""
        now = _usage()
        row = self.rows.setdefault(name, [0.0] * 5)
        for i, (a, b) in enumerate(zip(self._last, now, strict=True)):
            row[i] += b - a
        self._last = _usage()  # the bookkeeping itself is charged to nobody

    def timed(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn``, with its calls charged to ``name`` (the rest to the enclosing phase)."""
        def call(*args: Any, **kw: Any) -> Any:
            self.mark("_outer")
            try:
                return fn(*args, **kw)
            finally:
                self.mark(name)
        return call

    def text(self, outer: str, duration: float) -> str:
        """The table: one row per phase, in running order, and the total."""
        rows = {k: v for k, v in self.rows.items() if not k.startswith("_")}
        inner = self.rows.get("_outer", [0.0] * 5)
        rows[outer] = [a + b for a, b in zip(rows.get(outer, [0.0] * 5), inner, strict=True)]
        order = ("set-up", "run", "results")
        lines = [f"{'phase':50s} {'CPU ms':>8s} {'user':>7s} {'sys':>6s} {'faults':>7s} "
                 f"{'kernels':>7s}"]
        for name in sorted(rows, key=lambda k: order.index(k.split(":")[0])):
            cpu, user, sys_, flt, k = rows[name]
            lines.append(f"{name:50s} {1e3 * cpu:8.1f} {1e3 * user:7.1f} {1e3 * sys_:6.1f} "
                         f"{flt:7.0f} {k:7.0f}")
        total = sum(r[0] for r in rows.values())
        lines.append(f"{'total':50s} {1e3 * total:8.1f}   = {total / duration:.3f} CPU s per "
                     "simulated s")
        return "\n".join(lines)


def whole_path(ov: list[str], method: str, ph: Phases | None = None) -> None:
    """``compare(sc, [method])``'s work for one method, phase by phase (``ph``: timed)."""
    from sigma_des.api import Results, ideal_run
    from sigma_des.config import load
    from sigma_des.events.cohort import make_run
    from sigma_des.factory import make_behaviour, make_dynamics
    from sigma_des.metrics.fidelity import add_fidelity
    from sigma_des.metrics.reports import MethodReport

    mark = ph.mark if ph is not None else (lambda name: None)
    mark("_idle")
    sc = load(overrides=ov)
    spec, dyn, beh = sc.run_spec(), make_dynamics(sc), make_behaviour(sc)
    mark("set-up: scenario, dynamics, behaviour")
    run, fallback = make_run(spec, method, dyn, beh)
    mark("set-up: make_run (rings, network, tables, layout)")
    if ph is not None:
        run.finish = ph.timed("results: collector (finish)", run.finish)  # type: ignore[method-assign]
        run.truth.release = ph.timed("results: truth release", run.truth.release)  # type: ignore[method-assign]
    out = run.run()
    mark("run: the simulated seconds")
    out["engine"] = {"requested": sc.engine, "used": "events" if fallback else sc.engine,
                     "fallback": fallback}
    if sc.fidelity.enabled:
        add_fidelity(out, *run.trajectory(), ideal_run(sc)[1], sc.fidelity)
    mark("results: fidelity (cached ideal run, DTW)")
    res = Results(sc)
    res.add(method, MethodReport.of(out))
    res.rows(), res.table(), res.summary()
    mark("results: tables (rows, table, summary)")


def phases(ov: list[str], sc: Any, method: str, duration: float) -> None:
    """Print the unprofiled phase table of :func:`whole_path` (after its warm-up)."""
    import os

    from sigma_des.api import ideal_run

    whole_path([*ov, "nodes=2", "hosts=1"], method)  # the fidelity kernels
    if sc.fidelity.enabled:
        ideal_run(sc)  # flown once, then read from the cache as every later run does
    ph = Phases()
    whole_path(ov, method, ph)
    print(f"N={sc.nodes} method={method} {duration:g} s simulated, phases "
          f"(unprofiled; load {os.getloadavg()[0]:.2f}):")
    print(ph.text("run: the simulated seconds", duration))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--nodes", type=int, default=1000)
    p.add_argument("--duration", type=float, default=3.0)
    p.add_argument("--method", default="bides")
    p.add_argument("--top", type=int, default=25, help="functions listed")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--phases", action="store_true",
                   help="time set-up / run / results first; profile the whole path")
    p.add_argument("--quick", action="store_true", help="10 nodes, 0.3 s (for tests)")
    a = p.parse_args(argv)
    if a.quick:
        a.nodes, a.duration = 10, 0.3
    from sigma_des.config import load
    from sigma_des.errors import ConfigError
    from sigma_des.events.cohort import make_run
    from sigma_des.factory import make_behaviour, make_dynamics

    ov = [f"nodes={a.nodes}", f"hosts={max(1, a.nodes // 20)}", f"duration={a.duration}",
          f"warmup={min(0.5, a.duration / 4)}", *a.set]
    try:
        sc = load(overrides=ov)
        warm = load(overrides=[*ov, "nodes=2", "hosts=1", "duration=0.5", "warmup=0.1"])
    except ConfigError as e:
        print(f"profile_run: error: {e}", file=sys.stderr)
        return 2
    run, _ = make_run(warm.run_spec(), a.method, make_dynamics(warm), make_behaviour(warm))
    run.load_kernels()
    run.run()
    if a.phases:
        phases(ov, sc, a.method, a.duration)
    run, fallback = make_run(sc.run_spec(), a.method, make_dynamics(sc), make_behaviour(sc))
    prof = cProfile.Profile(time.process_time)
    c = time.process_time()
    prof.enable()
    if a.phases:
        del run
        whole_path(ov, a.method)
    else:
        run.run()
    prof.disable()
    cpu = time.process_time() - c
    what = "whole path" if a.phases else "simulated"
    print(f"N={a.nodes} method={a.method} {a.duration:g} s {what}: {cpu:.3f} CPU s "
          f"(profiled), {cpu / a.duration:.3f} CPU s per simulated s; "
          f"engine {'events (' + fallback + ')' if fallback else 'cohort'}")
    st = pstats.Stats(prof)
    rows = sorted(st.stats.items(), key=lambda kv: -kv[1][2])  # type: ignore[attr-defined]
    total = sum(v[2] for _k, v in rows) or 1.0
    print(f"{'own s':>8s} {'share':>6s} {'calls':>8s}  function")
    for (file, line, fn), (_cc, nc, tt, _ct, _callers) in rows[: a.top]:
        where = file.rsplit("/", 2)[-1] if "/" in file else file
        entry = BY_HANDLE.fullmatch(fn)
        if entry is not None:  # the loop's entry point, called by handle
            fn, where, line = entry[1], "loop.py", "by handle"
        print(f"{tt:8.3f} {100 * tt / total:5.1f}% {nc:8d}  {fn} ({where}:{line})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
