"""A calibrated scenario prepared for a target, and the DES's figures of it.

One function, :func:`prepare`, turns a calibration (the scenario ``calibrate`` wrote
and its report) into the DES scenario of a target setting; ``sigma-des predict``,
``sigma-des capacity`` and the validation suite all call it, so a prediction a user
makes is the one the validation scored:

* the target's keys (``--set KEY=VALUE``) on the calibrated scenario;
* bundled messages (``--bundle``): one client per host and a host's states of one
  turn in one PUBLISH (``deployment.clients = "host"``, ``deployment.bundle = true``),
  as live ``--bundle`` runs them;
* the broker's per-delivery service for the target
  (:func:`~sigma_des.calibrate.fit.for_target`: rescaled to ``hosts / nodes`` unless the
  DES has one client per host);
* the state hops' samples scaled to the target's nodes per host
  (:mod:`sigma_des.calibrate.burst`): with one PUBLISH per state, by the wait behind
  the host's burst they hold; bundled, by the excess the calibration's bundled run
  showed, grown with the target's nodes (none without one);
* an added latency (``--add-latency``) shifts every calibrated host-link sample by that
  much in both directions (:func:`shift_host_link`), as the live shim adds it to each
  host-link crossing.

:func:`des_figures` runs one method and returns the figures the validation compares:
mean and p99 AoI, mean state latency, achieved trigger rate and the missed-frame
fraction counted with the live runner's definition (:class:`MissedTap`), plus the
machine's CPU utilisation that decides the regime of an interval.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.calibrate.burst import (
    bundle_hop_factor,
    calibration_nodes_per_host,
    scale_state_hops,
    state_hop_factor,
)
from sigma_des.calibrate.fit import for_target
from sigma_des.config import Scenario
from sigma_des.errors import ConfigError
from sigma_des.events.tap import Tap
from sigma_des.net.latency import Dist, load_samples

__all__ = ["BUNDLE_SETS", "FIGURES", "MissedTap", "des_figures", "for_run", "prepare",
           "shift_host_link", "state_hop_ratio"]

#: The figures a prediction reports and the validation scores, in table order.
FIGURES = ("aoi_mean", "aoi_p99", "latency_state_mean", "trigger_rate_hz", "missed_frac")
#: The keys of bundled messages (live ``--bundle``).
BUNDLE_SETS = ('deployment.clients="host"', "deployment.bundle=true")
#: The largest latency ``prepare`` adds (s): beyond, a target is not a calibrated one.
MAX_ADD_LATENCY_S = 1.0


def shift_host_link(sc: Scenario, delta: float, d: Path) -> Scenario:
    """``sc`` with ``delta`` seconds added to every host-link latency draw, both
    directions (the live shim adds it on the host link each way).

    An empirical latency gets a shifted copy of its sample file in ``d``; a constant is
    shifted exactly; any other distribution is refused.

    Raises:
        ConfigError: (``net.host_link.latency``) a latency that is neither.
    """
    def shifted(dist: Dist, name: str) -> Dist:
        if dist.dist == "constant":
            return Dist(dist="constant", value=dist.value + delta)
        if dist.dist != "empirical":
            raise ConfigError("net.host_link.latency", f"cannot shift a {dist.dist!r} "
                              "latency; expected calibrate's empirical samples or a constant")
        d.mkdir(parents=True, exist_ok=True)
        path = d / f"{name}_plus_{delta * 1e3:g}ms.txt"
        np.savetxt(path, np.asarray(load_samples(dist.file)) + delta, fmt="%.9g")
        return Dist(dist="empirical", file=str(path))

    link = sc.net.host_link
    down = link.latency_down if link.latency_down is not None else link.latency
    link = replace(link, latency=shifted(link.latency, "host_up"),
                   latency_down=shifted(down, "host_down"))
    return replace(sc, net=replace(sc.net, host_link=link))


def prepare(cal: Scenario, report: dict[str, Any], sets: list[str], *, bundle: bool = False,
            add_latency_s: float = 0.0, samples_dir: Path | None = None) -> Scenario:
    """The calibrated scenario prepared for a target (see the module doc).

    Args:
        cal: the calibrated scenario (``sigma-des calibrate --out``).
        report: its report (the JSON next to it).
        sets: the target's keys, ``key=value``.
        bundle: bundled messages, as live ``--bundle``; without it one PUBLISH per state
            (even when the calibration's primary run was bundled), unless ``sets``
            says otherwise.
        add_latency_s: seconds added to each host-link crossing (0..1).
        samples_dir: where scaled and shifted sample files go (None: a directory
            of this process's, removed when it exits).

    Raises:
        ConfigError: a bad key (named), ``--add-latency`` out of range, or a report
            without ``delivery_service_per_client_s``.
    """
    if not (math.isfinite(add_latency_s) and 0.0 <= add_latency_s <= MAX_ADD_LATENCY_S):
        raise ConfigError("--add-latency", f"must be in 0..{MAX_ADD_LATENCY_S * 1e3:g} ms, "
                          f"got {add_latency_s * 1e3:g}")
    if "delivery_service_per_client_s" not in report:
        raise ConfigError("calibration", "the report has no delivery_service_per_client_s; "
                          "recalibrate with this version of `sigma-des calibrate`")
    mode = BUNDLE_SETS if bundle else ()
    sc = for_target(cal, report, [*(() if bundle else ("deployment.bundle=false",)), *sets,
                                  *mode])
    ratio, _rule = state_hop_ratio(cal, report, sc)
    if ratio != 1.0:
        sc = scale_state_hops(sc, ratio, samples_dir or _own_dir())
    if add_latency_s > 0.0:
        sc = shift_host_link(sc, add_latency_s, samples_dir or _own_dir())
    return sc


def for_run(cal: Scenario, report: dict[str, Any], run: Scenario, *, bundle: bool
            ) -> Scenario:
    """The calibration prepared for one of its own live runs (``run``: that run's fit):
    its size, hosts, window and seed, its message mode, and its measured background
    (what re-predicting that run needs: the in-sample check, the bundled match)."""
    sc = prepare(cal, report, [f"nodes={run.nodes}", f"hosts={run.hosts}",
                               f"duration={run.duration}", f"warmup={run.warmup}",
                               f"seed={run.seed}"], bundle=bundle)
    return replace(sc, deployment=replace(sc.deployment,
                                          background=run.deployment.background))


def state_hop_ratio(cal: Scenario, report: dict[str, Any], sc: Scenario) -> tuple[float, str]:
    """What :func:`prepare` multiplies target ``sc``'s state-hop samples by, and the rule
    (see the module doc): bundled, the bundled run's matched factor grown with the
    nodes (1 without one); per node, the host's burst."""
    if sc.deployment.bundle:  # a bundled turn is no burst of m: its own excess
        if "bundle_hop_scale" not in report:
            return 1.0, "bundled; no bundled calibration run: as calibrated"
        return (bundle_hop_factor(report, sc.nodes),
                f"bundled; matched on a run of {report.get('bundle_hop_nodes', '?'):g} nodes"
                if isinstance(report.get("bundle_hop_nodes"), int | float)
                else "bundled; matched on the bundled run")
    m = sc.nodes / sc.hosts
    return (state_hop_factor(calibration_nodes_per_host(cal, report), m,
                             float(report.get("hop_floor_share", 0.0))),
            f"per node; the host's burst at {m:g} nodes a host")


_DIR: list[tempfile.TemporaryDirectory[str]] = []


def _own_dir() -> Path:
    """A directory for this process's sample files, removed when it exits."""
    if not _DIR:
        _DIR.append(tempfile.TemporaryDirectory(prefix="sigma-des-samples-"))
    return Path(_DIR[0].name)


class MissedTap(Tap):
    """Counts what the live runner's missed-frame fraction needs: the frames whose
    trigger left in the window, and the (node, frame) states that reached the server."""

    def __init__(self, warmup: float, duration: float) -> None:
        self.window = (warmup, duration)
        self.frames: set[int] = set()
        self.got: list[NDArray[np.int64]] = []

    def issue(self, frame: int, t_send: float) -> None:
        """A trigger's issue: its frame counts if it left in the window (the issue, not
        the deliveries: a frame whose trigger reached no node in time counts too, as
        live's runner counts the triggers it sent)."""
        if self.window[0] <= t_send < self.window[1]:
            self.frames.add(int(frame))

    def states(self, t_recv: NDArray[np.float64], nodes: NDArray[np.int64],
               frames: NDArray[np.int64], gens: NDArray[np.float64],
               obs: NDArray[np.float64]) -> None:
        """State deliveries to the server."""
        self.got.append(np.asarray(frames, dtype=np.int64) * (1 << 32)
                        + np.asarray(nodes, dtype=np.int64))

    def missed_frac(self, nodes: int) -> float:
        """``1 - delivered / (window frames x nodes)``; NaN without a trigger."""
        if not self.frames:
            return math.nan
        keys = np.unique(np.concatenate(self.got)) if self.got else np.zeros(0, np.int64)
        fr = np.fromiter(self.frames, dtype=np.int64)
        return 1.0 - int(np.isin(keys >> 32, fr).sum()) / (fr.size * nodes)


def _num(v: Any) -> float:
    return float(v) if isinstance(v, int | float) else math.nan


def des_figures(sc: Scenario, method: str) -> dict[str, Any]:
    """One DES run of ``method``: :data:`FIGURES`, ``machine_cpu_util_max`` (NaN without
    a CPU stage) and the engine used (``engine``, ``fallback``)."""
    from sigma_des.events.cohort import execute
    from sigma_des.factory import make_behaviour, make_dynamics

    taps: list[MissedTap] = []

    def tap() -> Tap:
        taps.append(MissedTap(sc.warmup, sc.duration))
        return taps[-1]

    _run, out, engine = execute(sc.run_spec(), method, lambda: make_dynamics(sc),
                                lambda: make_behaviour(sc), None, tap)
    m = out["metrics"]
    figs = {k: _num(m.get(k)) for k in FIGURES if k != "missed_frac"}
    figs["missed_frac"] = taps[-1].missed_frac(sc.nodes)
    figs["machine_cpu_util_max"] = _num(m.get("machine_cpu_util_max"))
    return {**figs, "engine": engine["used"], "fallback": engine["fallback"]}
