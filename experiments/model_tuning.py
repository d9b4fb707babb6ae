#!/usr/bin/env python
"""Paper study "model tuning" (§IV.A, §V.A.2, Figs. 14–15): GA + DTW fit of our 6-DoF model.

Identifiability (the ground truth we can trust without real flights): for each
aircraft kind and seed, our own model at its preset ("true") parameters flies a
high-manoeuvrability attitude manoeuvre (sigma_des.tuning.synth) in a 1 m/s
mean wind with light Dryden turbulence, logged at 50 Hz with sensor noise; a
second, different manoeuvre (another variant and seed) is the validation log.
The GA starts from the true values perturbed by fixed factors (x1.3, x0.75,
x1.25, x0.8, x1.2, x0.7, x1.4 over the kind's default genes) and tunes on the
first log only. The fixed-wing replay knows the mean wind (not the turbulence);
the quadrotor replay assumes still air. Reported: fitted vs true per gene,
validation RMS / R² (quadrotor on pitch/roll angles, fixed wing on pitch/roll
rates, as the paper) before and after, GA wall time and generations/s.

Cross-model (JSBSim): JSBSim's F450 (shipped with the ``jsbsim`` package) flies
the same kind of manoeuvre under its own FCS (sigma_des.tuning.jsbsim_log); the
logged control signals are its four propeller speeds. Our quadrotor preset is
tuned on one log and validated on another manoeuvre. Because the logged speeds
are measured, not commanded, the motor-lag gene may go down to 0.5 ms. The
fixed-wing cross-fit, against JSBSim's minisgs glider, is experiments/fixed_wing_fit.py.

Outputs in ``--out`` (default ``out/model_tuning``): ``summary.json``,
``results.csv`` (tidy: study, kind, seed, name, value, config_hash, version),
and per run ``<kind>_seed<N>/`` with ``fitted.toml``, ``report.json/md`` and the
Figs. 14–15-like plots ``fit_validation.png``.

Usage: ``python experiments/model_tuning.py [--quick] [--seeds 1,2,3] [--out DIR]``
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

from sigma_lab.studies import command_line, finish_args, study_parser, write_summary

from sigma_des import __version__
from sigma_des.agents.presets import preset
from sigma_des.agents.wind import WindConfig
from sigma_des.tuning.pipeline import tune_and_report
from sigma_des.tuning.report import PAPER_VALUES
from sigma_des.tuning.spec import DEFAULT_GENES, TuneSpec, get_value, with_values
from sigma_des.tuning.synth import fly

try:
    from sigma_des.tuning.jsbsim_log import fly_f450
except ImportError:          # jsbsim not installed: the cross-model part is skipped
    fly_f450 = None  # type: ignore[assignment]

FACTORS = (1.3, 0.75, 1.25, 0.8, 1.2, 0.7, 1.4)
MEAN_WIND = (1.0, 0.5, 0.0)
#: Full-mode budgets: (log duration s, population, generations).
FULL = {"quadrotor": (10.0, 48, 100), "fixedwing": (12.0, 64, 150)}
QUICK = {"quadrotor": (3.0, 8, 3), "fixedwing": (3.0, 8, 3)}
TURB = {"quadrotor": 2.0, "fixedwing": 1.0}


def spec_hash(spec: TuneSpec) -> str:
    """12-hex hash of the tune settings without the seed."""
    d = dataclasses.asdict(spec)
    d.pop("seed")
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


def identifiability(kind: str, seed: int, quick: bool, out: Path) -> dict[str, Any]:
    """One kind, one seed: tune on a synthetic log, validate on another."""
    dur, pop, gens = (QUICK if quick else FULL)[kind]
    truth = preset(kind)
    genes = DEFAULT_GENES[kind]
    start = with_values(truth, {g: get_value(truth, g) * f
                                for g, f in zip(genes, FACTORS, strict=False)})
    wind = WindConfig(mean_ned=MEAN_WIND, w20=TURB[kind])
    log = fly(truth, kind, duration=dur, wind=wind, seed=seed)
    val = fly(truth, kind, duration=dur, wind=wind, seed=seed + 1000, variant=1)
    spec = TuneSpec(population=pop, generations=gens, seed=seed)
    replay_wind = WindConfig(mean_ned=MEAN_WIND) if kind == "fixedwing" else None
    rep = tune_and_report(log, start, spec, out / f"{kind}_seed{seed}", validate=val,
                          wind=replay_wind, truth={g: get_value(truth, g) for g in genes})
    rep["config_hash"] = spec_hash(spec)
    return rep


def crossmodel(seed: int, quick: bool, out: Path) -> dict[str, Any]:
    """Tune our quadrotor on a JSBSim F450 log; validate on another F450 manoeuvre."""
    dur, pop, gens = (QUICK if quick else FULL)["quadrotor"]
    start = preset("quadrotor")
    genes = DEFAULT_GENES["quadrotor"]
    lo = [get_value(start, g) * 0.5 for g in genes]
    hi = [get_value(start, g) * 2.0 for g in genes]
    lo[genes.index("tau_motor")] = 0.0005
    hi[genes.index("rotor_pitch")] = 0.5          # the blade model's limit is 0.7 rad
    spec = TuneSpec(population=pop, generations=gens, seed=seed, params=genes,
                    lower=tuple(lo), upper=tuple(hi))
    assert fly_f450 is not None
    log = fly_f450(duration=dur, seed=seed)
    val = fly_f450(duration=dur, seed=seed + 1000, variant=1)
    rep = tune_and_report(log, start, spec, out / f"jsbsim_F450_seed{seed}", validate=val)
    rep["config_hash"] = spec_hash(spec)
    return rep


def rows_of(rep: dict[str, Any], seed: int, study: str) -> list[dict[str, Any]]:
    """Tidy rows of one run."""
    base = {"study": study, "kind": rep["kind"], "seed": seed,
            "config_hash": rep["config_hash"], "version": __version__}
    rows = [dict(base, name=f"rel_error.{g['name']}", value=g["rel_error"])
            for g in rep["genes"] if "rel_error" in g]
    rows += [dict(base, name=f"fitted.{g['name']}", value=g["fitted"]) for g in rep["genes"]]
    for when in ("initial", "tuned"):
        v = rep["validation"][when]
        rows += [dict(base, name=f"validation.{when}.{k}", value=v[k])
                 for k in ("rms_pitch", "rms_roll", "r2")]
    rows += [dict(base, name="fitness_start", value=rep["fitness_start"]),
             dict(base, name="fitness_best", value=rep["fitness_best"]),
             dict(base, name="generations_per_s", value=rep["timing"]["generations_per_s"])]
    return rows


def _digest(rep: dict[str, Any], seed: int, where: str) -> dict[str, Any]:
    print(f"{where}: validation R² {rep['validation']['initial']['r2']:.3f} -> "
          f"{rep['validation']['tuned']['r2']:.3f}, "
          f"{rep['timing']['generations_per_s']:.1f} generations/s", flush=True)
    return {"seed": seed, "genes": rep["genes"], "validation": rep["validation"],
            "tuning": rep["tuning"], "fitness_start": rep["fitness_start"],
            "fitness_best": rep["fitness_best"], "timing": rep["timing"],
            "evaluations": rep["evaluations"], "dir": where}


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = finish_args(study_parser("model_tuning", __doc__).parse_args(argv))
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    per: dict[str, list[dict[str, Any]]] = {}
    for kind in ("quadrotor", "fixedwing"):
        for seed in args.seeds:
            rep = identifiability(kind, seed, args.quick, out)
            rows += rows_of(rep, seed, "identifiability")
            per.setdefault(kind, []).append(_digest(rep, seed, f"{kind}_seed{seed}"))
    cross: dict[str, list[dict[str, Any]]] = {}
    if fly_f450 is not None:
        for seed in args.seeds:
            rep = crossmodel(seed, args.quick, out)
            rows += rows_of(rep, seed, "jsbsim")
            cross.setdefault("F450", []).append(_digest(rep, seed, f"jsbsim_F450_seed{seed}"))
    with (out / "results.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["study", "kind", "seed", "name", "value",
                                           "config_hash", "version"])
        w.writeheader()
        w.writerows(rows)
    summary = {"study": "model_tuning", "quick": args.quick, "seeds": args.seeds,
               "command": command_line("model_tuning"), "version": __version__,
               "budgets": {k: dict(zip(("duration_s", "population", "generations"), v,
                                       strict=True))
                           for k, v in (QUICK if args.quick else FULL).items()},
               "factors": FACTORS, "mean_wind": MEAN_WIND, "turbulence_w20": TURB,
               "paper": PAPER_VALUES, "identifiability": per, "jsbsim": cross,
               "jsbsim_fixedwing": "experiments/fixed_wing_fit.py (JSBSim minisgs)"}
    write_summary(out, summary)
    print(f"wrote {out / 'summary.json'} and {out / 'results.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
