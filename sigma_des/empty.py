"""Why a method's table is empty: a run that measured no delivered state says so.

A scenario whose delays are longer than the run (a one-way latency or a broker
service of hours in a run of seconds) delivers no state inside the measured window:
every AoI and latency figure of such a method is NaN. :func:`empty_notes` names those
methods and the largest mean delay of the scenario, so that a table of NaN never
stands without a word (``compare`` prints the notes and ``summary.json`` keeps them
under ``warnings``).
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["empty_notes"]

#: The delay keys of a scenario named when a run delivered nothing.
DELAY_KEYS = ("net.host_link.latency", "net.server_link.latency", "broker.publish_service",
              "broker.delivery_service", "compute.step_time", "rpc.call_time",
              "rpc.render_time")


def _largest_delay(sc: Any) -> tuple[str, float]:
    """The delay key of ``sc`` with the largest mean (s), and that mean; a state's
    serialization on the host link counts as one (its payload over the link's rate)."""
    best = ("payload_bits / net.host_link.bandwidth_mbps (a state's serialization)",
            sc.payload_bits / (sc.net.host_link.bandwidth_mbps * 1e6))
    for key in DELAY_KEYS:
        obj = sc
        for part in key.split("."):
            obj = getattr(obj, part)
        mean = obj.mean_value()
        if mean > best[1]:
            best = (key, mean)
    return best


def empty_notes(sc: Any, methods: dict[str, dict[str, float]]) -> list[str]:
    """One line per method whose AoI is NaN (no state delivered inside the window).

    Args:
        sc: the scenario that ran.
        methods: per method, its metrics (``aoi_mean`` among them).

    Returns:
        The notes, empty when every method measured something.
    """
    empty = [m for m, ms in methods.items() if math.isnan(ms.get("aoi_mean", 0.0))]
    if not empty:
        return []
    key, mean = _largest_delay(sc)
    window = sc.duration - sc.warmup
    cause = (f"the largest mean delay is {key} = {mean:g} s" if key
             else "no delay of the scenario explains it")
    return [f"{m}: no state was delivered inside the measured window ({sc.warmup:g} to "
            f"{sc.duration:g} s, {window:g} s), so its AoI and latency are NaN; {cause}"
            for m in empty]
