"""The ``model_tuning`` section of ``lab/record/REPRODUCTION.md`` (hooked into make_report.py).

``section(outputs)`` reads ``<outputs>/model_tuning/summary.json`` (written by
``experiments/model_tuning.py``) and returns Markdown: the paper's validation
figures next to ours, per-gene recovery, GA speed, and why they differ.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

TITLE = "Automatic model tuning: GA + DTW fit (`model_tuning`)"
_UNITS = {"quadrotor": ("rad", "pitch / roll angle"), "fixedwing": ("rad/s", "pitch / roll rate")}


def _f(x: Any, nd: int = 3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{nd}f}"


def _mean(xs: list[float]) -> float:
    xs = [x for x in xs if x is not None]
    return sum(xs) / len(xs) if xs else float("nan")


def _jsbsim(s: dict[str, Any]) -> list[str]:
    runs = s.get("jsbsim", {}).get("F450", [])
    out = ["", "Cross-model fit: our quadrotor tuned on a log flown by JSBSim's F450 (its own "
           "FCS, propeller tables and motor model; logged control signals = its four "
           "propeller speeds), validated on a different F450 manoeuvre:", ""]
    if not runs:
        return out + ["Not run (jsbsim not installed).", ""]
    tuned = [r["validation"]["tuned"] for r in runs]
    init = [r["validation"]["initial"] for r in runs]
    out += ["| | RMS pitch (rad) | RMS roll (rad) | attitude R² | yaw-rate R² |",
            "|---|---|---|---|---|"]
    for name, rs in (("preset (before)", init), ("tuned", tuned)):
        out.append(f"| {name} | {_f(_mean([t['rms_pitch'] for t in rs]), 4)} | "
                   f"{_f(_mean([t['rms_roll'] for t in rs]), 4)} | "
                   f"{_f(_mean([t['r2'] for t in rs]))} | "
                   f"{_f(_mean([t['channels']['r']['r2'] for t in rs]))} |")
    p = s["paper"]["quadrotor"]
    out.append(f"| paper (P450, real flights) | {p['rms_pitch']} | {p['rms_roll']} | "
               f"{p['r2']} | – |")
    fitted = {g["name"]: _mean([r["genes"][i]["fitted"] for r in runs])
              for i, g in enumerate(runs[0]["genes"])}
    out += ["", "Fitted (mean over seeds): " + ", ".join(
        f"{k} {v:.4g}" for k, v in fitted.items()) + ". The motor lag goes to a few ms "
        "because the logged speeds are measured, not commanded. Yaw is the model difference "
        "that remains: izz and rotor_cd0 run to their bounds and the yaw-rate R² stays low; "
        "the likely cause (not isolated) is JSBSim's propeller torque — its C_POWER table "
        "and the propellers' own inertia, whose spin-up reaction torque acts on yaw — which "
        "our blade-element torque does not reproduce.", ""]
    return out


def _fixed_wing(outputs: Path) -> list[str]:
    """The fixed-wing cross-fit against JSBSim's minisgs (experiments/fixed_wing_fit.py)."""
    path = Path(outputs) / "fixed_wing" / "summary.json"
    head = ["", "Cross-model fit, fixed wing: our fixed wing tuned on a log flown by JSBSim's "
            "`minisgs` sailplane (2.44 m, 5 kg; `python experiments/fixed_wing_fit.py`), "
            "scored on held-out logs (other inputs at 10 m/s; other inputs at 12 m/s, outside "
            "the 9–11 m/s tuning log). The reference is a JSBSim model, not a flight.", ""]
    if not path.exists():
        return head + [f"Not run: no `{Path(outputs).name}/fixed_wing/summary.json`.", ""]
    s = json.loads(path.read_text())
    m = {(r["log"], r["params"], r["channel"]): r for r in s["metrics"]}
    out = head + ["| held-out log | parameters | RMS q (rad/s) | RMS p (rad/s) | R² q | R² p | "
                  "R² theta | R² phi |", "|---|---|---|---|---|---|---|---|"]
    for log in ("heldout_inputs", "heldout_speed"):
        for name in ("initial", "tuned"):
            r = {c: m[(log, name, c)] for c in ("q", "p", "theta", "phi")}
            out.append(f"| {log} | {name} | {_f(r['q']['rms'], 4)} | {_f(r['p']['rms'], 4)} | "
                       f"{_f(r['q']['r2'])} | {_f(r['p']['r2'])} | {_f(r['theta']['r2'])} | "
                       f"{_f(r['phi']['r2'])} |")
    p = s["paper_talon"]
    out += [f"| paper (TALON, real flight) | – | {p['rms_pitch']} | {p['rms_roll']} | "
            f"{p['r2']} (pitch and roll) | | | |", ""]
    return out


def section(outputs: Path) -> str:
    """Markdown for the study (a 'Not run' note when its outputs are missing)."""
    path = Path(outputs) / "model_tuning" / "summary.json"
    if not path.exists():
        return (f"## {TITLE}\n\nNot run: `python experiments/model_tuning.py` writes "
                f"`{Path(outputs).name}/model_tuning/summary.json`.\n")
    s = json.loads(path.read_text())
    out = [f"## {TITLE}", ""]
    out.append("Validation log (a different manoeuvre, never seen by the GA), after tuning; "
               "means over seeds. Paper: §V.A.2, Figs. 14–15 (real P450 and TALON flights).")
    out += ["", "| aircraft | scored on | paper RMS pitch | paper RMS roll | paper R² | "
            "ours RMS pitch | ours RMS roll | ours R² | R² before tuning |",
            "|---|---|---|---|---|---|---|---|---|"]
    for kind, runs in s["identifiability"].items():
        p = s["paper"][kind]
        tuned = [r["validation"]["tuned"] for r in runs]
        init = [r["validation"]["initial"] for r in runs]
        unit, what = _UNITS[kind]
        out.append(f"| {kind} | {what} ({unit}) | {p['rms_pitch']} | {p['rms_roll']} | "
                   f"{p['r2']} | {_f(_mean([t['rms_pitch'] for t in tuned]), 4)} | "
                   f"{_f(_mean([t['rms_roll'] for t in tuned]), 4)} | "
                   f"{_f(_mean([t['r2'] for t in tuned]))} | "
                   f"{_f(_mean([t['r2'] for t in init]))} |")
    out += ["", "Parameter recovery (identifiability test: logs flown by our model at the "
            "preset values with sensor noise and wind; GA started from perturbed values):", "",
            "| aircraft | gene | start error | fitted error, mean | worst |fitted error| |",
            "|---|---|---|---|---|"]
    for kind, runs in s["identifiability"].items():
        for i, g in enumerate(runs[0]["genes"]):
            errs = [r["genes"][i]["rel_error"] for r in runs]
            start = g["start"] / g["true"] - 1
            out.append(f"| {kind} | {g['name']} | {100 * start:+.0f} % | "
                       f"{100 * _mean(errs):+.1f} % | {100 * max(abs(e) for e in errs):.1f} % |")
    out += _jsbsim(s)
    out += _fixed_wing(outputs)
    gps = {k: _mean([r["timing"]["generations_per_s"] for r in runs])
           for k, runs in s["identifiability"].items()}
    b = s["budgets"]
    out += ["", "GA speed (wall, one core, whole run incl. reports): " + ", ".join(
        f"{k} {_f(v, 1)} generations/s (P = {b[k]['population']}, {b[k]['generations']} "
        f"generations, {b[k]['duration_s']:g} s log)" for k, v in gps.items())
        + ". The batched fitness is 5–9x faster than scoring candidates one by one "
        "(`python experiments/bench_tuning.py`).", ""]
    out.append(
        "Why ours differ from the paper: (1) our logs are flown by our own model, so there "
        "is no model-form error — what remains is sensor noise, unmodelled turbulence and "
        "GA convergence; the paper fits real flights, where the model itself is wrong in "
        "places, hence its lower R². (2) R² and RMS are computed over the tuning replay: "
        "1 s windows restarted from the logged state (an open-loop quadrotor diverges "
        "within seconds whatever its parameters); the paper does not state its horizon. "
        "(3) Which parameters are identifiable: for the quadrotor roll/pitch inertia, rotor "
        "thrust (collective pitch) and motor lag are recovered to a few per cent; yaw inertia "
        "and rotor profile drag only through their ratio (both set the yaw response); the "
        "frame drag not at these speeds. For the fixed wing, inertia is held at its measured "
        "value (only moment coefficient / inertia is identifiable); roll damping and aileron "
        "power and lift slope are recovered best, the pitch-moment derivatives lie on a ridge. "
        "(4) Cross-model: see the JSBSim tables (F450 and minisgs).")
    mode = " (**quick mode** — a smoke test, not the study)" if s.get("quick") else ""
    out += ["", f"Command: `{s['command']}`{mode} — seeds "
            f"{','.join(str(x) for x in s['seeds'])}, sigma_des {s['version']}. Per-run "
            "reports and plots (`fit_validation.png`, logged vs initial vs tuned, like Figs. "
            "14–15): `model_tuning/<kind>_seed<N>/`.", ""]
    return "\n".join(out)
