"""What a live method lost: hosts that sent no end-of-method report, a broker gone.

A host reports its counters and message rows once the method ends. A host that does
not (it died, a forged ``stop`` ended it early, the broker went away and never came
back) leaves its part of the tables missing: the run is not "complete" even though it
was not interrupted. :func:`lost_notes` words that for the method's ``warnings``
(``summary.json``'s ``live.<method>.warnings`` and ``warnings``; ``sigma-des live``
prints them).
"""

from __future__ import annotations

from typing import Any

__all__ = ["lost_notes"]


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
