"""Hop latencies matched to the calibration run: the calibrated DES re-predicts its own run.

``calibrate`` fits each hop's latency samples *net of* what it believes the DES adds on
the path (the sender's burst, the broker's services, waits for threads): a guess of
the DES's own waits, made before the DES ran. With waits that depend on load (the
CPU stage's run-queue waits, backlogs behind busy threads) the guess misses, and the
calibrated DES overshot its own calibration run's state latency by 12–53 %
(docs/concepts/decisions.md). :func:`match_hops` closes that loop by running the DES: each round
runs the calibrated scenario for every method of the live run, compares the mean
state latency and the mean trigger latency (each pooled over the methods) with the
live run's, and rescales each direction's hop samples (``hop_up``: the states' two
hops; ``hop_down``: the triggers') by the factor that removes the difference on the
two hops a message crosses, ``k' = k + (live - des) / (2 · mean hop)``, at least
:data:`K_MIN`. It stops when both directions are within :data:`MATCH_TOL` or after
:data:`MATCH_ROUNDS` rounds. A scale keeps each direction's distribution's shape (its
tail and its spread) and never makes a sample negative.

The same rounds match each process kind's CPU (``server``: its process; ``host``: the
busiest host's, as the DES's ``host_cpu_util_max``; each the mean over the methods of
the live run's ``cpu.csv`` and of the DES's metrics) by scaling the wake-up's part
beside the thread (``deployment.<kind>_wake_side``), the secant again, within
``[0, SIDE_MAX]`` times the fitted value. *Why*: the Utilization Law splits the live CPU
over live's wake-ups, and the DES's messages, timed by its own draws, find a thread
idle less often than live's do (on a calibration run: the server 0.21 wake-ups a
message against live's 0.53), so the fitted demands gave the DES half of live's CPU, and
its machine's load (which sets the run-queue waits) half of live's. The part beside the
thread is the one that can take the difference without changing how often the thread
is idle. :func:`match_bundled` then scales the state hops alone on a bundled run.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.config import Scenario
from sigma_des.guard import atomic_write, output_file
from sigma_des.net.latency import Dist, load_samples
from sigma_des.net.spec import LinkSpec

__all__ = ["K_MAX", "K_MIN", "MATCH_ROUNDS", "MATCH_TOL", "SIDE_MAX", "match_bundled",
           "match_hops"]

#: Rounds of DES runs at most.
MATCH_ROUNDS = 16
#: Largest scale of a wake-up's part beside the thread.
SIDE_MAX = 8.0
#: The DES metric and the ``deployment`` key each process kind's CPU is matched with
#: (the part beside the thread: per wake-up of the loop or, with a network thread, of
#: that thread).
CPU_KEYS = {"server": ("server_cpu_util", "server_wake_side"),
            "host": ("host_cpu_util_max", "host_wake_side")}
#: Largest scale of a direction's hop samples.
K_MAX = 4.0
#: Relative difference of the pooled mean latencies a round stops at.
MATCH_TOL = 0.03
#: Smallest scale of a direction's hop samples.
K_MIN = 0.05
#: Relative difference of the other scales within which a round's pair still counts.
SAME_REL = 0.02


def _live_means(source: Path, sc: Scenario) -> tuple[float, float]:
    """The live run's mean state and trigger latency (ms), each the mean over methods."""
    from sigma_des.calibrate.insample import live_trigger_latency

    summ = (source if source.is_dir() else source.parent) / "summary.json"
    methods = json.loads(summ.read_text()).get("methods", {}) if summ.exists() else {}
    up = [float(m["latency_state_mean"]) for m in methods.values()
          if m.get("latency_state_mean") is not None]
    trig = list(live_trigger_latency(source, sc).values())
    return (float(np.mean(up)) if up else math.nan,
            float(np.mean(trig)) if trig else math.nan)


def _live_cpu(source: Path) -> dict[str, float]:
    """The live run's CPU per process kind (cores), each the mean over the methods:
    the server's process, the busiest host's; empty without a ``cpu.csv``."""
    from sigma_des.calibrate.demands import kind_rows, read_cpu

    cpu = read_cpu(source)
    if cpu is None or "cpu_s" not in cpu.columns:
        return {}
    c = cpu.assign(cores=cpu["cpu_s"] / cpu["window_s"])
    srv = kind_rows(c, "server").groupby("method")["cores"].mean()
    host = kind_rows(c, "host").groupby("method")["cores"].max()
    out = {"server": float(srv.mean()) if len(srv) else math.nan,
           "host": float(host.mean()) if len(host) else math.nan}
    return {k: v for k, v in out.items() if math.isfinite(v) and v > 0}


def _des_means(sc: Scenario, methods: list[str]) -> dict[str, float]:
    """The DES's pooled means over ``methods``: ``hop_up``, ``hop_down`` (ms) and each
    kind's CPU (cores, NaN without a CPU stage)."""
    from sigma_des.api import run_method

    rows = [run_method(sc, m)["metrics"] for m in methods]

    def mean(key: str) -> float:
        return float(np.mean([float(r.get(key, math.nan)) for r in rows]))

    return {"hop_up": mean("latency_state_mean"), "hop_down": mean("latency_trigger_mean"),
            **{kind: mean(metric) for kind, (metric, _k) in CPU_KEYS.items()}}


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


def _next_scale(tried: list[tuple[float, float]], live: float, first: float,
                lo: float = K_MIN, hi: float = K_MAX) -> float:
    """The next scale from the ``(scale, DES value)`` pairs tried: the first step is
    ``first``; once pairs lie on both sides of ``live``, the secant through the closest
    pair on each side (it stays between them); before that, the secant through the
    last two pairs; always within ``[lo, hi]``."""
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
        x = first
    return min(max(x, lo), hi)


def _with_sides(sc: Scenario, base: Scenario, k: dict[str, float]) -> Scenario:
    """``sc`` with each matched kind's side part ``base``'s times ``k[kind]``."""
    dep = sc.deployment
    for kind, (_metric, key) in CPU_KEYS.items():
        if kind in k:
            dep = replace(dep, **{key: getattr(base.deployment, key) * k[kind]})
    return replace(sc, deployment=dep)


def _first(name: str, k: float, live: float, des: float, mean: dict[str, float]) -> float:
    """The first step: a hop's spreads the difference over the message's two hops (ms
    -> s); a kind's CPU scales its side part by the CPU's ratio."""
    if name in mean:  # an all-zero sample set: no scale moves it
        return k + (live - des) / 1000.0 / (2.0 * mean[name]) if mean[name] > 0 else k
    return k * live / des if des > 0 else k


def _pairs(tried: list[tuple[dict[str, float], dict[str, float]]], now: dict[str, float],
           name: str) -> list[tuple[float, float]]:
    """``name``'s ``(scale, DES value)`` pairs from the rounds whose *other* scales were
    within :data:`SAME_REL` of ``now``'s. *Why*: a round moves every scale at once, and
    a side part's CPU also lengthens the latency, so a pair from a round with other
    side parts is not a point of the same curve (on one calibration run the stale
    pairs held the up hop's scale still for five rounds, 9 % off live)."""
    def same(ks: dict[str, float]) -> bool:
        return all(abs(v - now[o]) <= SAME_REL * max(abs(now[o]), 1e-12)
                   for o, v in ks.items() if o != name)
    return [(ks[name], des[name]) for ks, des in tried if same(ks)]


def match_hops(sc: Scenario, source: Path, d: Path) -> tuple[Scenario, dict[str, Any]]:
    """Rescale the calibrated hop samples (and the wake-ups' parts beside the thread)
    until the DES re-predicts ``source``.

    Args:
        sc: the calibrated scenario (its host link's ``latency`` is the states' hop
            file, its ``latency_down`` the triggers').
        source: the live run it was fitted to (its ``summary.json``, messages and
            ``cpu.csv``).
        d: where the matched sample files go.

    Returns:
        The scenario reading the matched files, and a report: each direction's and
        kind's scale, the rounds run, the live and DES pooled means of the last round.
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
    fixed = [n for n, v in mean.items() if not v > 0]  # all zero: no scale moves them
    files = {n: p for n, p in files.items() if n not in fixed}
    live = {"hop_up": live_up, "hop_down": live_down, **_live_cpu(source)}
    kinds = [kind for kind, (_m, key) in CPU_KEYS.items()
             if kind in live and getattr(sc.deployment, key) > 0.0]
    names = [*files, *kinds]
    k = dict.fromkeys(names, 1.0)
    methods = list(sc.methods)
    out = sc
    rounds = 0
    des: dict[str, float] = {}
    tried: list[tuple[dict[str, float], dict[str, float]]] = []
    for rounds in range(1, MATCH_ROUNDS + 1):
        des = _des_means(out, methods)
        errs = {n: (des[n] - live[n]) / live[n] for n in names}
        if all(abs(e) <= MATCH_TOL for e in errs.values()) or rounds == MATCH_ROUNDS:
            break
        tried.append((dict(k), des))
        now = dict(k)
        for n in names:
            first = _first(n, now[n], live[n], des[n], mean)
            pairs = _pairs(tried, now, n)
            k[n] = (_next_scale(pairs, live[n], first) if n in files
                    else _next_scale(pairs, live[n], first, 0.0, SIDE_MAX))
        out = _with_sides(_scaled(sc, files, k, d), sc, k)
    unit = {n: "ms" if n in files else "cores" for n in names}
    report = {"hop_match_rounds": rounds, "hop_match_unscalable": ", ".join(fixed) or "none",
              **{f"{n}_scale" if n in files else f"{n}_side_scale": k[n] for n in names},
              **{f"{n}_live_{unit[n]}": live[n] for n in names},
              **{f"{n}_des_{unit[n]}": des[n] for n in names}}
    return out, report


def match_bundled(sc: Scenario, report: dict[str, Any], own: Scenario,
                  source: Path | Sequence[Path], name: str) -> dict[str, Any]:
    """Scale the state hops of ``sc`` (matched on a per-node run) prepared for a bundled
    run of the campaign until the DES re-predicts that run's mean state latency
    (pooled over its methods, the run's own background), or the mean of several runs
    of that setting: the factor a bundled target gets at that run's nodes
    (:func:`~sigma_des.calibrate.burst.bundle_hop_factor`). Repeats matter: one
    bundled run's latency varies by 10–20 % from run to run, and the factor carries
    that error, grown, to every larger bundled target.

    Args:
        sc: the calibrated scenario after :func:`match_hops`.
        report: its report (any earlier ``bundle_hop_*`` keys are ignored).
        own: the bundled run's own fit (its size, hosts, window, seed, background).
        source: the bundled live run, or the runs of its setting (the target is the
            mean of their pooled latencies).
        name: the run's (or runs') name, for the report.

    Returns:
        ``bundle_hop_scale`` (the factor), ``bundle_hop_nodes`` (the run's),
        ``bundle_hop_run``, the rounds and the live and DES pooled means (ms); or
        ``bundle_hop_match`` saying why it was skipped.
    """
    import tempfile

    from sigma_des.calibrate.burst import scale_state_hops
    from sigma_des.calibrate.target import for_run

    runs = [source] if isinstance(source, Path) else list(source)
    means = [m for m in (_live_means(r, own)[0] for r in runs) if math.isfinite(m)]
    live = math.fsum(means) / len(means) if means else math.nan  # any order: the same
    rep = {k: v for k, v in report.items() if not k.startswith("bundle_hop_")}
    base = for_run(sc, rep, own, bundle=True)
    up, down = base.net.host_link.latency, base.net.server_link.latency_down
    if (up.dist != "empirical" or down is None or down.dist != "empirical"
            or not math.isfinite(live)):
        return {"bundle_hop_match": "skipped (no empirical state hops or no live latency)"}
    hop = float(np.mean(load_samples(up.file))) + float(np.mean(load_samples(down.file)))
    methods = list(base.methods)
    k, des, rounds = 1.0, math.nan, 0
    tried: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory(prefix="sigma_des_bundled_") as tmp:
        for rounds in range(1, MATCH_ROUNDS + 1):
            des = _des_means(scale_state_hops(base, k, Path(tmp)), methods)["hop_up"]
            if abs(des - live) <= MATCH_TOL * live or rounds == MATCH_ROUNDS:
                break
            tried.append((k, des))
            first = k + (live - des) / 1000.0 / hop if hop > 0 else k
            k = _next_scale(tried, live, first)
    out: dict[str, Any] = {"bundle_hop_scale": k, "bundle_hop_nodes": float(own.nodes),
                           "bundle_hop_run": name, "bundle_hop_runs": float(len(means)),
                           "bundle_hop_rounds": rounds,
                           "bundle_hop_live_ms": live, "bundle_hop_des_ms": des}
    if abs(des - live) > MATCH_TOL * live:  # at a bound of the scale, or out of rounds
        out["bundle_hop_warning"] = (
            f"{name}: the bundled state hops matched only to {des:.3g} ms against live's "
            f"{live:.3g} (scale {k:.3g}, within {K_MIN:g}..{K_MAX:g})")
    return out
