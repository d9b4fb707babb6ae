"""lab/record/ENV.md from the env study outputs: speed (``bench_env.py``), training
(``train_formation.py``) and the training-under-delay studies (``train_under_delay.py``,
each followed by its ages control, ``train_ages_control.py``).

The fixed prose comes from :class:`~sigma_lab.studies.report.Templates` (``env_*``);
``experiments/report_env.py`` is the command that writes the document. Every section
says what is missing instead of failing when its input is absent, and the readings say
what the tables support and nothing beyond it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from sigma_lab.studies.report import Templates

__all__ = ["ages_control", "bench_section", "build", "delay_studies", "delay_study",
           "delay_verdict", "train_section"]


def bench_section(outputs: Path, templates: Templates) -> str:
    """The speed section from ``bench.json`` (``experiments/bench_env.py``)."""
    p = outputs / "bench.json"
    if not p.exists():
        return "## Speed\n\n(no `bench.json` under the outputs: run `experiments/bench_env.py`)\n"
    d = json.loads(p.read_text())
    rows = d["rows"]
    methods = sorted({r["method"] for r in rows}, key=["none", "lockstep", "hlc",
                                                       "bides"].index)
    lines = ["## Speed (`experiments/bench_env.py`)", "",
             f"Formation task, {d['agents']} agents per scene (11 nodes), the env's default "
             "scenario (point mass, 50 Hz triggers, 20 Hz alignment, a decision every 2nd "
             "tick = 5 physics frames per decision, datagram QoS 0, cohort engine); "
             "agent-steps per second of one core's CPU time (best of 3 batches), sigma_des "
             f"{d['version']}. `const`: compute time constant (no per-frame random draws).",
             ""]
    for variant in sorted({r["variant"] for r in rows}, key=lambda v: v != "default"):
        sizes = sorted({r["scenes"] for r in rows if r["variant"] == variant})
        lines.append(f"| {variant}: agent-steps/s | " + " | ".join(methods) + " |")
        lines.append("|---|" + "---:|" * len(methods))
        for s in sizes:
            cells = []
            for m in methods:
                r = next(r for r in rows if (r["variant"], r["scenes"], r["method"]) ==
                         (variant, s, m))
                cells.append(f"{r['agent_steps_per_s']:,.0f}")
            lines.append(f"| {s} scenes × {d['agents']} agents | " + " | ".join(cells) + " |")
        lines.append("")
    if d.get("plain"):
        lines.append("For reference, the same scenario run by the simulator alone (no env, "
                     "the built-in `follow` behaviour sending the commands), CPU ms per "
                     "decision period (0.1 s simulated): " +
                     ", ".join(f"{p['method']} {p['ms_per_decision']:.2f}" for p in d["plain"])
                     + " — against the env's ms per scene-step in `bench.csv`.")
        lines.append("")
    mem = d["memory_bytes_per_scene"]
    lines.append("Memory per scene (Python heap allocated by `reset`, tracemalloc, "
                 f"{d['mem_scenes']} scenes): " +
                 ", ".join(f"{m} {mem[m] / 1024:.0f} KiB" for m in methods) + ".")
    lines.append("")
    lines.append(templates.text("env_bound"))
    return "\n".join(lines)


def train_section(outputs: Path) -> str:
    """The training section from ``train/summary.json`` (``train_formation.py``)."""
    p = outputs / "train" / "summary.json"
    if not p.exists():
        return ("## Training\n\n(no `train/summary.json` under the outputs: run "
                "`experiments/train_formation.py`)\n")
    d = json.loads(p.read_text())
    a = d["args"]
    hist = d["history"]
    lines = ["## Training: under delay vs with perfect information "
             "(`experiments/train_formation.py`)", "",
             f"Formation task, {a['nodes']} nodes ({a['nodes'] - 1} agents), "
             f"{a['max_steps']} decisions (10 s) per episode. Learner: cross-entropy method "
             "over a shared linear policy `a = tanh(W o + b)` (30 parameters; "
             "`sigma_des/env/learn.py`), "
             f"{a['population']} candidates × {a['episodes']} episodes per iteration, "
             f"{a['iterations']} iterations, elite {max(1, a['population'] // 4)}, all "
             "candidates of an iteration in one vectorised env on common episodes. "
             "Fitness: mean reward per agent-step (an early termination scores its "
             "remaining steps at the worst clipped error cost).", "",
             "* **delay**: BiDES over host links with latency normal(150 ms, 30 ms) and "
             "10 % Bernoulli loss; agents observe the aligned view.",
             "* **perfect**: agents observe the true current state over an ideal network "
             "(0.25 ms links, no loss) — what a peer environment gives.", "",
             "Learning curves (elite mean fitness per iteration, in its own training "
             "condition; plot: `learning_curves.png` under the outputs, e.g. "
             "`/work/out/env/train/learning_curves.png`):", "",
             "| iteration | " + " | ".join(f"{c} elite" for c in ("delay", "perfect")) + " |",
             "|---:|---:|---:|"]
    its = sorted({int(r["iteration"]) for r in hist})
    step = max(1, len(its) // 8)
    for it in its[::step] + ([its[-1]] if its[-1] not in its[::step] else []):
        cells = [next(f"{r['elite_fitness']:.3f}" for r in hist
                      if r["trained"] == c and int(r["iteration"]) == it)
                 for c in ("delay", "perfect")]
        lines.append(f"| {it} | " + " | ".join(cells) + " |")
    lines += ["", f"Evaluation on {a['eval_episodes']} held-out episodes (same episodes "
              "for every policy):", "",
              "| trained | evaluated | fitness | mean slot error (m) | episodes failed |",
              "|---|---|---:|---:|---:|"]
    for r in d["eval"]:
        lines.append(f"| {r['trained']} | {r['evaluated']} | {r['fitness']:.3f} | "
                     f"{r['error']:.2f} | {r['failed']:.2f} |")
    ev = {(r["trained"], r["evaluated"]): r for r in d["eval"]}
    if all((t, e) in ev for t in ("delay", "perfect") for e in ("delay", "perfect")):
        lines += ["", _verdict(ev)]
    lines += _other_seeds(outputs)
    lines += ["", _conclusion(outputs)]
    wall = d.get("wall_s", {})
    if wall:
        lines += ["", "Training wall time of the first run: " + ", ".join(f"{k} {v:.0f} s"
                                                         for k, v in wall.items()) + "."]
    return "\n".join(lines) + "\n"


def _other_seeds(outputs: Path) -> list[str]:
    """The 2 x 2 evaluation of further training runs (``train_*/summary.json``)."""
    rows = []
    wins = []
    for p in sorted(outputs.glob("train_*/summary.json")):
        d = json.loads(p.read_text())
        a = d["args"]
        ev = {(r["trained"], r["evaluated"]): r["fitness"] for r in d["eval"]}
        cells = [f"{ev[(t, e)]:.3f}" for t in ("delay", "perfect") for e in ("delay", "perfect")]
        wins.append(ev[("delay", "delay")] > ev[("perfect", "delay")])
        lat = a.get("latency", 0.15) * 1e3
        rows.append(f"| `{p.parent.name}` | {a['seed']} | {lat:.0f} ms, {a.get('loss', 0.1):.0%} | "
                    f"{a['nodes']} × {a['population']} × {a['episodes']} × {a['iterations']} | "
                    + " | ".join(cells) + " |")
    if not rows:
        return []
    return ["", "Further training runs (fitness, trained → evaluated; budget = nodes × "
            "population × episodes × iterations):", "",
            "| run | seed | delay condition | budget | delay → delay | delay → perfect | "
            "perfect → delay | perfect → perfect |",
            "|---|---:|---|---|---:|---:|---:|---:|", *rows, "",
            f"In {sum(wins)} of these {len(wins)} further runs the delay-trained policy is "
            "the better one under delay."]


def _conclusion(outputs: Path) -> str:
    """One sentence over every training run: is the delay-specific advantage shown?"""
    specific = []
    for p in [outputs / "train" / "summary.json", *sorted(outputs.glob("train_*/summary.json"))]:
        ev = {(r["trained"], r["evaluated"]): r["fitness"]
              for r in json.loads(p.read_text())["eval"]}
        specific.append(ev[("delay", "delay")] > ev[("perfect", "delay")]
                        and ev[("perfect", "perfect")] > ev[("delay", "perfect")])
    if all(specific):
        return (f"**Conclusion.** In all {len(specific)} runs each policy is best in the "
                "condition it was trained in: training under delay pays under delay.")
    return (f"**Conclusion.** Each policy is best in its own training condition in "
            f"{sum(specific)} of {len(specific)} runs: at these budgets the learner improves "
            "the policy under delay as well as without it, but a better policy *under delay* "
            "from training under delay is **not established**: which policy wins varies "
            "between runs, within the noise of CEM at this budget (not converged).")


def _verdict(ev: dict[tuple[str, str], dict[str, float]]) -> str:
    """The comparison in words, without claiming more than the table shows."""
    dd, dp = ev[("delay", "delay")]["fitness"], ev[("delay", "perfect")]["fitness"]
    pd, pp = ev[("perfect", "delay")]["fitness"], ev[("perfect", "perfect")]["fitness"]
    text = (f"Under delay, the policy trained under delay scores {dd:.3f} against {pd:.3f} "
            "for the one trained with perfect information; with perfect information "
            f"{dp:.3f} against {pp:.3f}. Moving from perfect information to delay costs "
            f"the delay-trained policy {dp - dd:.3f} and the perfect-trained one "
            f"{pp - pd:.3f}. ")
    if dd > pd and pp > dp:
        return text + ("Each policy is best in the condition it was trained in: the "
                       "advantage under delay is specific to training under delay.")
    if dd > pd:
        return text + ("The delay-trained policy is better in *both* conditions, so this "
                       "run does not separate a delay-specific advantage from training "
                       "noise (CEM at this budget is not converged); it shows that the "
                       "toolbox trains under delay at least as well as without it.")
    return text + "Training under delay gave no advantage under delay in this run."


def delay_study(path: Path, img_dir: Path, level: int = 3) -> str:
    """The section of one ``train_under_delay.py`` run (its ``summary.json``), its heading
    at ``level``; its plots are linked where ``img_dir`` (the document's ``img/env``)
    holds copies."""
    d = json.loads(path.read_text())
    a = d["args"]
    ev = {(e["trained"], e["seed"], e["evaluated"]): e for e in d["eval"]}
    done = d.get("seeds_done", list(range(a["seeds"])))
    budget = (f"CEM: {a['iterations']} iterations × {a['population']} candidates × "
              f"{a['episodes']} episodes" if a["learner"] == "cem" else
              f"SB3 PPO ({a.get('policy', 'mlp')} policy), {a['ppo_steps']:,} agent-steps on "
              f"{a['ppo_scenes']} scenes, n_steps {a['ppo_n_steps']}, batch {a['ppo_batch']}")
    own = (f"--iterations {a['iterations']} --population {a['population']} --episodes "
           f"{a['episodes']}" if a["learner"] == "cem" else
           f"--ppo-steps {a['ppo_steps']} --ppo-scenes {a['ppo_scenes']}")
    cmd = (f"python experiments/train_under_delay.py --learner {a['learner']} --seeds "
           f"{a['seeds']} --max-steps {a['max_steps']} {own}")
    if a.get("merged_from"):
        cmd += (f"`, run as {len(a['merged_from'])} shards (`--seed-list`) merged with "
                "`--merge")
    lines = [f"{'#' * level} `{path.parent.name}`: {a['learner'].upper()}, seeds {done}", "",
             f"Command: `{cmd}` (delays {a['delays']} s, methods {a['methods']}, loss "
             f"{a['loss']:.0%}, {a['nodes']} nodes, {a['max_steps']} decisions per episode, "
             f"{a['eval_episodes']} held-out episodes of root seed {a['eval_seed']}); "
             f"budget per policy: {budget}.", "",
             "| cell | trained under it | trained perfect | difference | paired t p | "
             "Wilcoxon p | untrained | naive | extrapolating |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in d["stats"]:
        lines.append(
            f"| {r['cell']} | {r['delay_trained_mean']:.3f} ± {r['delay_trained_ci95']:.3f} | "
            f"{r['perfect_trained_mean']:.3f} ± {r['perfect_trained_ci95']:.3f} | "
            f"{r['diff_mean']:+.3f} ± {r['diff_ci95']:.3f} | {r['t_p_greater']:.3g} | "
            f"{r['wilcoxon_p_greater']:.3g} | {r['untrained_fitness']:.3f} | "
            f"{r['naive_fitness']:.3f} | {r['extrapolating_fitness']:.3f} |")
    pp = [ev[("perfect", s, "perfect")]["fitness"] for s in done if ("perfect", s, "perfect")
          in ev]
    base = {n: ev[(n, -1, "perfect")]["fitness"] for n in ("untrained", "naive",
                                                          "extrapolating")}
    best = max(base["naive"], base["extrapolating"])
    lines += ["", "Under perfect information: trained-perfect "
              f"{sum(pp) / max(len(pp), 1):.3f} (mean over seeds; per seed "
              f"{', '.join(f'{x:.3f}' for x in pp)}: {sum(x >= best for x in pp)} of {len(pp)} "
              f"at or above the better hand-written controller), untrained "
              f"{base['untrained']:.3f}, naive {base['naive']:.3f}, extrapolating "
              f"{base['extrapolating']:.3f}."]
    cost = d["cost"]
    if cost:
        wall = sum(c["train_wall_s"] for c in cost)
        steps = sum(c["agent_steps"] for c in cost)
        each = sorted(c["train_wall_s"] for c in cost)
        mid = each[len(each) // 2]
        # a resumed run's trainings are marked (older outputs: its wall is below theirs)
        resumed = any(c.get("resumed") for c in cost) or d["wall_s"] < wall
        lines += ["", f"Cost: {len(cost)} trainings, {wall:.0f} s of training wall time "
                  f"({steps / wall:,.0f} agent-steps/s; per policy median {mid:.0f} "
                  f"s, {each[0]:.0f}–{each[-1]:.0f} s), " + (
                      f"{d['wall_s']:.0f} s in all" if not resumed else
                      f"resumed: this run took {d['wall_s']:.0f} s, the trainings were done "
                      "before") + " (wall times: they depend on the machine's load and on how "
                  "many trainings shared it)."]
    shown = [r["cell"] for r in d["stats"]
             if r["diff_mean"] > 0 and r["t_p_greater"] < 0.05 and r["wilcoxon_p_greater"] < 0.05]
    name = path.parent.name
    figs = [f"![{name}: {f}](img/env/{name}_{f}.png)" for f in ("learning_curves", "eval")
            if (img_dir / f"{name}_{f}.png").exists()]
    lines += ["", f"Plots: `{name}/learning_curves.png` and `{name}/eval.png` under the "
              "outputs" + (" (copies in `lab/record/img/env/`):" if figs else "."), *(
                  ["", *figs] if figs else [])]
    lines += ["", f"Shown at p < 0.05 by both tests in: {', '.join(shown) or 'no cell'} "
              f"(of {len(d['stats'])}; {len(done)} seeds, no correction for multiple cells).",
              "", delay_verdict(d["stats"], len(done))]
    return "\n".join(lines) + "\n"


def delay_verdict(rows: list[dict[str, Any]], n_seeds: int) -> str:
    """What one run's table supports, in words (nothing beyond it)."""
    if n_seeds < 5:
        return (f"**Reading.** Only {n_seeds} seed(s) finished: below the 5 the protocol asks "
                "for; no conclusion is drawn from this run.")
    better = [r for r in rows if r["diff_mean"] > 0]
    shown = [r for r in better if r["t_p_greater"] < 0.05 and r["wilcoxon_p_greater"] < 0.05]
    under = [r for r in rows if max(r["delay_trained_mean"], r["perfect_trained_mean"])
             < r["naive_fitness"]]
    text = (f"**Reading.** Trained under delay beats trained with perfect information, "
            f"evaluated under delay, in {len(better)} of {len(rows)} cells by the mean and in "
            f"{len(shown)} by both paired tests at p < 0.05. ")
    if shown:
        text += (f"At this budget, training under delay gives the better policy under delay "
                 f"in {', '.join(str(r['cell']) for r in shown)} (one-sided, uncorrected). ")
    if under:
        text += (f"But in {len(under)} of {len(rows)} cells both trained policies score below "
                 "the hand-written naive controller: the learner is far from converged. And a "
                 "policy trained with perfect information only ever saw ages of 0, so under "
                 "delay its (untrained) weights on the age columns meet inputs it never saw; "
                 "part of the gap may be that rather than learned compensation (the "
                 "ages-hidden control, when run, follows this section). ")
    if not shown:
        text += "A better policy under delay from training under delay is **not shown** here."
    return text


def ages_control(path: Path, command: str | None = None) -> str:
    """The section of one ages-hidden control (its ``summary.json``; ``command``: how it
    was run, default the ``train_ages_control.py`` command)."""
    d = json.loads(path.read_text())
    command = command or (f"python experiments/train_ages_control.py --study "
                          f"{Path(d['study']).name}")
    lines = [f"Control (`{command}`): the study's perfect-information policies again (same "
             "seeds and budget; identical to the study's: "
             f"{all(t['reproduces_study'] for t in d['table'])}) and evaluated under "
             "each delay cell with their age columns set to 0:", "",
             "| cell | trained under it | perfect, ages shown | perfect, ages hidden | "
             "difference to hidden | paired t p |", "|---|---:|---:|---:|---:|---:|"]
    for t in d["table"]:
        lines.append(f"| {t['cell']} | {t['delay_trained_mean']:.3f} | "
                     f"{t['perfect_shown_mean']:.3f} ± {t['perfect_shown_ci95']:.3f} | "
                     f"{t['perfect_hidden_mean']:.3f} ± {t['perfect_hidden_ci95']:.3f} | "
                     f"{t['diff_vs_hidden_mean']:+.3f} ± {t['diff_vs_hidden_ci95']:.3f} | "
                     f"{t['t_p_delay_beats_hidden']:.3g} |")
    lines += ["", _control_reading(d["table"], len(d["seeds"]))]
    return "\n".join(lines) + "\n"


def _control_reading(table: list[dict[str, Any]], n_seeds: int) -> str:
    """What the ages-hidden control supports, in words."""
    if n_seeds < 5:
        return (f"**Control reading.** Only {n_seeds} seed(s): below the 5 the protocol asks "
                "for; no conclusion is drawn from this control.")
    win = [t["cell"] for t in table if t["t_p_delay_beats_hidden"] < 0.05]
    text = (f"**Control reading.** With the ages hidden from them, the policies trained with "
            f"perfect information are beaten at p < 0.05 (one-sided paired t, {n_seeds} "
            f"seeds) in {', '.join(win) or 'no cell'} of {len(table)}")
    if win:
        return text + (": there, training under delay gives a better policy under delay even "
                       "against perfect-trained policies spared the ages they never saw, a "
                       "learned, delay-specific advantage.")
    return text + (": a learned, delay-specific advantage of training under delay is **not "
                   "shown**; where the study shows one over the perfect-trained policies, it "
                   "comes from feeding them ages they never saw.")


def delay_studies(outputs: Path, templates: Templates, img_dir: Path) -> str:
    """Every ``delay_*`` study under ``outputs``, each followed by its ages control."""
    paths = sorted(p for p in outputs.glob("delay_*/summary.json")
                   if not p.parent.name.endswith("_ages_control"))
    head = templates.text("env_delay")
    if not paths:
        return head + "\n(no `delay_*/summary.json` under the outputs: run " \
            "`experiments/train_under_delay.py`)\n"
    parts = []
    for p in paths:
        parts.append(delay_study(p, img_dir))
        ctl = p.parent.with_name(p.parent.name + "_ages_control") / "summary.json"
        if ctl.exists():
            parts.append(ages_control(ctl))
    return head + "\n" + "\n".join(parts)


def build(outputs: Path, templates: Templates, img_dir: Path) -> str:
    """The whole of lab/record/ENV.md: the fixed prose of ``templates`` (``env_*``) around the
    sections of the study outputs under ``outputs``."""
    intro = templates.text("env_intro")
    return "\n".join([intro, bench_section(outputs, templates), train_section(outputs),
                      delay_studies(outputs, templates, img_dir)])
