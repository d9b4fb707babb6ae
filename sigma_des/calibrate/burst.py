"""The host's burst in the calibrated state hops, rescaled to a target's nodes per host.

A calibrated state hop (``net.host_link.latency`` up to the broker and
``net.server_link.latency_down`` on to the server, from the calibration run's states,
then matched by re-running the simulation) is what is left of a state's live latency
once the simulation's own services and waits are taken out. Part of it a state pays
with nothing ahead of it; the rest is its wait behind the other states its host
published in the same turn (a host's ``m = nodes / hosts`` states leave within about a
millisecond). Drawn as a fixed delay at every size, that wait came out too long at
fewer nodes per host and too short at more.

:func:`floor_share` measures the first part on the calibration run (the report's
``hop_floor_share``); :func:`burst_ratio` is how much longer the wait is at the
target: a first-in, first-out burst of ``m`` keeps on average ``(m - 1) / 2``
messages ahead of a message, so ``(m_target - 1) / (m_cal - 1)``.
:func:`scale_state_hops` multiplies every state-hop sample by
``floor + (1 - floor) · ratio`` (:func:`state_hop_factor`); the trigger and command
hops carry no host burst and are kept. Never rescaled: a calibration at one node per
host (no burst seen).

A bundled target's turn leaves in a few PUBLISHes, not a burst of ``m``, yet live's
bundled states take longer from stamp to server than the simulation of its bundles
says, by more the more states the server takes a frame. A campaign with a bundled run
measures that excess: :func:`~sigma_des.calibrate.match.match_bundled` scales the state
hops until the simulation re-predicts the bundled run (``bundle_hop_scale`` ``f`` at its
``bundle_hop_nodes`` ``N_b``), and a bundled target of ``N`` nodes has its state hops
multiplied by ``1 + (f - 1) · (N - 1) / (N_b - 1)`` (:func:`bundle_hop_factor`). Rules
and measurements: docs/concepts/decisions.md ("State hops scaled with the host's
burst", "Bundled state hops matched on a bundled run").
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import Scenario
from sigma_des.net.latency import Dist, load_samples

__all__ = ["bundle_hop_factor", "burst_ratio", "calibration_nodes_per_host", "floor_share",
           "scale_state_hops", "state_hop_factor"]


def calibration_nodes_per_host(cal: Scenario, report: dict[str, Any]) -> float:
    """Nodes per host of the runs the state-hop samples came from: the report's
    ``hop_nodes_per_host`` (a campaign's runs, weighted by their states), else the
    calibrated scenario's ``nodes / hosts`` (its primary run's)."""
    v = report.get("hop_nodes_per_host")
    if isinstance(v, int | float) and math.isfinite(v) and v > 0:
        return float(v)
    return cal.nodes / cal.hosts


def burst_ratio(m_cal: float, m_target: float) -> float:
    """``(m_target - 1) / (m_cal - 1)``: the mean number of a host's other states ahead
    of a state in its turn's burst at the target over that at the calibration; 1 when
    the calibration had at most one node per host (no burst to scale)."""
    if not m_cal > 1.0:
        return 1.0
    return max(m_target - 1.0, 0.0) / (m_cal - 1.0)


def floor_share(states: pd.DataFrame) -> float:
    """The share of the calibration run's state latency a state pays with nothing of its
    host's turn ahead of it: the mean latency of the first state each host published in
    a turn, over the mean of all states (each a mean of the methods' means), from
    Lock-Step's turns when the run has them (Lock-Step issues a trigger only once every
    state is in, so no earlier turn is still draining), else every method's. NaN
    without states.

    Args:
        states: the window's states: ``method``, ``frame``, ``host``, ``t_send``,
            ``t_recv``.
    """
    if states.empty:
        return math.nan
    s = states.assign(lat=states["t_recv"] - states["t_send"])
    rank = s.groupby(["method", "frame", "host"])["t_send"].rank(method="first")
    first = s[rank == 1.0].groupby("method")["lat"].mean()
    pooled = float(s.groupby("method")["lat"].mean().mean())
    ahead = float(first["lockstep"]) if "lockstep" in first.index else float(first.mean())
    return min(max(ahead / pooled, 0.0), 1.0) if pooled > 0 else math.nan


def state_hop_factor(m_cal: float, m_target: float, floor: float) -> float:
    """What the state-hop samples are multiplied by: ``floor`` of them kept, the rest
    scaled by :func:`burst_ratio` (``floor`` outside ``[0, 1]`` or NaN: 0)."""
    f = floor if math.isfinite(floor) and 0.0 <= floor <= 1.0 else 0.0
    return f + (1.0 - f) * burst_ratio(m_cal, m_target)


def bundle_hop_factor(report: dict[str, Any], n_target: float) -> float:
    """What the state-hop samples of a bundled target of ``n_target`` nodes are
    multiplied by: ``1 + (f - 1) · burst_ratio(N_b, n_target)`` with ``f`` the report's
    ``bundle_hop_scale`` and ``N_b`` its ``bundle_hop_nodes`` (the states ahead of one
    in the server's frame, as :func:`burst_ratio` counts a host's); 1 when the
    calibration matched no bundled run (either missing or not a finite positive
    number). Never below 0."""
    f = report.get("bundle_hop_scale")
    n_b = report.get("bundle_hop_nodes")
    if not (isinstance(f, int | float) and isinstance(n_b, int | float)
            and math.isfinite(f) and math.isfinite(n_b) and f > 0 and n_b > 0):
        return 1.0
    return max(1.0 + (float(f) - 1.0) * burst_ratio(float(n_b), n_target), 0.0)


def scale_state_hops(sc: Scenario, ratio: float, d: Path) -> Scenario:
    """``sc`` with its two state hops' empirical samples multiplied by ``ratio`` (copies
    in ``d``); ``sc`` itself when ``ratio`` is 1 or the hops are not empirical (a
    constant or parametric latency is a user's, not a calibration's)."""
    if ratio == 1.0:
        return sc
    net = sc.net
    up, down = net.host_link.latency, net.server_link.latency_down
    if up.dist != "empirical" or down is None or down.dist != "empirical":
        return sc
    made: dict[str, Dist] = {}

    def scaled(dist: Dist) -> Dist:
        if dist.file not in made:
            d.mkdir(parents=True, exist_ok=True)
            path = d / f"{Path(dist.file).stem}_burst_x{ratio:.6g}.txt"
            np.savetxt(path, np.asarray(load_samples(dist.file)) * ratio, fmt="%.9g")
            made[dist.file] = Dist(dist="empirical", file=str(path))
        return made[dist.file]

    keep = net.host_link.latency_down  # the triggers' hop: unscaled, even when it was
    host = replace(net.host_link, latency=scaled(up),  # the up latency's default
                   latency_down=up if keep is None else keep)
    server = replace(net.server_link, latency_down=scaled(down))
    return replace(sc, net=replace(net, host_link=host, server_link=server))
