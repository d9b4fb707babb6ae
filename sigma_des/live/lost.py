"""What a live method lost: hosts that sent no end-of-method report, a broker gone, a
slow broker hop.

A host reports its counters and message rows once the method ends. A host that does
not (it died, a forged ``stop`` ended it early, the broker went away and never came
back) leaves its part of the tables missing: the run is not "complete" even though it
was not interrupted. :func:`lost_notes` words that for the method's ``warnings``
(``summary.json``'s ``live.<method>.warnings`` and ``warnings``; ``sigma-des live``
prints them). :func:`hop_notes` flags an external broker whose hop is far above a
loopback broker's (Nagle's algorithm left on: ``set_tcp_nodelay`` missing).
"""

from __future__ import annotations

from typing import Any

__all__ = ["HOP_WARN_S", "hop_notes", "lost_notes"]

#: A broker hop above this (s) is far above a loopback broker's (a fraction of a ms).
HOP_WARN_S = 0.005


def _hosts(hs: list[int]) -> str:
    return ("host " if len(hs) == 1 else "hosts ") + ", ".join(str(h) for h in hs)


def lost_notes(info: dict[str, Any], hosts: int, broker_down: bool) -> list[str]:
    """The warnings of one live method.

    Args:
        info: the method's live info (``hosts_reported``, ``hosts_killed``, ``missed_frac``).
        hosts: the scenario's host count.
        broker_down: the server's broker connection was down when the method ended.

    Returns:
        One line per problem; empty for a complete method. ``info["lost_hosts"]`` is set
        to the hosts that sent no report.
    """
    lost = sorted(set(range(hosts)) - set(info["hosts_reported"]))
    info["lost_hosts"] = lost
    notes = []
    if broker_down:
        notes.append("the broker connection was down when the method ended (the broker "
                     "went away and did not come back)")
    if lost:
        died = sorted(set(lost) & set(info["hosts_killed"]))
        why = f" ({_hosts(died)} died)" if died else ""
        every = "every host" if len(lost) == hosts else _hosts(lost)
        notes.append(f"{every} of {hosts} sent no end-of-method report{why}: their counters "
                     "and message rows are missing (a host that died, a broker that went "
                     "away, or a forged stop); missed_frac = "
                     f"{info['missed_frac']:.2f}")
    return notes


def hop_notes(table: Any, sc: Any, impair: bool) -> list[str]:
    """A warning when the broker hop of the states is far above the loopback floor.

    The hop is the median state latency (host publish to server receipt, first sends
    only) less the mean latencies the clients add for the links (``net.host_link`` up,
    ``net.server_link`` down; none with ``--no-impair``).

    Args:
        table: the method's message table.
        sc: the scenario.
        impair: the clients applied the links' latencies.

    Returns:
        One line if the hop exceeds :data:`HOP_WARN_S`, else nothing.
    """
    states = table[(table["kind"] == "state") & ~table["republish"].astype(bool)]
    if states.empty:
        return []
    lat = float((states["t_recv"] - states["t_send"]).median())
    links = (sc.net.host_link.latency_of(True).mean_value()
             + sc.net.server_link.latency_of(False).mean_value()) if impair else 0.0
    hop = lat - links
    if not hop > HOP_WARN_S:
        return []
    return [f"the broker hop took {1e3 * hop:.1f} ms (median state latency "
            f"{1e3 * lat:.1f} ms less the links' {1e3 * links:.2f} ms), far above a loopback "
            "broker's fraction of a millisecond: a Mosquitto without `set_tcp_nodelay true` "
            "holds small messages back (Nagle's algorithm); see docs/LIVE.md, 'What an "
            "external broker must be configured with'"]
