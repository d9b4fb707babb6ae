"""Does training on the aligned, delayed view beat training with perfect information, under delay?

Task ``tight`` (fast manoeuvring leader, 6 m slots, observations with per-neighbour
age and velocity; ``sigma_des.env.tasks.TightTask``). Training conditions, equal
budgets, seeds ``0..seeds-1`` each:

* ``perfect``: the true current state over an ideal network (what peer envs give);
* ``delay`` cells: host links with latency normal(L, L/5) and Bernoulli loss
  (``--loss``), for every delay level L (``--delays``) and alignment method
  (``--methods``); agents observe that method's aligned view.

Learner: ``cem`` (zero-dependency cross-entropy method over a shared linear policy,
``sigma_des.env.learn``) or ``ppo`` (Stable-Baselines3 PPO, ``MlpPolicy``; the
``learn`` extra). Every trained policy, the untrained (zero) policy and the two
hand-written controllers (``sigma_des.env.controllers``) are evaluated on the same
held-out episodes (root seed ``--eval-seed``) of every delay cell and of ``perfect``.
Per delay cell: mean ± 95 % CI over seeds (t distribution) and a paired one-sided
test over seeds of "delay-trained beats perfect-trained under that delay" (paired t
test and Wilcoxon signed-rank, ``scipy.stats``).

Outputs (``--out``): ``history.csv`` (learning curves), ``eval.csv`` (per policy and
evaluation condition), ``stats.csv`` (per delay cell), ``summary.json``,
``learning_curves.png``, ``eval.png``.

Usage: ``python experiments/train_under_delay.py [--quick] [--learner cem|ppo]
[--seeds 5] [--out out/env/delay_study]``
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des import __version__
from sigma_des.env.controllers import extrapolating, naive
from sigma_des.env.learn import CEMConfig, act, score, train
from sigma_des.env.tasks import TightTask, make_task
from sigma_des.studies import plot_setup, save
from sigma_des.studies.delay import cells, ci95, env_kwargs, paired_cells

Policy = Callable[[np.ndarray], np.ndarray]


def _train_one(a: argparse.Namespace, cond: str, seed: int, history: list[dict[str, Any]]
               ) -> tuple[Policy, float, float]:
    """Train one policy; returns it, its wall time (s) and the agent-steps it used."""
    kw = env_kwargs(cond, a.nodes, a.max_steps, a.loss)
    t0 = time.perf_counter()
    agents = a.nodes - 1
    if a.learner == "cem":
        cfg = CEMConfig(population=a.population, elite=max(1, a.population // 4),
                        iterations=a.iterations, episodes=a.episodes, seed=seed)
        per_it = a.population * a.episodes * a.max_steps * agents
        theta, hist = train(kw, cfg)
        for r in hist:
            history.append({"learner": "cem", "trained": cond, "seed": seed,
                            "agent_steps": (r["iteration"] + 1) * per_it,
                            "fitness": r["elite_fitness"]})
        used = float(a.iterations * per_it)

        def policy(obs: np.ndarray, th: np.ndarray = theta) -> np.ndarray:
            return act(np.broadcast_to(th, (obs.shape[0],) + th.shape), obs)
    else:
        from sigma_des.env.sb3 import train_ppo

        policy, hist = train_ppo(kw, a.ppo_steps, seed, n_scenes=a.ppo_scenes,
                                 n_steps=a.ppo_n_steps, batch_size=a.ppo_batch)
        history += [{"learner": "ppo", "trained": cond, "seed": seed, **r} for r in hist]
        used = hist[-1]["agent_steps"] if hist else float(a.ppo_steps)
    return policy, time.perf_counter() - t0, used


def _parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny scale (CEM, seconds)")
    ap.add_argument("--learner", choices=("cem", "ppo"), default="cem")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--delays", default="0.05,0.2", help="mean host-link latencies (s)")
    ap.add_argument("--methods", default="bides,none")
    ap.add_argument("--loss", type=float, default=0.1)
    ap.add_argument("--nodes", type=int, default=5)
    ap.add_argument("--max-steps", type=int, default=50)
    ap.add_argument("--eval-episodes", type=int, default=32)
    ap.add_argument("--eval-seed", type=int, default=10_000)
    ap.add_argument("--iterations", type=int, default=10, help="CEM")
    ap.add_argument("--population", type=int, default=8, help="CEM")
    ap.add_argument("--episodes", type=int, default=2, help="CEM: episodes per candidate")
    ap.add_argument("--ppo-steps", type=int, default=20_000, help="PPO agent-steps")
    ap.add_argument("--ppo-scenes", type=int, default=4)
    ap.add_argument("--ppo-n-steps", type=int, default=128)
    ap.add_argument("--ppo-batch", type=int, default=256)
    ap.add_argument("--seed-list", default=None,
                    help="train these seeds (comma list) instead of 0..seeds-1: a shard")
    ap.add_argument("--skip-baselines", action="store_true",
                    help="do not evaluate the untrained and hand-written policies (a shard)")
    ap.add_argument("--merge", nargs="+", default=None, metavar="DIR",
                    help="merge the outputs of shards (same settings) into --out; no training")
    ap.add_argument("--out", default="out/env/delay_study")
    a = ap.parse_args(argv)
    if a.quick:
        a.learner, a.seeds, a.delays, a.methods = "cem", 2, "0.2", "bides"
        a.nodes, a.max_steps, a.eval_episodes = 3, 10, 2
        a.iterations, a.population, a.episodes = 2, 4, 1
    for key in ("seeds", "nodes", "max_steps", "eval_episodes", "iterations", "population",
                "episodes", "ppo_steps", "ppo_scenes"):
        if getattr(a, key) < 1 or (key == "nodes" and a.nodes < 2):
            ap.error(f"--{key.replace('_', '-')}: must be >= {2 if key == 'nodes' else 1}, "
                     f"got {getattr(a, key)}")
    if not 0 <= a.loss < 1:
        ap.error(f"--loss: must be in [0, 1), got {a.loss}")
    a.seed_ids = (list(range(a.seeds)) if a.seed_list is None
                  else [int(x) for x in a.seed_list.split(",")])
    a.delay_list = [float(x) for x in a.delays.split(",")]
    a.method_list = a.methods.split(",")
    return a


def main(argv: list[str] | None = None) -> int:
    """Train every condition and seed, evaluate everything everywhere, write the outputs."""
    a = _parse(argv)
    conds = cells(a.delay_list, a.method_list)
    if a.merge:
        return merge(a)
    seeds = a.seed_ids
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    task = make_task("tight")
    assert isinstance(task, TightTask)
    baselines: dict[str, Policy] = {
        "untrained": lambda o: np.zeros(o.shape[:-1] + (3,)),
        "naive": lambda o: naive(o, task), "extrapolating": lambda o: extrapolating(o, task)}
    history: list[dict[str, Any]] = []
    evals: list[dict[str, Any]] = []
    cost: list[dict[str, Any]] = []
    t_start = time.perf_counter()

    def evaluate(name: str, seed: int, policy: Policy, where: list[str]) -> None:
        for cond in where:
            t0 = time.perf_counter()
            r = score(policy, env_kwargs(cond, a.nodes, a.max_steps, a.loss),
                      a.eval_episodes, a.eval_seed)
            evals.append({"trained": name, "seed": seed, "evaluated": cond,
                          **{k: float(v.mean()) for k, v in r.items()},
                          "eval_wall_s": time.perf_counter() - t0})

    for name, pol in baselines.items() if not a.skip_baselines else ():
        evaluate(name, -1, pol, conds)
    for k, seed in enumerate(seeds):
        for cond in conds:
            pol, wall, used = _train_one(a, cond, seed, history)
            cost.append({"trained": cond, "seed": seed, "train_wall_s": wall,
                         "agent_steps": used, "agent_steps_per_s": used / wall})
            evaluate(cond, seed, pol, conds if cond == "perfect" else ["perfect", cond])
            own = next(e for e in evals[::-1] if (e["trained"], e["seed"], e["evaluated"])
                       == (cond, seed, cond))
            print(f"[{time.perf_counter() - t_start:7.0f} s] seed {seed} {cond:14s} trained "
                  f"({wall:.0f} s, {used / wall:,.0f} agent-steps/s); evaluated under it: "
                  f"{own['fitness']:.3f}", flush=True)
        # outputs after every seed: an interrupted study keeps its finished seeds
        table = paired_cells(evals, conds, seeds[: k + 1])
        _write(out, a, history, evals, cost, table, time.perf_counter() - t_start,
               seeds[: k + 1])
    for r in table:
        print(f"{r['cell']:14s} delay-trained {r['delay_trained_mean']:.3f} ± "
              f"{r['delay_trained_ci95']:.3f}  perfect-trained {r['perfect_trained_mean']:.3f} "
              f"± {r['perfect_trained_ci95']:.3f}  paired t p={r['t_p_greater']:.3g} "
              f"wilcoxon p={r['wilcoxon_p_greater']:.3g}", flush=True)
    return 0


def merge(a: argparse.Namespace) -> int:
    """Combine shards (``--merge``): their seeds, evaluations, curves; statistics anew."""
    keep = ("learner", "delays", "methods", "loss", "nodes", "max_steps", "eval_episodes",
            "eval_seed", "iterations", "population", "episodes", "ppo_steps", "ppo_scenes",
            "ppo_n_steps", "ppo_batch")
    parts = [json.loads((Path(d) / "summary.json").read_text()) for d in a.merge]
    first = parts[0]["args"]
    for d, p in zip(a.merge, parts, strict=True):
        bad = [k for k in keep if p["args"][k] != first[k]]
        if bad:
            raise SystemExit(f"--merge: {d} differs from {a.merge[0]} in {bad}")
    for k in keep:
        setattr(a, k, first[k])
    a.delay_list = [float(x) for x in a.delays.split(",")]
    a.method_list = a.methods.split(",")
    done = sorted({s for p in parts for s in p["seeds_done"]})
    if sum(len(p["seeds_done"]) for p in parts) != len(done):
        raise SystemExit("--merge: the shards share a seed")
    evals, history, cost = [], [], []
    for d, p in zip(a.merge, parts, strict=True):
        ok = set(p["seeds_done"]) | {-1}
        evals += [e for e in p["eval"] if e["seed"] in ok and not (
            e["seed"] == -1 and any(x["seed"] == -1 for x in evals))]
        cost += [c for c in p["cost"] if c["seed"] in ok]
        with (Path(d) / "history.csv").open() as fh:
            history += [{**r, "seed": int(r["seed"]), "agent_steps": float(r["agent_steps"]),
                         "fitness": float(r["fitness"])} for r in csv.DictReader(fh)
                        if int(r["seed"]) in ok]
    a.seeds, a.seed_ids, a.merged_from = len(done), done, list(a.merge)
    history = [{k: v for k, v in r.items() if k not in ("version", "learner")}
               | {"learner": a.learner} for r in history]
    table = paired_cells(evals, cells(a.delay_list, a.method_list), done)
    Path(a.out).mkdir(parents=True, exist_ok=True)
    _write(Path(a.out), a, history, evals, cost, table,
           sum(p["wall_s"] for p in parts), done)
    return 0


def _csv(path: Path, rows: list[dict[str, Any]], extra: dict[str, Any]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(dict.fromkeys([*rows[0], *extra])))
        w.writeheader()
        for r in rows:
            w.writerow({**r, **extra})


def _write(out: Path, a: argparse.Namespace, history: list[dict[str, Any]],
           evals: list[dict[str, Any]], cost: list[dict[str, Any]],
           table: list[dict[str, Any]], wall: float, done: list[int]) -> None:
    tag = {"version": __version__, "learner": a.learner}
    _csv(out / "history.csv", history, tag)
    _csv(out / "eval.csv", evals, tag)
    if table:
        _csv(out / "stats.csv", table, tag)
    args = {k: v for k, v in vars(a).items()}
    (out / "summary.json").write_text(json.dumps({
        "version": __version__, "args": args, "cells": cells(a.delay_list, a.method_list),
        "seeds_done": done,
        "stats": table, "eval": evals, "cost": cost, "wall_s": wall}, indent=2) + "\n")
    _plots(out, a, history, table, len(done))


def _plots(out: Path, a: argparse.Namespace, history: list[dict[str, Any]],
           table: list[dict[str, Any]], n_seeds: int) -> None:
    plt = plot_setup(fast=a.quick)
    conds = cells(a.delay_list, a.method_list)
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, cond in enumerate(conds):
        rows = [r for r in history if r["trained"] == cond]
        xs = sorted({r["agent_steps"] for r in rows})
        m, h = [], []
        for x in xs:
            v = np.array([r["fitness"] for r in rows if r["agent_steps"] == x], dtype=float)
            v = v[np.isfinite(v)]
            m.append(v.mean() if v.size else np.nan)
            h.append(ci95(v) if v.size else np.nan)
        m_, h_ = np.array(m), np.array(h)
        color = f"C{i}"
        ax.plot(xs, m_, color=color, marker="o", ms=3, label=f"trained {cond}")
        ax.fill_between(xs, m_ - h_, m_ + h_, color=color, alpha=0.15)
    ax.set_xlabel("agent-steps of training")
    ax.set_ylabel("reward per agent-step (own condition)")
    ax.set_title(f"tight task, {a.learner.upper()}: mean ± 95% CI over {n_seeds} seeds",
                 fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    save(fig, out, "learning_curves.png")
    if not table:
        return
    fig, ax = plt.subplots(figsize=(7, 4))
    x = np.arange(len(table))
    for k, (key, label) in enumerate((("delay_trained", "trained under that delay"),
                                      ("perfect_trained", "trained with perfect info"))):
        ax.errorbar(x + (k - 0.5) * 0.2, [r[f"{key}_mean"] for r in table],
                    yerr=[r[f"{key}_ci95"] for r in table], fmt="o", capsize=4,
                    color=f"C{k}", label=label)
    for name, mk in (("naive", "x"), ("extrapolating", "+")):
        ax.plot(x, [r[f"{name}_fitness"] for r in table], mk, color="k", ms=8,
                label=f"hand-written {name}")
    ax.set_xticks(x, [r["cell"] for r in table])
    ax.set_ylabel(f"reward per agent-step ({a.eval_episodes} held-out episodes)")
    ax.set_title("evaluated under delay: mean ± 95% CI over seeds", fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    save(fig, out, "eval.png")


if __name__ == "__main__":
    raise SystemExit(main())
