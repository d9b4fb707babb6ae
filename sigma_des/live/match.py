"""Hop latencies matched to the calibration run: the calibrated DES re-predicts its own run.

``calibrate`` fits each hop's latency samples *net of* what it believes the DES adds on
the path (the sender's burst, the broker's services, waits for threads): a guess of
the DES's own waits, made before the DES ran. With waits that depend on load (the
CPU stage's run-queue waits, backlogs behind busy threads) the guess misses, and the
calibrated DES overshot its own calibration run's state latency by 12–53 % (LIVE.md,
sessions 11–13). :func:`match_hops` closes that loop by running the DES: each round
runs the calibrated scenario for every method of the live run, compares the mean
state latency and the mean trigger latency (each pooled over the methods) with the
live run's, and rescales each direction's hop samples (``hop_up``: the states' two
hops; ``hop_down``: the triggers') by the factor that removes the difference on the
two hops a message crosses, ``k' = k + (live - des) / (2 · mean hop)``, at least
:data:`K_MIN`. It stops when both directions are within :data:`MATCH_TOL` or after
:data:`MATCH_ROUNDS` rounds. A scale keeps each direction's distribution's shape (its
tail and its spread) and never makes a sample negative.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.config import Scenario
from sigma_des.guard import atomic_write, output_file
from sigma_des.net.latency import Dist, load_samples
from sigma_des.net.spec import LinkSpec

__all__ = ["K_MAX", "K_MIN", "MATCH_ROUNDS", "MATCH_TOL", "match_hops"]

#: Rounds of DES runs at most.
MATCH_ROUNDS = 6
#: Largest scale of a direction's hop samples.
K_MAX = 4.0
#: Relative difference of the pooled mean latencies a round stops at.
MATCH_TOL = 0.03
#: Smallest scale of a direction's hop samples.
K_MIN = 0.05


def _live_means(source: Path, sc: Scenario) -> tuple[float, float]:
    """The live run's mean state and trigger latency (ms), each the mean over methods."""
    from sigma_des.live.insample import live_trigger_latency

    summ = (source if source.is_dir() else source.parent) / "summary.json"
    methods = json.loads(summ.read_text()).get("methods", {}) if summ.exists() else {}
    up = [float(m["latency_state_mean"]) for m in methods.values()
          if m.get("latency_state_mean") is not None]
    trig = list(live_trigger_latency(source, sc).values())
    return (float(np.mean(up)) if up else math.nan,
            float(np.mean(trig)) if trig else math.nan)


def _des_means(sc: Scenario, methods: list[str]) -> tuple[float, float]:
    from sigma_des.api import run_method

    up, down = [], []
    for m in methods:
        met = run_method(sc, m)["metrics"]
        up.append(float(met["latency_state_mean"]))
        down.append(float(met["latency_trigger_mean"]))
    return float(np.mean(up)), float(np.mean(down))


def _scaled(sc: Scenario, files: dict[str, Path], k: dict[str, float], d: Path) -> Scenario:
    """``sc`` with every link latency reading ``files[name]`` reading a copy scaled by
    ``k[name]`` (``<name>_matched.txt`` in ``d``)."""
    new: dict[str, str] = {}
    for name, path in files.items():
        out = output_file(d / f"{name}_matched.txt", "--out")
        scaled = np.asarray(load_samples(str(path))) * k[name]
        atomic_write(out, partial(np.savetxt, X=scaled, fmt="%.9g"), "--out")
        new[str(path)] = str(out)

    def swap(dist: Dist) -> Dist:
        if dist.dist != "empirical" or dist.file not in new:
            return dist
        return Dist(dist="empirical", file=new[dist.file])

    def link(lk: LinkSpec) -> LinkSpec:
        down = lk.latency_down
        return replace(lk, latency=swap(lk.latency),
                       latency_down=None if down is None else swap(down))

    net = sc.net
    host, server = link(net.host_link), link(net.server_link)
    return replace(sc, net=replace(net, host_link=host, server_link=server))


def _next_scale(tried: list[tuple[float, float]], live: float, mean: float) -> float:
    """The next scale of one direction from the ``(scale, DES mean)`` pairs tried: the
    first step spreads the difference over the message's two hops (ms -> s); once
    pairs lie on both sides of ``live``, the secant through the closest pair on each
    side (it stays between them); before that, the secant through the last two pairs;
    always within ``[K_MIN, K_MAX]``."""
    k1, d1 = tried[-1]
    below = [p for p in tried if p[1] <= live]
    above = [p for p in tried if p[1] > live]
    if below and above:
        (k0, d0), (k1, d1) = max(below, key=lambda p: p[1]), min(above, key=lambda p: p[1])
        x = k0 + (live - d0) * (k1 - k0) / (d1 - d0)
    elif len(tried) > 1 and tried[-2][1] != d1:
        k0, d0 = tried[-2]
        x = k1 + (live - d1) * (k1 - k0) / (d1 - d0)
    else:
        x = k1 + (live - d1) / 1000.0 / (2.0 * mean)
    return min(max(x, K_MIN), K_MAX)


def match_hops(sc: Scenario, source: Path, d: Path) -> tuple[Scenario, dict[str, Any]]:
    """Rescale the calibrated hop samples until the DES re-predicts ``source``.

    Args:
        sc: the calibrated scenario (its host link's ``latency`` is the states' hop
            file, its ``latency_down`` the triggers').
        source: the live run it was fitted to (its ``summary.json`` and messages).
        d: where the matched sample files go.

    Returns:
        The scenario reading the matched files, and a report: each direction's scale,
        the rounds run, the live and DES pooled means of the last round.
    """
    live_up, live_down = _live_means(source, sc)
    lk = sc.net.host_link
    if lk.latency.dist != "empirical" or not math.isfinite(live_up):
        return sc, {"hop_match": "skipped (no empirical hop samples or no live latency)"}
    files = {"hop_up": Path(lk.latency.file)}
    down = lk.latency_down
    if (down is not None and down.dist == "empirical" and down.file != lk.latency.file
            and math.isfinite(live_down)):
        files["hop_down"] = Path(down.file)
    mean = {n: float(np.mean(load_samples(str(p)))) for n, p in files.items()}
    live = {"hop_up": live_up, "hop_down": live_down}
    k = dict.fromkeys(files, 1.0)
    methods = list(sc.methods)
    out = sc
    rounds = 0
    des: dict[str, float] = {}
    tried: dict[str, list[tuple[float, float]]] = {n: [] for n in files}
    for rounds in range(1, MATCH_ROUNDS + 1):
        des_up, des_down = _des_means(out, methods)
        des = {"hop_up": des_up, "hop_down": des_down}
        errs = {n: (des[n] - live[n]) / live[n] for n in files}
        if all(abs(e) <= MATCH_TOL for e in errs.values()) or rounds == MATCH_ROUNDS:
            break
        for n in files:
            tried[n].append((k[n], des[n]))
            k[n] = _next_scale(tried[n], live[n], mean[n])
        out = _scaled(sc, files, k, d)
    report = {"hop_match_rounds": rounds,
              **{f"{n}_scale": k[n] for n in files},
              **{f"{n}_live_ms": live[n] for n in files},
              **{f"{n}_des_ms": des[n] for n in files}}
    return out, report
