"""The delay study's runs and outputs (``experiments/train_under_delay.py`` is its command).

Trains a policy per condition and seed (CEM or Stable-Baselines3 PPO), evaluates every
trained, untrained and hand-written policy on the same held-out episodes of every
condition, and writes ``history.csv``, ``eval.csv``, ``stats.csv``, ``summary.json``
and the plots after every seed; :func:`merge` combines shards of one study. The
conditions and the paired statistics are :mod:`sigma_lab.studies.delay`.
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
from sigma_lab.studies import plot_setup, save
from sigma_lab.studies.delay import cells, ci95, env_kwargs, paired_cells, perfect_rows
from sigma_lab.studies.env_report import delay_study

__all__ = ["Policy", "merge", "run", "train_one"]

Policy = Callable[[np.ndarray], np.ndarray]


def train_one(a: argparse.Namespace, cond: str, seed: int, history: list[dict[str, Any]]
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

        def linear(obs: np.ndarray, th: np.ndarray = theta) -> np.ndarray:
            return act(np.broadcast_to(th, (obs.shape[0],) + th.shape), obs)
        policy: Policy = linear
    else:
        policy, hist = _train_ppo(a, kw, cond, seed)
        history += [{"learner": "ppo", "trained": cond, "seed": seed,
                     **{k: r[k] for k in ("agent_steps", "fitness")}} for r in hist]
        if hist:  # a resumed training: its wall time and agent-steps in all
            return policy, hist[-1]["wall_s"], hist[-1]["agent_steps"]
        used = float(a.ppo_steps)
    return policy, time.perf_counter() - t0, used


def _train_ppo(a: argparse.Namespace, kw: dict[str, Any], cond: str, seed: int
               ) -> tuple[Policy, list[dict[str, float]]]:
    """One PPO policy (``sigma_des.env.ppo``), checkpointed under ``a.checkpoints``
    (resumed from there), with a progress line every ``a.progress`` rollouts."""
    from sigma_des.env.ppo import train as train_ppo

    t0 = time.perf_counter()
    rollouts = [0]

    def progress(row: dict[str, float]) -> None:
        rollouts[0] += 1
        if rollouts[0] % a.progress == 0 or row["agent_steps"] >= a.ppo_steps:
            rate = row["agent_steps"] / max(row["wall_s"], 1e-9)
            eta = (a.ppo_steps - row["agent_steps"]) / max(rate, 1e-9)
            print(f"  [{time.perf_counter() - t0:6.0f} s] {cond} seed {seed} {a.policy}: "
                  f"{row['agent_steps']:,.0f}/{a.ppo_steps:,} agent-steps, reward per "
                  f"agent-step {row['fitness']:.3f}, {rate:,.0f}/s, ETA {eta / 60:.0f} min",
                  flush=True)

    ck = Path(a.checkpoints) / f"{cond}_{a.policy}_s{seed}" if a.checkpoints else None
    return train_ppo(kw, a.ppo_steps, seed, policy=a.policy, n_scenes=a.ppo_scenes,
                 n_stack=a.n_stack, checkpoint=ck, log=progress, max_wall_s=a.ppo_wall,
                 n_steps=a.ppo_n_steps, batch_size=a.ppo_batch)


def run(a: argparse.Namespace) -> int:
    """Train every condition and seed, evaluate everything everywhere, write the outputs
    (``a``: the parsed command line of ``experiments/train_under_delay.py``)."""
    conds = cells(a.delay_list, a.method_list)
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
        for cond in [c for c in conds if a.train_list is None or c in a.train_list]:
            rec = Path(a.checkpoints) / f"{cond}_{_tag(a)}_s{seed}.done.json" \
                if a.checkpoints else None
            if rec is not None and rec.exists():  # resume: this training is finished
                done = json.loads(rec.read_text())
                history += done["history"]
                cost.append({**done["cost"], "resumed": True})  # trained by an earlier run
                evals += done["eval"]
                print(f"seed {seed} {cond:14s} done before ({rec.name})", flush=True)
                continue
            n_hist, n_eval = len(history), len(evals)
            pol, wall, used = train_one(a, cond, seed, history)
            cost.append({"trained": cond, "seed": seed, "train_wall_s": wall,
                         "agent_steps": used, "agent_steps_per_s": used / wall})
            evaluate(cond, seed, pol, conds if cond == "perfect" else ["perfect", cond])
            own = next(e for e in evals[::-1] if (e["trained"], e["seed"], e["evaluated"])
                       == (cond, seed, cond))
            print(f"[{time.perf_counter() - t_start:7.0f} s] seed {seed} {cond:14s} trained "
                  f"({wall:.0f} s, {used / wall:,.0f} agent-steps/s); evaluated under it: "
                  f"{own['fitness']:.3f}", flush=True)
            if rec is not None and (a.learner == "cem" or used >= a.ppo_steps):
                rec.parent.mkdir(parents=True, exist_ok=True)
                rec.write_text(json.dumps({"history": history[n_hist:], "cost": cost[-1],
                                           "eval": evals[n_eval:]}) + "\n")
        # outputs after every seed: an interrupted study keeps its finished seeds
        table = paired_cells(evals, conds, seeds[: k + 1])
        _write(out, a, history, evals, cost, table, time.perf_counter() - t_start,
               seeds[: k + 1])
    for cond in conds:
        for r in perfect_rows(evals, seeds, cond):
            print(f"under {cond:12s}: {r['policy']:24s} {r['mean']:.3f} ± {r['ci95']:.3f} "
                  f"({r['n']} {'seeds' if r['seed_mean'] else 'controller'})", flush=True)
    for r in table:
        print(f"{r['cell']:14s} delay-trained {r['delay_trained_mean']:.3f} ± "
              f"{r['delay_trained_ci95']:.3f}  perfect-trained {r['perfect_trained_mean']:.3f} "
              f"± {r['perfect_trained_ci95']:.3f}  paired t p={r['t_p_greater']:.3g} "
              f"wilcoxon p={r['wilcoxon_p_greater']:.3g}", flush=True)
    return 0


def _tag(a: argparse.Namespace) -> str:
    """The learner's part of a training's file names (``cem`` or the PPO policy)."""
    return "cem" if a.learner == "cem" else a.policy


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
    a.delay_list = [] if a.delays == "none" else [float(x) for x in a.delays.split(",")]
    a.method_list = a.methods.split(",")
    done = sorted({s for p in parts for s in p["seeds_done"]})
    if sum(len(p["seeds_done"]) for p in parts) != len(done):
        raise SystemExit("--merge: the shards share a seed")
    evals: list[dict[str, Any]] = []
    history: list[dict[str, Any]] = []
    cost: list[dict[str, Any]] = []
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
        "seeds_done": done, "perfect": perfect_rows(evals, done),
        "evaluated_under": {c: perfect_rows(evals, done, c)
                            for c in cells(a.delay_list, a.method_list)},
        "stats": table, "eval": evals, "cost": cost, "wall_s": wall}, indent=2) + "\n")
    refs = {r["policy"]: r["mean"] for r in perfect_rows(evals, done) if not r["seed_mean"]}
    _plots(out, a, history, table, len(done), refs)
    if any(e["seed"] == -1 for e in evals):  # a shard without the baselines has none
        # the study's own reading, in words: the results page shows it above the plots
        (out / "summary.md").write_text(delay_study(out / "summary.json", out, level=1))


def _plots(out: Path, a: argparse.Namespace, history: list[dict[str, Any]],
           table: list[dict[str, Any]], n_seeds: int, refs: dict[str, float]) -> None:
    plt = plot_setup(fast=a.quick)
    conds = cells(a.delay_list, a.method_list)
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, cond in enumerate(conds):
        rows = [r for r in history if r["trained"] == cond]
        if not rows:  # not trained (--train)
            continue
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
    for name, style in (("naive", "--"), ("extrapolating", ":")):
        if name in refs:  # the hand-written controllers under perfect information
            ax.axhline(refs[name], color="k", ls=style, lw=1,
                       label=f"{name}, perfect info (held-out)")
    ax.set_yscale("symlog", linthresh=0.1)  # early failures (-10 each) beside the tail
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
