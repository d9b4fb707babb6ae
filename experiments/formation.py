#!/usr/bin/env python
"""Paper study "formation": five fixed-wing aircraft in a leader–follower V (DESIGN §7).

The swarm: 5 fixed-wing aircraft (``dynamics = "fixedwing"``, the TALON-class
preset, trimmed at 20 m/s and 100 m), behaviour ``formation`` — the leader (node
0) flies the clockwise 1 km × 0.75 km rectangle, the followers hold V slots with
the paper's law (eqs. 16–19) and a separation rule. The paper's parameters
d = 30 m, θ = 45°, P_φ = 0.015, P_ψ = 0.4, P_v = 0.3, v_cru = 20 m/s are the
defaults of ``formation_rule`` / ``formation_behaviour``; the script checks that
at start-up and records them in ``summary.json``. Trajectories are logged at 30 Hz
of physics time (``fidelity.log_rate``).

Runs, per seed: every alignment method (none, lockstep, hlc, bides) over the
chosen network (one aircraft per host), plus the *ideal* run (zero latency,
perfect alignment: :func:`sigma_des.agents.ideal.fly`, the reference of
``sigma_des.api.ideal_run``). Networks (``--network``):

* ``lossy`` (default) — the latency-tolerance study's network
  (``scenarios/latency_tolerance.toml``): 30 ± 10 ms one-way delay and 30 %
  packet loss on every physics host's link, datagram transport, QoS 0, alignment
  and rendering at 30 Hz, physics at 100 Hz — so the methods differ;
* ``default`` — the default scenario's LAN (0.25 ms links, TCP-like, QoS 1);
* ``ideal`` — the default scenario with zero link latency and no loss.

Start (``--start``): ``offset`` (default) puts every follower ``--offset H,V``
metres off its slot (horizontally along and across track, vertically alternating
up/down, on alternating sides); ``grid`` is the model's own start (30 m grid, all
at 100 m, heading north), from which the rear followers need ~40 s to reach their
slots.

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

Outputs (``--out``, default ``out/formation``): ``results.csv`` (tidy: one row per
seed × method × metric with ``config_hash`` and ``version``), ``summary.json``
(command, parameters, per method mean / std / per-seed values), and PNGs:
``trajectories.png`` (north vs east per method and ideal), ``convergence.png``
(horizontal and vertical distance to slot vs time), ``formation_error.png``
(formation error over time and DTW per method).

Examples::

    python experiments/formation.py                 # 150 s flights, seeds 1,2,3, lossy net
    python experiments/formation.py --quick --out /tmp/formation
    python experiments/formation.py --network default --seeds 1 --duration 120
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

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

import sigma_des  # noqa: E402
from sigma_des import load  # noqa: E402
from sigma_des.agents import layout as L  # noqa: E402
from sigma_des.agents.formation import (  # noqa: E402
    formation_behaviour,
    formation_rule,
    formation_slots,
)
from sigma_des.agents.ideal import fly  # noqa: E402
from sigma_des.config import Scenario, config_hash, to_dict  # noqa: E402
from sigma_des.events.cohort import execute  # noqa: E402
from sigma_des.factory import make_behaviour, make_dynamics  # noqa: E402
from sigma_des.metrics.collector import METRIC_UNITS  # noqa: E402
from sigma_des.metrics.dtw import dtw, dtw_normalised  # noqa: E402
from sigma_des.metrics.fidelity import fidelity  # noqa: E402

Array = NDArray[np.float64]

NAME = "formation"
METHODS = ("none", "lockstep", "hlc", "bides")
IDEAL = "ideal"
N_AIRCRAFT = 5
LEADER = 0
SCENARIO_LOSSY = Path(__file__).resolve().parent.parent / "scenarios" / "latency_tolerance.toml"
#: The paper's formation parameters (DESIGN §7).
PAPER = {"d": 30.0, "theta_deg": 45.0, "p_phi": 0.015, "p_psi": 0.4, "p_v": 0.3, "v_cru": 20.0,
         "route_m": [1000.0, 750.0], "log_rate_hz": 30.0, "aircraft": 5}
COMMON = (f"nodes={N_AIRCRAFT}", f"hosts={N_AIRCRAFT}", "dynamics=fixedwing",
          'commands.behaviour="formation"', "fidelity.log_rate=30.0", "f_trig=100.0")
NETWORKS: dict[str, tuple[Path | None, tuple[str, ...]]] = {
    "lossy": (SCENARIO_LOSSY, ()),
    "default": (None, ()),
    "ideal": (None, ('net.host_link.latency={dist="constant", value=0.0}',
                     'net.server_link.latency={dist="constant", value=0.0}')),
}
TURN_DEG = 15.0
TURN_START_DEG = 1.0
COLORS = {**common.COLORS, IDEAL: "#000000"}
UNITS = {"conv_h_s": "s", "conv_v_s": "s", "conv_h_s_mean": "s", "conv_h_s_max": "s",
         "conv_v_s_mean": "s", "conv_v_s_max": "s", "converged_h_frac": "",
         "converged_v_frac": "", "window_s": "s", "flight_s": "s", "slot_h_mean_m": "m",
         "slot_v_mean_m": "m", "slot_h_final_m": "m", "slot_v_final_m": "m",
         "formation_err_mean": "m", "formation_err_max": "m", "dtw_r": "m", "dtw_m": "m",
         "sim_duration_s": "s"}
CSV_COLUMNS = ("study", "network", "seed", "config_hash", "version", "method", "metric", "value",
               "unit")


# ------------------------------------------------------------------ set-up


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


def scenario(network: str, duration: float, seed: int) -> Scenario:
    """The scenario of one network, flight duration and seed."""
    path, extra = NETWORKS[network]
    warm = min(1.0, 0.2 * duration)
    return load(path, [*common.known(COMMON), *extra, f"duration={duration}", f"warmup={warm}",
                       f"seed={seed}"])


class StartAt:
    """A dynamics model whose ``initial_state`` is a given state (everything else delegated)."""

    def __init__(self, dynamics: Any, state: Array) -> None:
        self._dyn = dynamics
        self._state = np.array(state, dtype=np.float64)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._dyn, name)

    def initial_state(self, n: int) -> Array:
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


def slot_distances(t: Array, pos: Array) -> tuple[Array, Array, Array]:
    """Horizontal and vertical distance of every node to its slot, and the leader course.

    Args:
        t: ``(T,)`` sample times.
        pos: ``(T, n, 3)`` true positions (north, east, altitude).

    Returns:
        ``(dh (T, n), dv (T, n), course (T,))``; the leader's entries are 0.
    """
    lead = pos[:, LEADER, :2]
    vel = np.gradient(lead, t, axis=0) if len(t) > 1 else np.zeros_like(lead)
    course = np.arctan2(vel[:, 1], vel[:, 0])
    theta = math.radians(PAPER["theta_deg"])
    dh = np.empty(pos.shape[:2])
    obs = np.zeros((pos.shape[1], 12))
    for k in range(len(t)):
        obs[:, 9:12] = pos[k]
        obs[LEADER, 5] = course[k]
        slots = formation_slots(obs, LEADER, PAPER["d"], theta)
        dh[k] = np.hypot(pos[k, :, 0] - slots[:, 0], pos[k, :, 1] - slots[:, 1])
    dv = np.abs(pos[:, :, 2] - pos[:, LEADER, 2][:, None])
    return dh, dv, course


def window_end(t: Array, course: Array) -> float:
    """End of the convergence window: the leader's first turn, or the end of the flight."""
    if len(t) < 2:
        return float(t[-1]) if len(t) else 0.0
    c0 = course[min(len(course) - 1, 3)]                 # initial course (skip edge samples)
    dev = np.abs((course - c0 + np.pi) % (2 * np.pi) - np.pi)
    off = np.nonzero((dev > math.radians(TURN_DEG)) & (t > 1.0))[0]
    if not off.size:
        return float(t[-1])
    # Back to where that turn began (course within TURN_START_DEG of the initial one):
    # the slots start to swing as soon as the leader banks.
    calm = np.nonzero(dev[: off[0]] <= math.radians(TURN_START_DEG))[0]
    return float(t[calm[-1]]) if calm.size else float(t[off[0]])


def convergence_time(t: Array, d: Array, threshold: float, t_end: float) -> float:
    """First time after which ``d`` stays below ``threshold`` up to ``t_end`` (NaN: never)."""
    inside = t <= t_end + 1e-9
    tt, dd = t[inside], d[inside]
    if tt.size == 0 or dd[-1] >= threshold:
        return math.nan
    above = np.nonzero(dd >= threshold)[0]
    return float(tt[0]) if above.size == 0 else float(tt[above[-1] + 1])


def flight_metrics(t: Array, pos: Array, ideal: Array, args: argparse.Namespace
                   ) -> tuple[dict[str, float], dict[str, Array]]:
    """Convergence, slot distances, formation error and DTW of one flight (module doc)."""
    m: dict[str, float] = {}
    dh, dv, course = slot_distances(t, pos)
    t_end = window_end(t, course)
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
    run, out, engine = execute(sc, method, lambda: dyn, lambda: make_behaviour(sc))
    out["engine"] = engine
    t, pos = run.trajectory()
    return out, t, pos


def run_seed(args: argparse.Namespace, seed: int) -> dict[str, Any]:
    """The ideal run and every method for one seed."""
    sc = scenario(args.network, args.duration, seed)
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
        "command": common.command_line(NAME),
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
    common.write_summary(out, summary)


def fmt(x: float, spec: str = ".1f") -> str:
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
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True))
                     for r in rows)


def plots(args: argparse.Namespace, r: dict[str, Any]) -> None:
    """trajectories.png, convergence.png, formation_error.png (first seed)."""
    plt = common.plot_setup(args.quick)
    out = Path(args.out)
    labels = [IDEAL, *METHODS]
    seed = r["seed"]

    fig, axs = plt.subplots(1, len(labels), figsize=(3.6 * len(labels), 4.2), sharex=True,
                            sharey=True)
    for ax, lab in zip(axs, labels, strict=True):
        pos = r["traj"][lab]
        for k in range(pos.shape[1]):
            ax.plot(pos[:, k, 1], pos[:, k, 0], lw=1.4 if k == LEADER else 0.8,
                    color="k" if k == LEADER else f"C{k}",
                    label="leader" if k == LEADER else f"follower {k}")
            ax.plot(pos[-1, k, 1], pos[-1, k, 0], "o", ms=3, color="k" if k == LEADER else f"C{k}")
        ax.set_title(f"{lab} ({r['metrics'][lab]['flight_s']:.0f} s flight)")
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal", adjustable="box")
    axs[0].set_ylabel("north (m)")
    axs[0].legend(loc="best", fontsize=7)
    fig.suptitle(f"Trajectories, {args.network} network, seed {seed} (dot = end)")
    common.save(fig, out, "trajectories.png")

    fig, axs = plt.subplots(2, len(labels), figsize=(3.6 * len(labels), 6.2), sharex=True,
                            sharey="row")
    for col, lab in enumerate(labels):
        ser = r["series"][lab]
        for row, key, thr, name in ((0, "dh", args.h_threshold, "horizontal"),
                                    (1, "dv", args.v_threshold, "vertical")):
            ax = axs[row, col]
            for k in range(ser[key].shape[1]):
                if k == LEADER:
                    continue
                ax.plot(ser["t"], ser[key][:, k], lw=0.8, color=f"C{k}", label=f"follower {k}")
            ax.axhline(thr, color="k", ls="--", lw=0.8, label=f"threshold {thr:g} m")
            ax.axvline(float(ser["t_end"]), color="grey", ls=":", lw=0.8,
                       label="window end (1st turn)")
            ax.set_ylim(bottom=0.0)
            if col == 0:
                ax.set_ylabel(f"{name} distance to slot (m)")
            if row == 0:
                ax.set_title(lab)
            else:
                ax.set_xlabel("flight time (s)")
    axs[0, 0].legend(loc="upper right", fontsize=6)
    fig.suptitle(f"Convergence to the V slots, {args.network} network, seed {seed}")
    common.save(fig, out, "convergence.png")

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.2))
    for lab in METHODS:
        ser = r["series"][lab]
        n = len(ser["formation_err"])
        axs[0].plot(ser["t"][:n], ser["formation_err"], lw=0.8, color=COLORS.get(lab), label=lab)
    axs[0].set_xlabel("flight time (s)")
    axs[0].set_ylabel("formation (shape) error vs ideal (m)")
    axs[0].set_title("Formation error over time")
    axs[0].legend(loc="upper left")
    for lab in labels:
        ser = r["series"][lab]
        foll = [k for k in range(ser["dh"].shape[1]) if k != LEADER]
        axs[1].plot(ser["t"], ser["dh"][:, foll].mean(axis=1), lw=0.8, color=COLORS.get(lab),
                    label=lab)
    axs[1].set_yscale("log")
    axs[1].set_xlabel("flight time (s)")
    axs[1].set_ylabel("mean horizontal distance to slot (m)")
    axs[1].set_title("Followers' mean distance to slot")
    axs[1].legend(loc="upper right")
    x = np.arange(len(labels))
    ys = [r["metrics"][lab]["dtw_r"] for lab in labels]
    axs[2].bar(x, ys, color=[COLORS.get(lab) for lab in labels])
    axs[2].set_xticks(x, labels)
    axs[2].set_ylabel("normalised DTW to ideal, r = D·T/s (m)")
    axs[2].set_title("Trajectory DTW to the ideal run (mean over nodes)")
    for xi, y in zip(x, ys, strict=True):
        axs[2].annotate(f"{y:.3g}", (xi, y), ha="center", va="bottom", fontsize=8)
    common.save(fig, out, "formation_error.png")


# ------------------------------------------------------------------ main


def parser() -> argparse.ArgumentParser:
    p = common.study_parser(NAME, __doc__, default_seeds="1,2,3")
    p.add_argument("--network", choices=tuple(NETWORKS), default="lossy",
                   help="network between hosts and broker (default: lossy)")
    p.add_argument("--duration", type=float, default=None,
                   help="flight time, s (default 150; --quick: 6)")
    p.add_argument("--start", choices=("offset", "grid"), default="offset",
                   help="initial positions (default: followers offset from their slots)")
    p.add_argument("--offset", type=lambda s: tuple(float(x) for x in s.split(",")),
                   default=None, help="start offset from the slot 'H,V' in m "
                   "(default 20,8; --quick: 6,3)")
    p.add_argument("--h-threshold", type=float, default=5.0, help="horizontal threshold, m")
    p.add_argument("--v-threshold", type=float, default=2.0, help="vertical threshold, m")
    p.add_argument("--match-flight", dest="match_flight", action="store_true", default=None,
                   help="re-run a method that covered less flight with a longer simulated "
                   "duration (default in full mode)")
    p.add_argument("--no-match-flight", dest="match_flight", action="store_false")
    p.add_argument("--max-stretch", type=float, default=40.0,
                   help="--match-flight: longest simulated duration, in flight durations")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the study and write its outputs."""
    args = common.finish_args(parser().parse_args(argv))
    if args.duration is None:
        args.duration = 6.0 if args.quick else 150.0
    if args.offset is None:
        args.offset = (6.0, 3.0) if args.quick else (20.0, 8.0)
    if len(args.offset) != 2:
        raise SystemExit("--offset takes two numbers, H,V")
    if args.match_flight is None:
        args.match_flight = not args.quick
    params = check_paper_parameters()
    t0 = time.perf_counter()
    runs = [run_seed(args, seed) for seed in args.seeds]
    wall = time.perf_counter() - t0
    write_outputs(args, runs, params, wall)
    plots(args, runs[0])
    common.update_plot_list(Path(args.out))
    import json
    print(json.loads((Path(args.out) / "summary.json").read_text())["table"])
    print(f"wrote {args.out} ({wall:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
