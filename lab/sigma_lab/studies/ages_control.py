"""The delay study's control: perfect-trained policies under delay with the ages hidden.

A policy trained with perfect information only ever sees ages of 0. Under delay its
age columns carry values it never saw, so part of its loss there may be those inputs
rather than the delay itself. The control takes the study's perfect-information
policies again (from the study's checkpoints, or retrained: training is
deterministic), evaluates each under every delay cell twice on the study's held-out
episodes — ages shown (must equal the study's own figures) and age columns set to 0
(``hidden``) — and compares the delay-trained policies with the hidden ones (paired
over seeds, one-sided t test). Commands: ``experiments/train_ages_control.py`` and
``experiments/train_under_delay.py --ages-control``.
"""

from __future__ import annotations

import argparse
import csv
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from sigma_des import __version__
from sigma_des.env.learn import score
from sigma_lab.studies.delay import cells, ci95, env_kwargs
from sigma_lab.studies.delay_study import train_one
from sigma_lab.studies.env_report import ages_control

__all__ = ["AGE_COLUMNS", "add_to_study", "run_control"]

#: Age columns of the ``tight`` observation (own, leader, nearest neighbour).
AGE_COLUMNS = [5, 8, 13]


def _hide(policy: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], np.ndarray]:
    """``policy`` fed observations whose age columns are 0."""
    def hidden(obs: np.ndarray) -> np.ndarray:
        o = obs.copy()
        o[..., AGE_COLUMNS] = 0.0
        return policy(o)
    return hidden


def _evaluate(a: argparse.Namespace, seeds: list[int], conds: list[str],
              log: Callable[[str], None]) -> list[dict[str, Any]]:
    """Every seed's perfect-trained policy under every delay cell, ages shown and hidden."""
    rows: list[dict[str, Any]] = []
    for seed in seeds:
        policy, _, _ = train_one(a, "perfect", seed, [])
        for cell in conds[1:]:
            kw = env_kwargs(cell, a.nodes, a.max_steps, a.loss)
            for view, pol in (("shown", policy), ("hidden", _hide(policy))):
                r = score(pol, kw, a.eval_episodes, a.eval_seed)
                rows.append({"seed": seed, "evaluated": cell, "ages": view,
                             "fitness": float(r["fitness"].mean())})
            log(f"seed {seed} {cell:12s} shown {rows[-2]['fitness']:.3f} hidden "
                f"{rows[-1]['fitness']:.3f}")
    return rows


def _table(study: dict[str, Any], rows: list[dict[str, Any]], seeds: list[int],
           conds: list[str]) -> list[dict[str, Any]]:
    """Per delay cell: delay-trained against perfect-trained with ages shown and hidden."""
    fit = {(e["trained"], e["seed"], e["evaluated"]): e["fitness"] for e in study["eval"]}
    table = []
    for cell in conds[1:]:
        d = np.array([fit[(cell, s, cell)] for s in seeds])
        sh = np.array([r["fitness"] for r in rows if r["evaluated"] == cell
                       and r["ages"] == "shown"])
        hi = np.array([r["fitness"] for r in rows if r["evaluated"] == cell
                       and r["ages"] == "hidden"])
        study_p = np.array([fit[("perfect", s, cell)] for s in seeds])
        table.append({
            "cell": cell, "n_seeds": len(seeds),
            "reproduces_study": bool(np.array_equal(sh, study_p)),
            "perfect_shown_mean": float(sh.mean()), "perfect_shown_ci95": ci95(sh),
            "perfect_hidden_mean": float(hi.mean()), "perfect_hidden_ci95": ci95(hi),
            "delay_trained_mean": float(d.mean()),
            "diff_vs_hidden_mean": float((d - hi).mean()), "diff_vs_hidden_ci95": ci95(d - hi),
            "t_p_delay_beats_hidden": float(
                stats.ttest_rel(d, hi, alternative="greater").pvalue)})
    return table


def run_control(study_dir: Path, csv_path: Path, json_path: Path,
                log: Callable[[str], None] = print) -> dict[str, Any]:
    """Run the control on the study in ``study_dir`` (its ``summary.json``); write the
    per-cell table to ``csv_path`` and everything to ``json_path``; return the latter's
    content."""
    study = json.loads((study_dir / "summary.json").read_text())
    a = argparse.Namespace(**study["args"])
    seeds = study["seeds_done"]
    if a.delays == "none":
        raise SystemExit(f"{study_dir}: the study has no delay cell to control")
    conds = cells([float(x) for x in a.delays.split(",")], a.methods.split(","))
    rows = _evaluate(a, seeds, conds, log)
    table = _table(study, rows, seeds, conds)
    with csv_path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*table[0], "learner", "version"])
        w.writeheader()
        for t in table:
            w.writerow({**t, "learner": a.learner, "version": __version__})
    out = {"version": __version__, "study": str(study_dir), "args": study["args"],
           "seeds": seeds, "rows": rows, "table": table}
    json_path.write_text(json.dumps(out, indent=2) + "\n")
    for t in table:
        log(f"{t['cell']:12s} delay-trained {t['delay_trained_mean']:.3f}  perfect shown "
            f"{t['perfect_shown_mean']:.3f}  hidden {t['perfect_hidden_mean']:.3f} ± "
            f"{t['perfect_hidden_ci95']:.3f}  p={t['t_p_delay_beats_hidden']:.3g}  "
            f"reproduces study: {t['reproduces_study']}")
    return out


def add_to_study(out: Path, log: Callable[[str], None] = print) -> None:
    """Run the control on the finished study in ``out`` (``train_under_delay.py
    --ages-control``): ``ages_control.csv`` and ``ages_control.json`` beside the study's
    outputs, and the control's section appended to its ``summary.md``."""
    run_control(out, out / "ages_control.csv", out / "ages_control.json", log)
    md = out / "summary.md"
    if md.exists():  # a study with its baselines (not a bare shard): its page text
        cmd = "python experiments/train_under_delay.py ... --ages-control"
        md.write_text(md.read_text() + "\n" + ages_control(out / "ages_control.json", cmd))
