"""The host's burst in the calibrated state hops, rescaled to a target's nodes per host.

A calibrated state hop (``net.host_link.latency`` up to the broker and
``net.server_link.latency_down`` on to the server, both read from the calibration
run's state samples, then matched by re-running the simulation) is what is left of a
state's live latency once the simulation's own services and waits are taken out. On
the loopback of a live run the wire itself is a few tens of µs; most of what is left
is the wait of a state behind the other states its host published in the same turn
(each host's ``m = nodes / hosts`` states leave within about a millisecond and queue
on the host's sending path and the broker's). Drawn as a fixed delay at every size,
that wait came out too long at fewer nodes per host and too short at more.

:func:`burst_ratio` is how much longer that wait is at the target: in a first-in,
first-out queue a burst of ``m`` messages arriving together, each served in turn,
keeps on average ``(m - 1) / 2`` messages ahead of a message, so the ratio is
``(m_target - 1) / (m_cal - 1)``. :func:`scale_state_hops` multiplies every state-hop
sample by it (the trigger and command hops, which carry no host burst, are kept). A
calibration whose runs had one node per host (no burst seen) is never rescaled, nor is a
bundled target (:func:`~sigma_des.calibrate.target.prepare`): its host's turn leaves
in one PUBLISH or a few, not in a burst of ``m``.
Rules and measurements: docs/concepts/decisions.md ("State hops scaled with the
host's burst").
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.config import Scenario
from sigma_des.net.latency import Dist, load_samples

__all__ = ["burst_ratio", "calibration_nodes_per_host", "scale_state_hops"]


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
