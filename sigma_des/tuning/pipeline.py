"""One tuning run end to end: GA on a log, fitted file, fit report, plots.

Used by ``sigma-des tune`` (cli.py) and by ``experiments/model_tuning.py``.
Outputs in the chosen directory: ``fitted.toml`` (loadable as
``dynamics_params``), ``report.json`` (genes, bounds, fitness, GA history, R² /
RMS before and after on the tuning log and, if given, the validation log;
wall time under ``timing``), ``report.md`` and ``fit_tuning.png`` /
``fit_validation.png`` (logged vs initial vs tuned pitch and roll).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from sigma_des.agents.fitted import GAIN_PREFIX, PARAM_NAMES, get_value, write_fitted
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.agents.wind import WindConfig
from sigma_des.tuning.flightlog import FlightLog
from sigma_des.tuning.ga import tune
from sigma_des.tuning.report import PAPER_VALUES, plot_fit, replayed, score
from sigma_des.tuning.spec import TuneSpec, with_values
from sigma_des.version import __version__

__all__ = ["tune_and_report", "markdown"]


def _clean(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    return x


def _file_values(start: AircraftParams, kind: str, genes: dict[str, float]) -> dict[str, float]:
    """What fitted.toml holds: the start's values that differ from the preset (an
    ``--init`` file's structure) and the fitted genes, so the file alone rebuilds it."""
    base = preset(kind)
    vals = {n: get_value(start, n) for n in PARAM_NAMES
            if get_value(start, n) != get_value(base, n)}
    vals.update({GAIN_PREFIX + k: v for k, v in start.gains.items() if base.gains.get(k) != v})
    vals.update(genes)
    return vals


def tune_and_report(log: FlightLog, start: AircraftParams, spec: TuneSpec, out: str | Path,
                    validate: FlightLog | None = None, wind: WindConfig | None = None,
                    truth: dict[str, float] | None = None) -> dict[str, Any]:
    """Tune ``start`` on ``log``, write the outputs to ``out`` and return the report.

    Args:
        log: tuning log.
        start: starting parameters ("initial parameters" of the paper's Fig. 5).
        spec: GA / fitness settings.
        out: output directory.
        validate: held-out log scored before/after (not used by the GA).
        wind: replay wind (default still air).
        truth: known true gene values (synthetic logs), reported as relative errors.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    kind = log.kind
    res = tune(log, start, spec, wind)
    fitted = with_values(start, res.values())
    rep: dict[str, Any] = {
        "kind": kind, "version": __version__, "seed": spec.seed,
        "tune": dataclasses.asdict(spec), "log": log.source,
        "validate": validate.source if validate else None,
        "genes": [{"name": n, "lower": lo, "upper": hi, "start": s, "fitted": b}
                  for n, lo, hi, s, b in zip(res.names, res.lower, res.upper, res.start,
                                             res.best, strict=True)],
        "fitness_start": res.start_fitness, "fitness_best": res.best_fitness,
        "evaluations": res.evaluations, "history": res.history,
        "paper": PAPER_VALUES[kind],
        "timing": {"seconds": res.seconds,
                   "generations_per_s": spec.generations / res.seconds if res.seconds else None},
    }
    if truth:
        for g in rep["genes"]:
            if g["name"] in truth:
                g["true"] = truth[g["name"]]
                g["rel_error"] = g["fitted"] / truth[g["name"]] - 1.0
    for name, lg in (("tuning", log), ("validation", validate)):
        if lg is None:
            continue
        win, sims = replayed(lg, [start, fitted], spec, wind)
        rep[name] = {"initial": score(win, sims[0], kind), "tuned": score(win, sims[1], kind)}
        png = plot_fit(out / f"fit_{name}.png", win, {"initial": sims[0], "tuned": sims[1]},
                       kind, f"{kind}: {name} log {lg.source}")
        rep[name]["plot"] = png.name if png else None
    write_fitted(out / "fitted.toml", kind, _file_values(start, kind, res.values()),
                 {"seed": spec.seed, "log": log.source, "fitness": res.best_fitness,
                  "fitness_start": res.start_fitness, "version": __version__})
    rep = _clean(rep)
    (out / "report.json").write_text(json.dumps(rep, indent=1))
    (out / "report.md").write_text(markdown(rep))
    return rep


def markdown(rep: dict[str, Any]) -> str:
    """The fit report as Markdown tables."""
    f = lambda x: "–" if x is None else f"{x:.4g}"  # noqa: E731
    lines = [f"# Tuning report ({rep['kind']})", "",
             f"Log `{rep['log']}`, seed {rep['seed']}, sigma_des {rep['version']}; fitness "
             f"r = D T / s: {f(rep['fitness_start'])} -> {f(rep['fitness_best'])} "
             f"({rep['evaluations']} evaluations).", "",
             "| gene | lower | upper | start | fitted | true | error |",
             "|---|---|---|---|---|---|---|"]
    for g in rep["genes"]:
        err = f"{100 * g['rel_error']:+.1f} %" if "rel_error" in g else "–"
        lines.append(f"| {g['name']} | {f(g['lower'])} | {f(g['upper'])} | {f(g['start'])} | "
                     f"{f(g['fitted'])} | {f(g.get('true'))} | {err} |")
    p = rep["paper"]
    for name in ("tuning", "validation"):
        if name not in rep:
            continue
        r = rep[name]
        pc, rc = r["tuned"]["pitch_channel"], r["tuned"]["roll_channel"]
        lines += ["", f"## {name} log", "",
                  f"| | RMS pitch ({pc}) | RMS roll ({rc}) | R² |", "|---|---|---|---|",
                  f"| initial | {f(r['initial']['rms_pitch'])} | {f(r['initial']['rms_roll'])} | "
                  f"{f(r['initial']['r2'])} |",
                  f"| tuned | {f(r['tuned']['rms_pitch'])} | {f(r['tuned']['rms_roll'])} | "
                  f"{f(r['tuned']['r2'])} |",
                  f"| paper | {p['rms_pitch']} | {p['rms_roll']} | {p['r2']} |"]
    return "\n".join(lines) + "\n"
