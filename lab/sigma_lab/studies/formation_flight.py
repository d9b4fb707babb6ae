"""The formation study's runs and metrics: five fixed-wing aircraft in a leader–follower V.

``experiments/formation.py`` (the script: networks, command line, plots) runs, per
seed, the ideal run and every alignment method with :func:`run_seed` and writes
``results.csv`` and ``summary.json`` with :func:`write_outputs`.

Metrics (per method and for the ideal run):

* slots — from the *true* logged positions with
  :func:`sigma_des.agents.formation.formation_slots`; the leader's heading is its
  course over ground from the logged positions (central differences; still air,
  so course = heading up to the small sideslip); a slot's altitude is the leader's;
* ``conv_h_s`` / ``conv_v_s`` — convergence time of a follower: the first time
  after which its horizontal (vertical) distance to its slot stays below
  ``--h-threshold`` (5 m) / ``--v-threshold`` (2 m) until the end of the
  *convergence window*, which ends where the leader's first turn begins (the last
  time its course is within 1° of the initial course before it turns more than
  15° — at a corner of the rectangle every slot swings round, and the followers
  leave it for a while) or at the end of the flight.
  NaN = not converged within the window. Reported per follower
  (``conv_h_s.node<i>``), as mean and max over followers, and as the fraction of
  followers that converged;
* ``slot_h_mean_m`` / ``slot_v_mean_m`` — mean distance to slot over followers
  and the whole flight (corners included);
* ``formation_err_mean`` / ``formation_err_max`` — shape error against the ideal
  run (:func:`sigma_des.metrics.fidelity.fidelity`, the engine's definition);
* ``dtw_r`` — DTW distance of each node's trajectory to its ideal trajectory,
  normalised as the paper does, ``r = D·T/s`` (``T`` = 1/30 s, ``s`` = the flight
  time covered; :func:`sigma_des.metrics.dtw.dtw_normalised`), mean over the 5
  nodes; ``dtw_r.node<i>`` per node; 0 for the ideal run against itself;
* ``flight_s`` — physics time covered. Lock-Step under heavy loss advances
  physics far slower than real time (its barrier waits for every lost trigger
  and state to be re-requested); with ``--match-flight`` (default in full mode)
  a method whose run covered less flight than the others is re-run with a longer
  simulated duration until it covers the same flight, and every comparison with
  the ideal run is made over the common flight time;
* the engine's own metrics of each run (AoI, latency, trigger rate, …).
"""

from __future__ import annotations

import argparse
import csv
import inspect
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import sigma_des
from sigma_des.agents import layout as L
from sigma_des.agents.formation import formation_behaviour, formation_rule, formation_slots
from sigma_des.agents.ideal import fly
from sigma_des.api import TIDY_COLUMNS
from sigma_des.config import Scenario, config_hash, to_dict
from sigma_des.events.cohort import execute
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.metrics.collector import METRIC_UNITS
from sigma_des.metrics.dtw import dtw, dtw_normalised
from sigma_des.metrics.fidelity import fidelity
from sigma_lab.studies.args import command_line
from sigma_lab.studies.output import write_summary
from sigma_lab.studies.tables import text_table
from sigma_lab.studies.trajectory import convergence_time, slot_distances, window_end

Array = NDArray[np.float64]

NAME = "formation"
METHODS = ("none", "lockstep", "hlc", "bides")
IDEAL = "ideal"
N_AIRCRAFT = 5
LEADER = 0
#: The paper's formation parameters (docs/concepts/paper.md).
PAPER: dict[str, Any] = {
    "d": 30.0, "theta_deg": 45.0, "p_phi": 0.015, "p_psi": 0.4, "p_v": 0.3, "v_cru": 20.0,
    "route_m": [1000.0, 750.0], "log_rate_hz": 30.0, "aircraft": 5,
}
TURN_DEG = 15.0
TURN_START_DEG = 1.0
UNITS = {"conv_h_s": "s", "conv_v_s": "s", "conv_h_s_mean": "s", "conv_h_s_max": "s",
         "conv_v_s_mean": "s", "conv_v_s_max": "s", "converged_h_frac": "",
         "converged_v_frac": "", "window_s": "s", "flight_s": "s", "slot_h_mean_m": "m",
         "slot_v_mean_m": "m", "slot_h_final_m": "m", "slot_v_final_m": "m",
         "formation_err_mean": "m", "formation_err_max": "m", "dtw_r": "m", "dtw_m": "m",
         "sim_duration_s": "s"}
CSV_COLUMNS = ("study", "network", *TIDY_COLUMNS)



def check_paper_parameters() -> dict[str, float]:
    """The formation defaults, checked against the paper's values (raises if they differ)."""
    rule = inspect.signature(formation_rule).parameters
    beh = inspect.signature(formation_behaviour).parameters
    got = {k: float(rule[k].default) for k in ("d", "theta_deg", "p_phi", "p_psi", "p_v")}
    got["v_cru"] = float(beh["v_cru"].default)
    for k, v in got.items():
        if not math.isclose(v, PAPER[k]):
            raise SystemExit(f"formation default {k} = {v} differs from the paper's {PAPER[k]}")
    size = tuple(beh["size"].default)
    if size != tuple(PAPER["route_m"]):
        raise SystemExit(f"route size {size} differs from the paper's {PAPER['route_m']}")
    return got


class StartAt:
    """A dynamics model whose ``initial_state`` is a given state (everything else delegated)."""

    def __init__(self, dynamics: Any, state: Array) -> None:
        """Wrap ``dynamics``; ``state`` is the ``(n, state)`` initial swarm state."""
        self._dyn = dynamics
        self._state = np.array(state, dtype=np.float64)

    def __getattr__(self, name: str) -> Any:
        """Everything but ``initial_state`` comes from the wrapped model."""
        return getattr(self._dyn, name)

    def initial_state(self, n: int) -> Array:
        """The given state (``n`` must match it)."""
        if n != self._state.shape[0]:
            raise ValueError(f"StartAt: built for {self._state.shape[0]} aircraft, asked for {n}")
        return self._state.copy()


def start_state(dynamics: Any, mode: str, offset_h: float, offset_v: float) -> Array:
    """Initial swarm state: the model's grid, or followers off their slots (module doc)."""
    s = dynamics.initial_state(N_AIRCRAFT)
    if mode == "grid":
        return s
    obs = dynamics.observe(s)
    obs[LEADER, 9:12] = (0.0, 0.0, s[LEADER, L.H])
    slots = formation_slots(obs, LEADER, PAPER["d"], math.radians(PAPER["theta_deg"]))
    s[LEADER, L.XN], s[LEADER, L.YE] = 0.0, 0.0
    a = offset_h / math.sqrt(2.0)
    for k in range(N_AIRCRAFT):
        if k == LEADER:
            continue
        sgn = 1.0 if k % 2 else -1.0
        s[k, L.XN] = slots[k, 0] + a * sgn        # ahead (odd) / behind (even) the slot
        s[k, L.YE] = slots[k, 1] + a * sgn        # outboard on both sides of the V
        s[k, L.H] = s[LEADER, L.H] + offset_v * sgn
    return s


# ------------------------------------------------------------------ metrics


def slots_at(pos: Array, course: float) -> Array:
    """The paper's V-formation slots given the positions and the leader's course."""
    obs = np.zeros((pos.shape[0], 12))
    obs[:, 9:12] = pos
    obs[LEADER, 5] = course
    return formation_slots(obs, LEADER, PAPER["d"], math.radians(PAPER["theta_deg"]))


def flight_metrics(t: Array, pos: Array, ideal: Array, args: argparse.Namespace
                   ) -> tuple[dict[str, float], dict[str, Array]]:
    """Convergence, slot distances, formation error and DTW of one flight (module doc).

    ``args.h_threshold`` / ``args.v_threshold`` are the convergence thresholds (m).
    """
    m: dict[str, float] = {}
    dh, dv, course = slot_distances(t, pos, LEADER, slots_at)
    t_end = window_end(t, course, TURN_DEG, TURN_START_DEG)
    foll = [k for k in range(pos.shape[1]) if k != LEADER]
    ch = [convergence_time(t, dh[:, k], args.h_threshold, t_end) for k in foll]
    cv = [convergence_time(t, dv[:, k], args.v_threshold, t_end) for k in foll]
    for k, a, b in zip(foll, ch, cv, strict=True):
        m[f"conv_h_s.node{k}"] = a
        m[f"conv_v_s.node{k}"] = b
    for name, xs in (("conv_h_s", np.array(ch)), ("conv_v_s", np.array(cv))):
        ok = xs[np.isfinite(xs)]
        # mean / max over followers; NaN unless every follower converged
        m[f"{name}_mean"] = float(xs.mean()) if ok.size == xs.size else math.nan
        m[f"{name}_max"] = float(xs.max()) if ok.size == xs.size else math.nan
    m["converged_h_frac"] = float(np.isfinite(ch).mean())
    m["converged_v_frac"] = float(np.isfinite(cv).mean())
    m["window_s"] = t_end
    m["flight_s"] = float(t[-1])
    m["slot_h_mean_m"] = float(dh[:, foll].mean())
    m["slot_v_mean_m"] = float(dv[:, foll].mean())
    m["slot_h_final_m"] = float(dh[-1, foll].mean())
    m["slot_v_final_m"] = float(dv[-1, foll].mean())
    n = min(len(pos), len(ideal))
    period = 1.0 / PAPER["log_rate_hz"]
    fid, err = fidelity(pos[:n], ideal[:n], period, pos.shape[1])
    m["formation_err_mean"] = fid["formation_err_mean"]
    m["formation_err_max"] = fid["formation_err_max"]
    d = np.asarray(dtw(pos[:n], ideal[:n]))
    r = np.asarray(dtw_normalised(d, period, max((n - 1) * period, period)))
    m["dtw_r"] = float(r.mean())
    m["dtw_m"] = float(d.mean())
    for k in range(pos.shape[1]):
        m[f"dtw_r.node{k}"] = float(r[k])
    series = {"t": t, "dh": dh, "dv": dv, "formation_err": err, "t_end": np.array(t_end)}
    return m, series


# ------------------------------------------------------------------ running


def run_engine(sc: Scenario, method: str, dyn: Any) -> tuple[dict[str, Any], Array, Array]:
    """One method on ``sc`` (what :func:`sigma_des.api.run_method` does, keeping the
    trajectory): returns the engine's result dict and the ``(T,)``, ``(T, n, 3)`` log."""
    run, out, engine = execute(sc.run_spec(), method, lambda: dyn, lambda: make_behaviour(sc))
    out["engine"] = engine
    t, pos = run.trajectory()
    return out, t, pos


def run_seed(args: argparse.Namespace, sc: Scenario) -> dict[str, Any]:
    """The ideal run and every method on ``sc`` (one seed; options in ``args``, see
    :func:`flight_metrics`, and ``start``, ``offset``, ``match_flight``, ``max_stretch``,
    ``progress``)."""
    seed = sc.seed
    base = make_dynamics(sc)
    s0 = start_state(base, args.start, args.offset[0], args.offset[1])
    dt = 1.0 / sc.f_trig
    t0 = time.perf_counter()
    t_id, ideal = fly(StartAt(base, s0), make_behaviour(sc), N_AIRCRAFT, sc.duration, dt,
                      log_rate=sc.fidelity.log_rate, state=s0)
    wall = {IDEAL: time.perf_counter() - t0}
    metrics: dict[str, dict[str, float]] = {}
    series: dict[str, dict[str, Array]] = {}
    traj: dict[str, Array] = {IDEAL: ideal}
    m, ser = flight_metrics(t_id, ideal, ideal, args)
    m["sim_duration_s"] = sc.duration
    metrics[IDEAL], series[IDEAL] = m, ser
    hashes = {IDEAL: config_hash(sc)}
    for method in METHODS:
        t0 = time.perf_counter()
        scm = sc
        out, t, pos = run_engine(scm, method, StartAt(base, s0))
        target = t_id[-1]
        tries = 0
        while args.match_flight and t[-1] < target - 1e-6 and tries < 3:
            covered = max(float(t[-1]), 1e-3)
            dur = scm.duration * min(target / covered * 1.05 + 0.02, args.max_stretch)
            if dur <= scm.duration * 1.0001 or dur > sc.duration * args.max_stretch:
                break
            scm = replace(scm, duration=round(dur, 3))
            out, t, pos = run_engine(scm, method, StartAt(base, s0))
            tries += 1
        keep = t <= target + 1e-9
        t, pos = t[keep], pos[keep]
        wall[method] = time.perf_counter() - t0
        m, ser = flight_metrics(t, pos, ideal, args)
        m["sim_duration_s"] = scm.duration
        metrics[method] = {**{k: float(v) for k, v in out["metrics"].items()
                              if k not in ("formation_err_mean", "formation_err_max", "dtw_r")},
                           **m}
        series[method] = ser
        traj[method] = pos
        hashes[method] = config_hash(scm)
        if args.progress:
            print(f"  seed {seed} {method}: {wall[method]:.1f} s, flight {t[-1]:.1f} s",
                  file=sys.stderr)
    return {"seed": seed, "scenario": sc, "metrics": metrics, "series": series, "traj": traj,
            "hashes": hashes, "wall": wall}


# ------------------------------------------------------------------ output


def write_outputs(args: argparse.Namespace, runs: list[dict[str, Any]], params: dict[str, float],
                  wall_s: float) -> None:
    """results.csv (tidy) and summary.json."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    labels = [IDEAL, *METHODS]
    with (out / "results.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in runs:
            for lab in labels:
                for name, value in r["metrics"][lab].items():
                    w.writerow({"study": NAME, "network": args.network, "seed": r["seed"],
                                "config_hash": r["hashes"][lab], "version": sigma_des.__version__,
                                "method": lab, "metric": name, "value": value,
                                "unit": UNITS.get(name.split(".")[0],
                                                  METRIC_UNITS.get(name, ""))})
    methods: dict[str, Any] = {}
    std: dict[str, Any] = {}
    per_seed: dict[str, Any] = {}
    for lab in labels:
        names = list(runs[0]["metrics"][lab])
        methods[lab], std[lab], per_seed[lab] = {}, {}, {}
        for name in names:
            xs = np.array([r["metrics"][lab].get(name, math.nan) for r in runs], dtype=float)
            ok = xs[np.isfinite(xs)]
            methods[lab][name] = float(ok.mean()) if ok.size else math.nan
            std[lab][name] = float(ok.std()) if ok.size > 1 else 0.0 if ok.size else math.nan
            per_seed[lab][name] = xs.tolist()
    sc = runs[0]["scenario"]
    summary = {
        "study": NAME,
        "command": command_line(NAME),
        "quick": bool(args.quick),
        "seeds": [r["seed"] for r in runs],
        "version": sigma_des.__version__,
        "network": args.network,
        "start": {"mode": args.start, "offset_h_m": args.offset[0], "offset_v_m": args.offset[1]},
        "thresholds": {"horizontal_m": args.h_threshold, "vertical_m": args.v_threshold,
                       "turn_deg": TURN_DEG, "turn_start_deg": TURN_START_DEG},
        "match_flight": bool(args.match_flight),
        "paper": PAPER,
        "formation_parameters": params,
        "scenario": {k: v for k, v in to_dict(sc).items() if k not in ("seed", "methods")},
        "config_hash": runs[0]["hashes"],
        "methods": methods,
        "std": std,
        "per_seed": per_seed,
        "table": table(methods),
        "plots": [],
        "wall": {"total_s": wall_s, "per_seed": [r["wall"] for r in runs]},
    }
    write_summary(out, summary)


def fmt(x: float, spec: str = ".1f") -> str:
    """``x`` formatted, or ``n/c`` (not converged) when not finite."""
    return "n/c" if not np.isfinite(x) else format(x, spec)


TABLE_COLS = (("flight_s", "flight s", ".0f"), ("conv_h_s_mean", "conv h mean s", ".1f"),
              ("conv_h_s_max", "conv h max s", ".1f"), ("conv_v_s_mean", "conv v mean s", ".1f"),
              ("conv_v_s_max", "conv v max s", ".1f"), ("slot_h_mean_m", "slot h m", ".2f"),
              ("slot_v_mean_m", "slot v m", ".2f"), ("formation_err_mean", "form err m", ".2f"),
              ("dtw_r", "DTW r m", ".3f"), ("aoi_mean", "AoI ms", ".1f"),
              ("trigger_rate_hz", "trig Hz", ".1f"))


def table(methods: dict[str, dict[str, float]]) -> str:
    """Plain-text table of the seed means (n/c = not converged within the window)."""
    rows = [["method", *(h for _, h, _ in TABLE_COLS)]]
    for lab, ms in methods.items():
        rows.append([lab, *(fmt(ms.get(k, math.nan), f) for k, _, f in TABLE_COLS)])
    return text_table(rows)
