"""The engine benchmark's table of the compiled core's events by class, batched or not.

For every case the compiled core ran (cohort rows), one line per event class of
:func:`sigma_des.events.fast.tally.breakdown` that ran at all: its events, their share of
the core's events, how many ran from batches (fan-out batches and channels), and one line
of why the others of a batchable class ran one by one (broadcasts out of order or without
room; hops out of order or finding their channel's ring full; batches re-queued through
the pending buffer, tokens moved into a run of their own). Counts come from the core's
own counters, so they are deterministic: the same case prints the same table.
"""

from __future__ import annotations

from typing import Any

from sigma_des.events.fast.tally import CLASSES
from sigma_des.tables import text_table

__all__ = ["class_table", "reasons"]

#: The breakdown's reason counters, with their labels in :func:`reasons`.
REASONS: dict[str, str] = {
    "bcast_out_of_order": "broadcast deliveries out of order",
    "bcast_no_room": "broadcast deliveries without room or with a payload",
    "down_out_of_order": "deliveries out of order",
    "down_full": "deliveries finding the ring full",
    "up_out_of_order": "publishes out of order",
    "up_full": "publishes finding the ring full",
    "fanout_requeued": "fan-out batches re-queued via the pending buffer",
    "chan_moved": "channel tokens moved into a run of their own",
}


def reasons(c: dict[str, int]) -> str:
    """The breakdown's reasons, as one line (``off`` where batching was switched off)."""
    if not c.get("fanout_on") and not c.get("chan_on"):
        return "batching off (a CPU stage, QoS 1 over datagram or a stream with hold-back)"
    return "; ".join(f"{label} {c.get(k, 0):,}" for k, label in REASONS.items())


def class_table(rows: list[dict[str, Any]]) -> str:
    """One line per (cohort case, event class that ran), then each case's reasons."""
    head = ["N", "scenario", "method", "sim s", "class", "events", "share", "batched"]
    lines = [head]
    notes = []
    for r in rows:
        c = r.get("_classes") or {}
        if r["impl"] != "cohort" or not c:
            continue
        total = max(1, c["total"])
        case = [str(r["n"]), r["scenario"], r["method"], f"{r['sim_s']:g}"]
        for name in CLASSES:
            if c.get(name, 0) == 0:
                continue
            lines.append([*case, name, f"{c[name]:,}", f"{c[name] / total:.1%}",
                          f"{c[name + '_batched'] / c[name]:.1%}"])
        lines.append([*case, "all", f"{c['total']:,}", "100.0%",
                      f"{c['batched'] / total:.1%}"])
        notes.append(f"N={r['n']} {r['scenario']} {r['method']} {r['sim_s']:g} s: "
                     + reasons(c))
    return "\n".join([text_table(lines), *notes])
