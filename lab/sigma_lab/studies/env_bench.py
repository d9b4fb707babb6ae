"""The learning env's speed and memory, measured (``experiments/bench_env.py`` is the command).

:func:`speed`, :func:`plain` and :func:`memory` measure the formation task's env per
method (agent-steps per CPU-s of this thread, the same scenario run by the simulator
alone, Python heap per scene); :func:`study` measures the delay study's configuration
against its targets, with the in-repo SimPy baseline's CPU per simulated second for
comparisons across machines (:func:`baseline_cpu_per_sim_s`). Timings are CPU time of
the calling thread; the functions print their figures as they go.
"""

from __future__ import annotations

import os
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.env import SwarmVec

__all__ = ["AGENTS", "PPO_TARGET_MIN", "STUDY_TARGETS", "TARGET_500", "VARIANTS",
           "baseline_cpu_per_sim_s", "make", "memory", "plain", "ppo", "speed", "study"]

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
    from sigma_des.config import load
    from sigma_lab.reference.process_model import ProcessModel

    def scenario(d: float) -> Any:
        return load(None, ["nodes=50", "net.transport=\"stream\"", "fidelity.enabled=false",
                           "commands.enabled=false", f"duration={d}", f"warmup={d / 4}"])

    ProcessModel(scenario(0.2)).run()  # imports and caches first, untimed
    t = time.thread_time()
    ProcessModel(scenario(duration)).run()
    return (time.thread_time() - t) / duration


#: The study's PPO budget per policy and its wall-time target (minutes, 2 cores).
PPO_POLICY_STEPS, PPO_TARGET_MIN = 2_000_000, 15.0

#: The study's training episodes: at most this many env steps (``train_under_delay --full``).
STUDY_EPISODE = 50


def study(sizes: tuple[int, ...], steps: int, reps: int, fit: int,
          metrics: bool = False, warm: int = 60, steady: int = 100) -> dict[str, Any]:
    """Agent-steps per CPU-s on the delay study's configuration, and memory per scene
    (``metrics``: the scenes' runs collect the simulator's metrics, the env's default).

    Two figures per case. The headline, *steady*: the study's training episodes (at most
    :data:`STUDY_EPISODE` steps, random actions, so most end earlier by a failure), timed
    over ``steady`` steps after ``warm`` steps, so the episodes' restarts are in it
    at their real rate. *Within episodes*: the best of ``reps`` batches of ``steps`` steps
    right after a reset with episodes too long to end, restarts excluded (the
    measurement of earlier versions).
    """
    import gc

    from sigma_lab.studies.delay import env_kwargs

    base = baseline_cpu_per_sim_s()
    print(f"SimPy baseline (50 nodes, stream, none): {base:.3f} CPU-s per simulated second; "
          f"load {os.getloadavg()[0]:.1f}", flush=True)
    rows = []
    for cond in ("bides@200ms", "perfect"):
        for scenes in sizes:
            rate, restarts = _steady(cond, scenes, warm, steady, metrics)
            inner = _within(cond, scenes, steps, reps, metrics)
            r = {"condition": cond, "scenes": scenes, "steps": steady, "metrics": metrics,
                 "agent_steps_per_s": rate, "restarts_per_scene_step": restarts,
                 "within_episode_agent_steps_per_s": inner}
            rows.append(r)
            goal = STUDY_TARGETS.get(scenes)
            met = "" if goal is None else (
                f"  target >= {goal:,}: {'met' if rate >= goal else 'not met'}")
            print(f"study {cond:12s} {scenes:4d} scenes{' (metrics)' if metrics else ''}: "
                  f"{rate:9.0f} agent-steps per CPU-s, steady ({restarts:.3f} restarts a "
                  f"scene-step); {inner:9.0f} within episodes{met}; "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
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
            "episode_steps": STUDY_EPISODE, "warm_steps": warm,
            "rss_grown_bytes": grown,
            "rss_bytes_per_scene": grown / fit, "fits_2gib": grown < 2 * 2**30}


def _steady(cond: str, scenes: int, warm: int, steps: int, metrics: bool
            ) -> tuple[float, float]:
    """Agent-steps per CPU-s over ``steps`` steps after ``warm`` of the study's training
    episodes, and the episode restarts per scene-step in that window."""
    from sigma_lab.studies.delay import env_kwargs

    env = SwarmVec(n_scenes=scenes, **{**env_kwargs(cond, 5, STUDY_EPISODE, 0.1),
                                       "metrics": metrics})
    env.reset(seed=1)
    acts = np.random.default_rng(0).uniform(-1, 1, (warm + steps, scenes, env.n_agents, 3))
    for k in range(warm):
        env.step(acts[k])
    episodes = sum(env.batch.episode)
    t = time.thread_time()
    for k in range(warm, warm + steps):
        env.step(acts[k])
    dt = time.thread_time() - t
    return scenes * env.n_agents * steps / dt, (sum(env.batch.episode) - episodes) / (
        scenes * steps)


def _within(cond: str, scenes: int, steps: int, reps: int, metrics: bool) -> float:
    """The best of ``reps`` batches of ``steps`` steps after a reset, episodes too long to
    end (restarts excluded)."""
    from sigma_lab.studies.delay import env_kwargs

    env = SwarmVec(n_scenes=scenes, **{**env_kwargs(cond, 5, 10_000, 0.1), "metrics": metrics})
    env.reset(seed=1)
    acts = np.random.default_rng(0).uniform(-1, 1, (steps, scenes, env.n_agents, 3))
    best = float("inf")
    for _ in range(reps):
        t = time.thread_time()
        for k in range(steps):
            env.step(acts[k])
        best = min(best, time.thread_time() - t)
    return scenes * env.n_agents * steps / best


def ppo(steps: int, scenes: int = 16, n_steps: int = 64, batch: int = 1024) -> dict[str, Any]:
    """Wall and CPU time of one PPO training (MLP policy) on the study's BiDES cell, with
    the study's settings (``train_under_delay --full``: 16 scenes, rollouts of 64 steps,
    minibatches of 1 024), ``steps`` agent-steps from scratch; projected to the study's
    2 x 10^6 agent-steps per policy. One training uses one core (PyTorch on one thread),
    as each of the study's ``--jobs 2`` does. Beside it, the env's own share: the same
    ``scenes`` stepped with random actions for as many steps (steady state), CPU."""
    from sigma_des.env.ppo import train
    from sigma_lab.studies.delay import env_kwargs

    kw = env_kwargs("bides@200ms", 5, STUDY_EPISODE, 0.1)
    wall, cpu = time.perf_counter(), time.process_time()
    _, curve = train(kw, steps, 0, policy="mlp", n_scenes=scenes, n_steps=n_steps,
                     batch_size=min(batch, scenes * 4 * n_steps))
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    done = int(curve[-1]["agent_steps"]) if curve else steps
    env_rate, _ = _steady("bides@200ms", scenes, 10, max(1, done // (scenes * 4)), False)
    minutes = PPO_POLICY_STEPS / done * wall / 60
    row = {"policy": "mlp", "scenes": scenes, "agent_steps": done, "wall_s": wall,
           "cpu_s": cpu, "agent_steps_per_wall_s": done / wall,
           "env_cpu_s": done / env_rate, "minutes_per_policy": minutes,
           "target_minutes": PPO_TARGET_MIN}
    print(f"PPO (mlp, {scenes} scenes, bides@200ms): {done:,} agent-steps in {wall:.1f} s wall, "
          f"{cpu:.1f} CPU-s ({done / wall:,.0f} agent-steps/s; the env's share "
          f"{row['env_cpu_s']:.1f} CPU-s); {PPO_POLICY_STEPS:,} agent-steps: "
          f"{minutes:.1f} min a policy, one core each  target <= {PPO_TARGET_MIN:.0f} min: "
          f"{'met' if minutes <= PPO_TARGET_MIN else 'not met'}; load {os.getloadavg()[0]:.1f}",
          flush=True)
    return row
