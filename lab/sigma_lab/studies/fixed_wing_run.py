"""One run of the fixed-wing fit: logs, ``sigma-des tune``, held-out scores, identifiability.

:func:`run` writes the glider's logs (CSV, made by ``sigma-des flightlog``'s
generator), the starting parameters (``start.toml``) and the GA settings
(``tune_<stage>.toml``), runs ``sigma-des tune`` on them in process, one run per
stage (:data:`~sigma_lab.studies.fixed_wing.STAGES`; outputs in ``tune/<stage>/``,
the final ``fitted.toml`` beside them, and ``minisgs_powered.toml``: the same with
an 11x10 propeller, the shipped ``minisgs`` fit), and scores the starting, the tuned and
the JSBSim-coefficient parameter sets on every log: RMS and R² per channel over
the tuning replay (``tune.segment``-second windows restarted from the logged state). Results:
``metrics.csv`` (log x parameter set x channel), ``genes.csv`` (bounds, start,
fitted, JSBSim's value, local sensitivity), ``summary.json`` / ``summary.md`` and
``run.json``
(date, machine, load, command, wall and CPU time).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from sigma_des import __version__
from sigma_des.agents.fitted import fitted_params, write_fitted
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.tuning.flightlog import FlightLog, write_csv
from sigma_des.tuning.glider_log import GlideSpec, fly_glider, glider_structure
from sigma_des.tuning.report import PAPER_VALUES, replayed, score
from sigma_des.tuning.spec import TuneSpec, get_value, with_values
from sigma_lab.studies.fixed_wing import (
    GENES,
    STAGES,
    course_step,
    glide_cd0,
    glider_start,
    inertia_ridge,
    joint_profile,
    jsbsim_coefficients,
    powered,
    sensitivity,
    trim_moments,
)
from sigma_lab.studies.machine import machine

__all__ = ["LOGS", "CHANNELS", "Budget", "run", "machine"]

#: The logs: name -> (variant, trim speed m/s, speed step halfway m/s, seed offset).
#: ``tuning`` (two trims, 9 then 11 m/s: the static pitch balance needs more than one)
#: is the only one the GA sees; the others are held out: other inputs at 10 m/s, other
#: inputs at 12 m/s (outside the tuning speeds).
LOGS: dict[str, tuple[int, float, float, int]] = {
    "tuning": (0, 9.0, 2.0, 0), "heldout_inputs": (1, 10.0, 0.0, 1000),
    "heldout_speed": (2, 12.0, 0.0, 2000)}
#: Channels reported (the paper's: pitch and roll rate; plus the angles and yaw rate).
CHANNELS = ("q", "p", "theta", "phi", "r")
#: Replay window (s): every window restarts from the logged state.
SEGMENT = 1.0
#: Sensitivity threshold: a gene whose +-10 % moves the fitness by less is "flat".
FLAT = 0.01


class Budget:
    """Log length and GA size of a run (full or quick)."""

    def __init__(self, quick: bool) -> None:
        self.duration = 6.0 if quick else 40.0
        self.population = 8 if quick else 96
        self.generations = 3 if quick else 200


def _logs(out: Path, seed: int, duration: float) -> dict[str, FlightLog]:
    logs = {}
    for name, (variant, speed, step, off) in LOGS.items():
        logs[name] = fly_glider(GlideSpec(speed=speed, speed_step=step, variant=variant,
                                          duration=duration, seed=seed + off))
        write_csv(logs[name], out / "logs" / f"{name}.csv")
    return logs


def _scores(logs: dict[str, FlightLog], sets: dict[str, AircraftParams], spec: TuneSpec
            ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    series: dict[str, Any] = {}
    names = list(sets)
    for lname, log in logs.items():
        win, sims = replayed(log, [sets[n] for n in names], spec)
        series[lname] = {"win": win, "sims": dict(zip(names, sims, strict=True))}
        for n, sim in zip(names, sims, strict=True):
            ch = score(win, sim, "fixedwing")["channels"]
            rows += [{"log": lname, "params": n, "channel": c, "rms": ch[c]["rms"],
                      "r2": ch[c]["r2"]} for c in CHANNELS]
    return rows, series


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _stage_spec(genes: tuple[str, ...], channels: tuple[str, ...], b: Budget,
                seed: int) -> dict[str, Any]:
    """The ``[tune]`` table of one stage."""
    return {"seed": seed, "population": b.population, "generations": b.generations,
            "segment": SEGMENT, "params": list(genes), "channels": list(channels),
            "lower": [GENES[g][0] for g in genes], "upper": [GENES[g][1] for g in genes]}


def _tune(out: Path, start: AircraftParams, b: Budget, seed: int) -> list[dict[str, Any]]:
    """``sigma-des tune`` per stage on the tuning log (held-out inputs as --validate);
    the last stage's fitted file is copied to ``out/fitted.toml``."""
    from sigma_des.cli import main as cli

    values = {n: get_value(start, n) for n in
              ("mass", "ixx", "iyy", "izz", "ixz", "s", "b", "c", "delta_max", "tau_servo",
               "cd_0")}
    init = write_fitted(out / "start.toml", "fixedwing", values, {
        "what": "glider structure + preset derivatives; cd_0 from the logged steady glide"})
    reports = []
    for name, genes, channels in STAGES:
        cfg = out / f"tune_{name}.toml"
        cfg.write_text(tomli_w.dumps({"tune": _stage_spec(genes, channels, b, seed)}))
        argv = ["tune", "--dynamics", "fixedwing", "--log", str(out / "logs" / "tuning.csv"),
                "--validate", str(out / "logs" / "heldout_inputs.csv"), "--init", str(init),
                "--config", str(cfg), "--out", str(out / "tune" / name)]
        t0 = time.perf_counter()
        if cli(argv) != 0:
            raise RuntimeError(f"sigma-des {' '.join(argv)} failed")
        rep = json.loads((out / "tune" / name / "report.json").read_text())
        reports.append({"stage": name, "genes": list(genes), "channels": list(channels),
                        "fitness_start": rep["fitness_start"],
                        "fitness_best": rep["fitness_best"], "evaluations": rep["evaluations"],
                        "seconds": time.perf_counter() - t0, "history": rep["history"],
                        "command": "sigma-des " + " ".join(argv)})
        init = out / "tune" / name / "fitted.toml"
    (out / "fitted.toml").write_text(init.read_text())
    return reports


def _f(x: float | None, nd: int = 3) -> str:
    return "–" if x is None else f"{x:.{nd}f}"


def summary_md(s: dict[str, Any]) -> str:
    """The study's results as Markdown: held-out table beside the paper's, genes, timing."""
    p = s["paper_talon"]
    m = {(r["log"], r["params"], r["channel"]): r for r in s["metrics"]}
    lines = ["# Fixed wing against JSBSim's minisgs (the paper's Fig. 15 in kind)", "",
             "R² and RMS per channel over 1 s replay windows restarted from the reference "
             "state, on logs the GA never saw. **Caveat: the reference is JSBSim's minisgs "
             "model, not a flight; the paper's TALON figures are from real flights.**", "",
             "| log | parameters | RMS q (rad/s) | RMS p (rad/s) | RMS θ (rad) | RMS φ (rad) | "
             "R² q | R² p | R² θ | R² φ |", "|---|---|---|---|---|---|---|---|---|---|"]
    for log in ("heldout_inputs", "heldout_speed", "tuning"):
        for name in ("initial", "tuned", "jsbsim_coeffs"):
            r = {c: m[(log, name, c)] for c in ("q", "p", "theta", "phi")}
            lines.append(f"| {log} | {name} | " + " | ".join(
                _f(r[c]["rms"], 4) for c in ("q", "p", "theta", "phi")) + " | " + " | ".join(
                _f(r[c]["r2"]) for c in ("q", "p", "theta", "phi")) + " |")
    lines += [f"| paper, TALON flight | – | {p['rms_pitch']} | {p['rms_roll']} | – | – | "
              f"{p['r2']} (pitch and roll rate) | | | |", "",
              "Logs: " + "; ".join(f"`{n}` {v['source']}" for n, v in s["logs"].items()) + ".",
              "", "| gene | bounds | start | fitted | JSBSim's | ±10 % fitness rise | "
              "identifiable |", "|---|---|---|---|---|---|---|"]
    for g in s["genes"]:
        lines.append(f"| {g['name']} | [{g['lower']:g}, {g['upper']:g}] | {g['start']:.4g} | "
                     f"{g['fitted']:.4g} | {_f(g['jsbsim'], 4)} | {100 * g['rise_low']:+.1f} / "
                     f"{100 * g['rise_high']:+.1f} % | {'yes' if g['identifiable'] else 'no'} |")
    tm = ", ".join(f"{r['speed']:g} m/s {r['cm']:+.4f} ({r['q_dot']:+.2f} rad/s²)"
                   for r in s["trim_moments"])
    lines += ["", "Why the pitch angle misses outside the tuning speeds: our pitch moment "
              f"at JSBSim's trimmed glides (JSBSim's is 0) is {tm}; the fitted static "
              "balance crosses zero inside the 9–11 m/s of the tuning log and grows "
              "outside it, so the replay drifts in pitch within each window."]
    t = s["tune"]
    ridge = ", ".join(f"x{r['k']:g}: {r['both']:.6f} (inertia alone {r['inertia_only']:.3f})"
                      for r in s["inertia_ridge"])
    lines += ["", f"Inertia held at JSBSim's values: all inertias and moment coefficients "
              f"scaled together leave the fitness unchanged ({ridge}).", "",
              f"GA: {len(t['stages'])} `sigma-des tune` stages ("
              + ", ".join(f"{st['stage']}: r {st['fitness_start']:.3g} -> "
                          f"{st['fitness_best']:.3g}" for st in t["stages"])
              + f"), population {t['population']} x {t['generations']} generations each, "
              f"{t['evaluations']} evaluations, {t['seconds']:.0f} s wall, "
              f"{t['cpu_s']:.0f} s CPU.", ""]
    return "\n".join(lines)


def run(out: Path, quick: bool, seed: int, command: str) -> dict[str, Any]:
    """The whole study into ``out``; returns the summary (also written as JSON)."""
    t_wall, t_cpu, load0 = time.perf_counter(), time.process_time(), os.getloadavg()
    out.mkdir(parents=True, exist_ok=True)
    b = Budget(quick)
    logs = _logs(out, seed, b.duration)
    st = glider_structure()
    start = glider_start(st)
    start = with_values(start, {"cd_0": glide_cd0(logs["tuning"], start)})
    names = tuple(g for _, genes, _ in STAGES for g in genes)
    spec = TuneSpec(seed=seed, segment=SEGMENT)
    t_tune, c_tune = time.perf_counter(), time.process_time()
    stages = _tune(out, start, b, seed)
    tune_s, tune_cpu = time.perf_counter() - t_tune, time.process_time() - c_tune
    fitted = fitted_params(out / "fitted.toml", "fixedwing")
    flying = fitted_params(powered(out / "fitted.toml", out / "minisgs_powered.toml"),
                           "fixedwing")
    steps = {"preset gains": course_step(dataclasses.replace(flying, gains=preset(
        "fixedwing").gains)), "retuned gains": course_step(flying),
        "preset airframe": course_step(preset("fixedwing"))}
    alpha = np.arctan2(logs["tuning"].obs[:, 2], logs["tuning"].obs[:, 0])
    ref = jsbsim_coefficients("minisgs", (float(alpha.min()), float(alpha.max())))
    mapped = with_values(start, ref)
    sets = {"initial": start, "tuned": fitted, "jsbsim_coeffs": mapped}
    rows, series = _scores(logs, sets, spec)
    sens = sensitivity(logs["tuning"], fitted, names, spec)
    ridge = inertia_ridge(logs["tuning"], fitted, spec)
    joint = joint_profile(logs["tuning"], fitted, spec)
    genes = [{"name": g, "lower": GENES[g][0], "upper": GENES[g][1],
              "start": get_value(start, g), "fitted": get_value(fitted, g),
              "jsbsim": ref.get(g), "rise_low": s["rise_low"], "rise_high": s["rise_high"],
              "identifiable": min(s["rise_low"], s["rise_high"]) >= FLAT}
             for g, s in zip(names, sens, strict=True)]
    _write_csv(out / "metrics.csv", rows)
    _write_csv(out / "genes.csv", genes)
    summary = {
        "study": "fixed_wing", "quick": quick, "seed": seed, "version": __version__,
        "aircraft": "jsbsim:minisgs", "structure": st, "logs": {
            n: {"variant": v, "speed_m_s": s, "speed_step_m_s": st_, "seed": seed + o,
                "duration_s": b.duration, "source": logs[n].source,
                "command": f"sigma-des flightlog --speed {s:g} --speed-step {st_:g} --variant "
                           f"{v} --duration {b.duration:g} --seed {seed + o} --out {n}.csv"}
            for n, (v, s, st_, o) in LOGS.items()},
        "tune": {"population": b.population, "generations": b.generations,
                 "segment_s": SEGMENT, "rate_hz": spec.rate, "band": spec.band,
                 "stages": stages, "seconds": tune_s, "cpu_s": tune_cpu,
                 "evaluations": sum(st_["evaluations"] for st_ in stages),
                 "score_channels": list(spec.channels_of("fixedwing"))},
        "metrics": rows, "genes": genes, "inertia_ridge": ridge, "joint_profile": joint,
        "course_step": steps, "trim_moments": trim_moments(fitted),
        "flat_threshold": FLAT,
        "paper_talon": PAPER_VALUES["fixedwing"],
        "caveat": "the reference is JSBSim's minisgs model, not a flight; the paper's TALON "
                  "figures are from real flights",
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=float) + "\n")
    (out / "summary.md").write_text(summary_md(summary))
    (out / "run.json").write_text(json.dumps({
        "date": datetime.now(UTC).isoformat(timespec="seconds"), "machine": machine(),
        "load_before": list(load0), "load_after": list(os.getloadavg()), "command": command,
        "wall_s": time.perf_counter() - t_wall, "cpu_s": time.process_time() - t_cpu,
        "tune_wall_s": tune_s, "tune_cpu_s": tune_cpu}, indent=1) + "\n")
    summary["series"] = series
    return summary
