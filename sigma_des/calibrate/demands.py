"""Per-message CPU service demands of the live processes, by the Utilization Law.

For each process the live runner records (:mod:`sigma_des.live.cpu`, ``cpu.csv``)
its CPU seconds over an idle window and over the metrics window, and the PUBLISH
messages it handled in the metrics window. The Utilization Law ``U = X · D`` gives
the mean CPU demand per message

    D = busy CPU seconds / messages handled,
    busy = CPU in the window - idle rate x window length,

where the idle rate (CPU seconds per second) is the process's rate over the idle
window: the cost of a loop that only waits (paho's network thread, our timers),
which a message-driven model must not charge to the messages. The ``background``
row is the machine's busy CPU not used by our processes: on a shared machine that
is capacity the run did not have (``background_cores`` = its CPU seconds per
second of the window).

One run gives one equation per process, so each process gets one demand per
message of any kind; separating, e.g., the broker's per-inbound from its
per-delivery cost needs runs with different fan-outs. These demands are measured
and reported; the DES does not consume them yet (docs/concepts/live-and-calibration.md).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from sigma_des.live.cpu import CPU_COLUMNS, CPU_FILE

__all__ = ["DEMAND_COLUMNS", "fit_demands", "kind_rows", "read_cpu"]

#: Columns of :func:`fit_demands`'s table.
DEMAND_COLUMNS = ("method", "process", "window_s", "cpu_s", "idle_rate", "busy_s",
                  "messages", "throughput_per_s", "utilization", "demand_s")


def read_cpu(source: Path) -> pd.DataFrame | None:
    """The ``cpu.csv`` of a live ``--out`` directory (or next to a recording), if any."""
    path = (source if source.is_dir() else source.parent) / CPU_FILE
    if not path.exists():
        return None
    df = pd.read_csv(path)
    missing = {"method", *CPU_COLUMNS} - set(df.columns)
    return None if missing else df


def kind_rows(table: pd.DataFrame, kind: str) -> pd.DataFrame:
    """The rows of a table with a ``process`` column (``cpu.csv``, :func:`fit_demands`'s)
    that belong to process kind ``kind``: ``host`` is every ``host<H>``, any other kind
    (``server``, ``broker``) its own name."""
    proc = table["process"].astype(str)
    mine = proc.str.fullmatch(r"host\d+") if kind == "host" else proc == kind
    return table.loc[mine.to_numpy(bool)]


def _row(r: Any) -> dict[str, Any]:
    idle_rate = r.idle_cpu_s / r.idle_s if r.idle_s > 0 else math.nan
    busy = r.cpu_s - idle_rate * r.window_s
    msgs = r.messages
    ok = math.isfinite(busy) and isinstance(msgs, int | float) and msgs > 0
    return {
        "method": r.method, "process": r.process, "window_s": r.window_s, "cpu_s": r.cpu_s,
        "idle_rate": idle_rate, "busy_s": busy, "messages": msgs,
        "throughput_per_s": msgs / r.window_s if r.window_s > 0 else math.nan,
        "utilization": busy / r.window_s if r.window_s > 0 else math.nan,
        "demand_s": busy / msgs if ok else math.nan,
    }


def fit_demands(cpu: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, float], list[str]]:
    """Utilization-Law demands per (method, process) from the live run's CPU rows.

    Args:
        cpu: rows with ``method`` and :data:`CPU_COLUMNS` (``cpu.csv``).

    Returns:
        The table (:data:`DEMAND_COLUMNS`; the ``background`` rows left out), the
        background CPU per method in cores (``background_cores``: CPU seconds per
        second of the metrics window), and warnings for rows that give no demand
        (a process not measured, no messages, or less CPU than its idle rate
        explains: the idle window then overstates the idle cost).
    """
    rows, warn = [], []
    bg: dict[str, float] = {}
    for r in cpu.itertuples(index=False):
        if r.process == "background":
            bg[str(r.method)] = r.cpu_s / r.window_s if r.window_s > 0 else math.nan
            continue
        d = _row(r)
        if not math.isfinite(d["demand_s"]):
            warn.append(f"{r.method}/{r.process}: no CPU demand (cpu {r.cpu_s} s, "
                        f"{r.messages} messages)")
        elif d["busy_s"] < 0:
            warn.append(f"{r.method}/{r.process}: less CPU in the window ({r.cpu_s:.3f} s) "
                        f"than its idle rate explains ({d['idle_rate'] * r.window_s:.3f} s); "
                        "demand negative")
        rows.append(d)
    return pd.DataFrame(rows, columns=list(DEMAND_COLUMNS)), bg, warn
