"""The interpolation study's runs: dense flights, sparse noisy logs, scores per method.

``experiments/interpolation.py`` (the script: command line, plots, outputs) runs
:func:`run` (every aircraft type × seed × noise × log rate × method, plus the window
rule ablation at the headline rate) and :func:`aggregate` (means over seeds). The
flights, logs and scores are :mod:`sigma_lab.studies.interpolation_flights`'s.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

import sigma_des
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.formation import FormationRoute
from sigma_des.agents.registry import make_dynamics
from sigma_des.agents.wind import WindConfig
from sigma_des.replay import INTERP_METHODS, RULES, WindowRule
from sigma_lab.studies.interpolation_flights import Flight, Noise, dense_flight, score, sparse_log

DT = 0.01
RATES = (1.0, 2.0, 5.0, 10.0, 25.0)
HEADLINE = 2.0
WINDOWS = (1, 2, 3)
NOISE = {"noisy": Noise(0.05, 0.1, 0.01), "clean": Noise(0.0, 0.0, 0.0)}
KIND = {"fixedwing": "fixed-wing", "quadrotor": "multirotor", "jsbsim:c172x": "fixed-wing",
        "jsbsim:F450": "multirotor"}
COLUMNS = ("study", "aircraft", "kind", "noise", "rate_hz", "method", "window", "seed",
           "version", "metric", "value", "unit")



def fly(aircraft: str, n: int, duration: float, seed: int) -> Flight:
    """The dense flight of one aircraft type (see the module doc)."""
    wind = WindConfig(mean_ned=(3.0, 2.0, 0.0), w20=15.4)
    if aircraft == "fixedwing":
        return dense_flight(GeneralAircraft("fixedwing", wind=wind, seed=seed),
                            FormationRoute(size=(400.0, 300.0)), n, duration, DT)
    if aircraft == "quadrotor":
        return dense_flight(GeneralAircraft("quadrotor", wind=wind, seed=seed),
                            FormationRoute(size=(200.0, 150.0), v_cru=10.0), n, duration, DT)
    if aircraft == "jsbsim:c172x":
        return dense_flight(make_dynamics(aircraft), FormationRoute(v_cru=50.0), n, duration,
                            DT)
    return dense_flight(make_dynamics(aircraft), FormationRoute(size=(200.0, 150.0),
                                                                v_cru=10.0), n, duration, DT)


def rows_of(base: dict[str, Any], res: dict[str, float]) -> list[dict[str, Any]]:
    """Tidy rows of one scored case: ``base`` plus every metric (m, or a count)."""
    return [{**base, "metric": k, "value": v, "unit": "m" if k != "n" else "count"}
            for k, v in res.items()]


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Fly, log and score every aircraft type, seed, noise, rate and method.

    ``args``: ``quick``, ``seeds`` (a count, None: 3; quick 1) and ``no_jsbsim``.
    Returns the rows, the first seed's noisy headline flights (for the plots), the
    seeds, the aircraft types, the nodes per flight and the flight duration.
    """
    seeds = list(range(1, (args.seeds or (1 if args.quick else 3)) + 1))
    types = ["fixedwing", "quadrotor"]
    if not args.no_jsbsim and not args.quick:
        types += ["jsbsim:c172x", "jsbsim:F450"]
    n, duration = (2, 20.0) if args.quick else (3, 90.0)
    rows: list[dict[str, Any]] = []
    flights: dict[str, tuple[Flight, Flight, np.ndarray]] = {}
    for ac in types:
        for seed in seeds:
            f = fly(ac, n, duration, seed)
            for noise, nz in NOISE.items():
                for rate in RATES:
                    idx, log = sparse_log(f, int(round(1 / (rate * DT))), nz, seed)
                    base = {"study": "interpolation", "aircraft": ac, "kind": KIND[ac],
                            "noise": noise, "rate_hz": rate, "seed": seed,
                            "version": sigma_des.__version__}
                    for m in INTERP_METHODS:
                        rows += rows_of({**base, "method": m, "window": "both-w1"},
                                        score(f, idx, log, m))
                    if rate == HEADLINE:
                        for w in WINDOWS:
                            for rule in RULES:
                                if rule == "none" and w > 1:
                                    continue
                                res = score(f, idx, log, "hermite-dw", WindowRule(rule=rule, w=w))
                                rows += rows_of({**base, "method": "ablation",
                                                 "window": f"{rule}-w{w}"}, res)
                        if noise == "noisy" and seed == seeds[0]:
                            flights[ac] = (f, log, idx)
    return {"rows": rows, "flights": flights, "seeds": seeds, "types": types, "n": n,
            "duration": duration}


def aggregate(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean over seeds: ``[aircraft][noise][rate][method or window][metric]``."""
    acc: dict[tuple[Any, ...], list[float]] = {}
    for r in rows:
        key = (r["aircraft"], r["noise"], r["rate_hz"],
               r["method"] if r["method"] != "ablation" else "ablation:" + r["window"],
               r["metric"])
        acc.setdefault(key, []).append(float(r["value"]))
    out: dict[str, Any] = {}
    for (ac, nz, rate, m, met), vs in acc.items():
        out.setdefault(ac, {}).setdefault(nz, {}).setdefault(str(rate), {}).setdefault(
            m, {})[met] = float(np.mean(vs))
    return out
