"""Agent-steps per second of the vectorised swarm env, per method, and memory per scene.

The formation task with 11 nodes (a scripted leader and 10 learning agents), the
env's default scenario otherwise (point mass, 50 Hz triggers, 20 Hz alignment, a
decision every 2nd tick = 5 physics frames per decision, datagram QoS 0, cohort
engine), for 1, 10 and 500 scenes and each alignment method. An agent-step is one
agent's decision: ``scenes x 10`` per env step. Times are the thread's CPU time
(``time.thread_time``, one core), the best of ``--reps`` batches of ``--steps``
steps after a reset (reset excluded). ``--variant const`` also runs every case with
a constant compute time (no per-frame random draws). Memory per scene: Python heap
allocated by ``reset`` (tracemalloc) of a batch of ``--mem-scenes`` scenes / scenes.
For reference, the same scenario run on its own by the simulator (no env; the
built-in ``follow`` behaviour sends the commands): CPU ms per decision period.

``--study``: instead, the delay study's configuration (``tight`` task, 5 nodes = 4
agents, BiDES at 200 ms with 10 % loss, and ``perfect``; the study's env arguments, so
without simulator metrics, ``metrics=False``; ``--with-metrics``: the env's default,
with them), 4 and 64 scenes, random actions, against the targets (>= 50 000
agent-steps per CPU-s at 64 scenes, >= 20 000 at 4); memory: the process's resident
set (``VmRSS``) grown by building and resetting ``--fit`` scenes (default 512), per
scene and in all (target: 512 scenes in 2 GB). For normalisation across machines it
also prints the CPU seconds per simulated second of the in-repo process-per-message
SimPy baseline (``sigma_lab.reference.process_model``) on a fixed scenario (50 nodes,
stream transport, method ``none``, 2 s), run in the same
process: divide an env figure by it to compare machines.

Usage: ``python experiments/bench_env.py [--quick] [--study] [--out out/env]``
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
import tracemalloc
from pathlib import Path
from typing import Any

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from sigma_des import __version__  # noqa: E402
from sigma_des.config import METHODS  # noqa: E402
from sigma_des.env import SwarmVec  # noqa: E402

AGENTS = 10
#: Issue 27's target: agent-steps per second at 500 scenes x 10 agents on one core.
TARGET_500 = 50_000
VARIANTS = {"default": {}, "const": {"compute.step_time": 0.002}}


def make(method: str, scenes: int, variant: str) -> SwarmVec:
    """The benchmarked env."""
    scenario = {"nodes": AGENTS + 1, **VARIANTS[variant]}
    return SwarmVec(method=method, n_scenes=scenes, scenario=scenario, max_steps=10_000)


def speed(method: str, scenes: int, variant: str, steps: int, reps: int) -> dict[str, Any]:
    """Agent-steps/s (CPU time, best batch) of one case."""
    env = make(method, scenes, variant)
    env.reset(seed=1)
    actions = np.zeros((scenes, AGENTS, 3))
    actions[..., 0] = 0.5  # fly north at 10 m/s: the leader's start
    best = float("inf")
    for _ in range(reps):
        t = time.thread_time()
        for _ in range(steps):
            env.step(actions)
        best = min(best, time.thread_time() - t)
    return {"method": method, "scenes": scenes, "variant": variant, "steps": steps,
            "agent_steps_per_s": scenes * AGENTS * steps / best,
            "ms_per_scene_step": best / (scenes * steps) * 1e3}


def plain(method: str, decisions: int) -> dict[str, Any]:
    """The same scenario run on its own (behaviour ``follow``, no env): ms per decision."""
    from dataclasses import replace

    from sigma_des.events.cohort import make_run
    from sigma_des.factory import make_behaviour, make_dynamics

    env = make(method, 1, "default")
    period = env.sc.commands.every / env.sc.f_align
    sc = replace(env.sc, duration=decisions * period,
                 commands=replace(env.sc.commands, behaviour="follow"))
    run, _ = make_run(sc.run_spec(), method, make_dynamics(sc), make_behaviour(sc))
    t = time.thread_time()
    run.run()
    dt = time.thread_time() - t
    return {"method": method, "decisions": decisions, "ms_per_decision": dt / decisions * 1e3}


def memory(method: str, scenes: int) -> float:
    """Python heap bytes per scene allocated by ``reset`` (tracemalloc)."""
    env = make(method, scenes, "default")
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    env.reset(seed=1)
    after = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    return (after - before) / scenes


STUDY_TARGETS = {4: 20_000, 64: 50_000}


def _rss() -> int:
    """Resident set of this process (bytes, ``/proc/self/status``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def baseline_cpu_per_sim_s(duration: float = 2.0) -> float:
    """CPU seconds (this thread) per simulated second of the SimPy baseline (module doc),
    after an untimed short run (first imports)."""
    from sigma_lab.reference.process_model import ProcessModel

    from sigma_des.config import load

    def scenario(d: float) -> Any:
        return load(None, ["nodes=50", "net.transport=\"stream\"", "fidelity.enabled=false",
                           "commands.enabled=false", f"duration={d}", f"warmup={d / 4}"])

    ProcessModel(scenario(0.2)).run()  # imports and caches first, untimed
    t = time.thread_time()
    ProcessModel(scenario(duration)).run()
    return (time.thread_time() - t) / duration


def study(sizes: tuple[int, ...], steps: int, reps: int, fit: int,
          metrics: bool = False) -> dict[str, Any]:
    """Agent-steps per CPU-s on the delay study's configuration, and memory per scene
    (``metrics``: the scenes' runs collect the simulator's metrics, the env's default)."""
    import gc

    from sigma_lab.studies.delay import env_kwargs

    base = baseline_cpu_per_sim_s()
    print(f"SimPy baseline (50 nodes, stream, none): {base:.3f} CPU-s per simulated second; "
          f"load {os.getloadavg()[0]:.1f}", flush=True)
    rows = []
    for cond in ("bides@200ms", "perfect"):
        kw = {**env_kwargs(cond, 5, 10_000, 0.1), "metrics": metrics}
        for scenes in sizes:
            env = SwarmVec(n_scenes=scenes, **kw)
            env.reset(seed=1)
            acts = np.random.default_rng(0).uniform(-1, 1, (steps, scenes, env.n_agents, 3))
            best = float("inf")
            for _ in range(reps):
                t = time.thread_time()
                for k in range(steps):
                    env.step(acts[k])
                best = min(best, time.thread_time() - t)
            r = {"condition": cond, "scenes": scenes, "steps": steps, "metrics": metrics,
                 "agent_steps_per_s": scenes * env.n_agents * steps / best}
            rows.append(r)
            goal = STUDY_TARGETS.get(scenes)
            met = "" if goal is None else (
                f"  target >= {goal:,}: {'met' if r['agent_steps_per_s'] >= goal else 'not met'}")
            print(f"study {cond:12s} {scenes:4d} scenes{' (metrics)' if metrics else ''}: "
                  f"{r['agent_steps_per_s']:9.0f} "
                  f"agent-steps per CPU-s{met}; load {os.getloadavg()[0]:.1f}", flush=True)
            del env
            gc.collect()
    gc.collect()
    before = _rss()
    env = SwarmVec(n_scenes=fit, **{**env_kwargs("bides@200ms", 5, 50, 0.1),
                                    "metrics": metrics})
    env.reset(seed=1)
    env.step(np.zeros((fit, env.n_agents, 3)))
    grown = _rss() - before
    print(f"memory: {fit} scenes (bides@200ms) grew the resident set by {grown / 2**20:.1f} MiB "
          f"= {grown / fit / 1024:.1f} KiB per scene; in 2 GiB: "
          f"{'yes' if grown < 2 * 2**30 else 'no'}", flush=True)
    return {"rows": rows, "baseline_cpu_per_sim_s": base, "fit_scenes": fit,
            "rss_grown_bytes": grown,
            "rss_bytes_per_scene": grown / fit, "fits_2gib": grown < 2 * 2**30}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print the table, write CSV and JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 and 2 scenes, few steps")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--mem-scenes", type=int, default=50)
    ap.add_argument("--variant", choices=["default", "const", "both"], default="both")
    ap.add_argument("--study", action="store_true",
                    help="the delay study's configuration (see the module docstring)")
    ap.add_argument("--fit", type=int, default=512, help="--study: scenes of the memory check")
    ap.add_argument("--with-metrics", action="store_true",
                    help="--study: the scenes' runs collect the simulator's metrics")
    ap.add_argument("--out", default="out/env")
    args = ap.parse_args(argv)
    if args.study:
        res = study((1, 2) if args.quick else (4, 64), 2 if args.quick else args.steps,
                    1 if args.quick else args.reps, 4 if args.quick else args.fit,
                    args.with_metrics)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "bench_study.json").write_text(json.dumps(
            {"version": __version__, **res, "quick": args.quick}, indent=2) + "\n")
        return 0
    sizes = (1, 2) if args.quick else (1, 10, 500)
    steps = 2 if args.quick else args.steps
    reps = 1 if args.quick else args.reps
    mem_scenes = 2 if args.quick else args.mem_scenes
    variants = ["default", "const"] if args.variant == "both" else [args.variant]
    make("none", 1, "default").reset(seed=1)  # compile/warm the kernels outside the timing
    rows = []
    for variant in variants:
        for scenes in sizes:
            for method in METHODS:
                r = speed(method, scenes, variant, steps if scenes < 500 else max(2, steps // 2),
                          reps)
                rows.append(r)
                goal = ""
                if scenes == 500:
                    met = "met" if r["agent_steps_per_s"] >= TARGET_500 else "not met"
                    goal = f"  target >= {TARGET_500:,}: {met}; load {os.getloadavg()[0]:.1f}"
                print(f"{variant:8s} {method:9s} {scenes:4d} scenes: "
                      f"{r['agent_steps_per_s']:9.0f} agent-steps/s "
                      f"({r['ms_per_scene_step']:.3f} ms per scene-step){goal}", flush=True)
    plains = [plain(m, 20 if args.quick else 500) for m in METHODS]
    for p in plains:
        print(f"plain run {p['method']:9s}: {p['ms_per_decision']:.3f} ms per decision period "
              "(the simulator alone, same scenario, built-in behaviour)", flush=True)
    mem = {m: memory(m, mem_scenes) for m in METHODS}
    for m, b in mem.items():
        print(f"memory per scene ({m}): {b / 1024:.1f} KiB", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "bench.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*rows[0], "version"])
        w.writeheader()
        for r in rows:
            w.writerow({**r, "version": __version__})
    (out / "bench.json").write_text(json.dumps(
        {"version": __version__, "agents": AGENTS, "rows": rows, "plain": plains,
         "memory_bytes_per_scene": mem, "mem_scenes": mem_scenes, "quick": args.quick},
        indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
