"""Where the live processes' time went, per cell: ``processes.csv`` and its summary table.

Each live run's CPU table (``live/<cell>/cpu.csv``, :mod:`sigma_des.live.cpu`) says, per
process and method, the CPU it used, the wall time its loop thread was busy and the
time its threads waited on a run queue (runnable, no core). Per cell, method and
process kind (``broker``, ``server``, ``host``: the mean over a run's hosts) this module
turns them into cores: CPU seconds, loop-busy seconds and run-queue seconds per second
of the metrics window. A run-queue wait as large as the CPU says the machine's
scheduler, not the process's own work, holds its messages: the CPU stage of the DES
places bursts on free cores and does not model that wait (lab/record/LIVE.md, Session 12).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

__all__ = ["PROCESS_COLUMNS", "process_md", "process_rows"]

#: Columns of ``processes.csv``.
PROCESS_COLUMNS = ("cell", "method", "kind", "processes", "cpu_cores", "loop_cpu_cores",
                   "loop_busy", "runq_cores", "net_cpu_cores", "net_switch_rate",
                   "main_switch_rate")
#: Columns of the CPU table this reads (``loop_wall_s`` and ``runq_wait_s`` may be absent:
#: a run recorded before them; their figures are then NaN).
_NEEDED = ("method", "process", "window_s", "cpu_s")


def _per_second(rows: pd.DataFrame, col: str) -> float:
    """The mean over ``rows`` (one kind's processes) of ``col`` per window second."""
    if col not in rows.columns:
        return math.nan
    x = (rows[col] / rows["window_s"]).to_numpy(dtype=float)
    return float(x.mean()) if x.size and all(map(math.isfinite, x)) else math.nan


def process_rows(live_root: Path, cells: list[str]) -> list[dict[str, Any]]:
    """One row per cell, method and process kind of the CPU tables under ``live_root``
    (``<live_root>/<cell>/cpu.csv``; a cell without one is left out).

    Args:
        live_root: the suite's ``live`` folder.
        cells: cell names, in the order wanted.

    Returns:
        Rows with :data:`PROCESS_COLUMNS`: per process of the kind, in cores
        (seconds per window second), its CPU, its loop thread's CPU, the wall time its
        loop thread was busy, its threads' run-queue wait, and its other threads' (paho's
        network thread) CPU; per second, the voluntary context switches (wake-ups) of
        those threads and of its main thread. NaN in runs recorded before a column.
    """
    out: list[dict[str, Any]] = []
    for cell in cells:
        path = live_root / cell / "cpu.csv"
        if not path.exists():
            continue
        cpu = pd.read_csv(path)
        if not set(_NEEDED) <= set(cpu.columns):
            continue
        cpu = cpu[cpu["process"] != "background"]
        kind = cpu["process"].astype(str).str.replace(r"\d+$", "", regex=True)
        for (method, k), rows in cpu.groupby([cpu["method"], kind], sort=False):
            out.append({"cell": cell, "method": method, "kind": k, "processes": len(rows),
                        "cpu_cores": _per_second(rows, "cpu_s"),
                        "loop_cpu_cores": _per_second(rows, "loop_cpu_s"),
                        "loop_busy": _per_second(rows, "loop_wall_s"),
                        "runq_cores": _per_second(rows, "runq_wait_s"),
                        # the threads but the loop's (paho's): CPU, voluntary switches /s
                        "net_cpu_cores": _per_second(rows, "net_cpu_s"),
                        "net_switch_rate": _per_second(rows, "net_switches"),
                        "main_switch_rate": _per_second(rows, "main_switches")})
    return out


def process_md(rows: list[dict[str, Any]]) -> list[str]:
    """The summary's table: per cell, the server's and a host's CPU, loop-busy and
    run-queue cores (means over the methods), and the broker's CPU."""
    if not rows:
        return []
    df = pd.DataFrame(rows)
    mean = df.groupby(["cell", "kind"], sort=False)[
        ["cpu_cores", "loop_busy", "runq_cores"]].mean()

    def f(cell: str, kind: str, col: str) -> str:
        x = mean[col].get((cell, kind), math.nan)
        return "-" if not math.isfinite(x) else f"{x:.2f}"

    lines = ["| cell | server CPU | server loop busy | server run-queue | host CPU | "
             "host loop busy | host run-queue | broker CPU |",
             "|---|---|---|---|---|---|---|---|"]
    for cell in dict.fromkeys(df["cell"]):
        lines.append(f"| {cell} | " + " | ".join(
            [f(cell, "server", c) for c in ("cpu_cores", "loop_busy", "runq_cores")]
            + [f(cell, "host", c) for c in ("cpu_cores", "loop_busy", "runq_cores")]
            + [f(cell, "broker", "cpu_cores")]) + " |")
    return lines
