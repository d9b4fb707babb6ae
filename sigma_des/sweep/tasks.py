"""Sweep tasks: the default task function, its error-catching wrapper and cost estimates.

A *task function* takes ``(scenario, method)`` and returns a small mapping with a
``metrics`` dict (and optionally ``wall``, ``links_mbps``, ``ts_summary``). The
default is :func:`run_task`; tests and users may pass their own to
:class:`~sigma_des.sweep.Sweep` (``task=``). :func:`execute` is what actually runs on
a worker: it calls the task function and turns any exception into a ``failed``
payload carrying the traceback text, so one bad run never kills a sweep.
"""

from __future__ import annotations

import os
import socket
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from sigma_des.config import Scenario, config_hash
from sigma_des.sweep.store import RunKey
from sigma_des.version import __version__

__all__ = ["Task", "TaskFn", "estimate_seconds", "execute", "run_task"]

#: A task function: runs one method on one scenario, returns ``metrics`` (and
#: optionally ``wall``, ``links_mbps``, ``ts_summary``) as plain dicts.
TaskFn = Callable[[Scenario, str], Mapping[str, Any]]

#: Kernel events per node per simulated frame (measured, default scenario) and the
#: engine's rough event rate on one core; used only for ETA estimates.
EVENTS_PER_NODE_FRAME = 4.1
EVENTS_PER_WALL_S = 30_000.0
TASK_OVERHEAD_S = 0.2


def run_task(sc: Scenario, method: str) -> dict[str, Any]:
    """The default task: :func:`sigma_des.api.run_method`, reduced to a small record.

    Returns:
        ``metrics``, ``wall`` and ``links_mbps`` as returned by the engine, and
        ``ts_summary``: mean/min/max/last of every per-render-tick series.
    """
    from sigma_des.api import run_method

    out = run_method(sc, method)
    ts: dict[str, dict[str, float]] = {}
    for name, arr in out["timeseries"].items():
        a = np.asarray(arr, dtype=float)
        if name == "t" or a.size == 0:
            continue
        ts[name] = {
            "mean": float(np.nanmean(a)) if np.isfinite(a).any() else float("nan"),
            "min": float(np.nanmin(a)) if np.isfinite(a).any() else float("nan"),
            "max": float(np.nanmax(a)) if np.isfinite(a).any() else float("nan"),
            "last": float(a[-1]),
        }
    return {
        "metrics": {k: float(v) for k, v in out["metrics"].items()},
        "wall": {k: float(v) for k, v in out["wall"].items()},
        "links_mbps": {k: float(v) for k, v in out["links_mbps"].items()},
        "ts_summary": ts,
    }


def execute(task: TaskFn, sc: Scenario, method: str) -> dict[str, Any]:
    """Run ``task(sc, method)`` and catch any error (this runs on the worker).

    Returns:
        ``status`` (``ok``/``failed``), the task's dicts or ``error`` (traceback
        text), ``elapsed_s``, ``worker`` (host:pid) and ``version``.
    """
    t0 = time.perf_counter()
    info = {"worker": f"{socket.gethostname()}:{os.getpid()}", "version": __version__}
    try:
        out = task(sc, method)
        if not isinstance(out, Mapping) or not isinstance(out.get("metrics"), Mapping):
            raise TypeError(f"task returned {type(out).__name__} without a 'metrics' dict")
        payload = {
            k: {str(n): float(v) for n, v in dict(out[k]).items()}
            for k in ("metrics", "wall", "links_mbps")
            if k in out
        }
        if "ts_summary" in out:
            payload["ts_summary"] = dict(out["ts_summary"])
        return {"status": "ok", **payload, "elapsed_s": time.perf_counter() - t0, **info}
    except Exception:
        return {
            "status": "failed",
            "error": traceback.format_exc(),
            "elapsed_s": time.perf_counter() - t0,
            **info,
        }


def estimate_seconds(sc: Scenario) -> float:
    """Rough wall seconds of one method run of ``sc`` on one core (for ETAs only)."""
    events = EVENTS_PER_NODE_FRAME * sc.nodes * sc.f_trig * sc.duration
    return TASK_OVERHEAD_S + events / EVENTS_PER_WALL_S


@dataclass(frozen=True)
class Task:
    """One run of a sweep: grid point × seed × method.

    Attributes:
        point_index: index of the grid point in :attr:`Sweep.points`.
        point: the grid point (dotted key → value).
        scenario: the point's scenario with this seed (and this method only).
        method: the alignment method.
    """

    point_index: int
    point: dict[str, Any]
    scenario: Scenario
    method: str

    @property
    def key(self) -> RunKey:
        """The store key (config hash, seed, method)."""
        return (config_hash(self.scenario), self.scenario.seed, self.method)

    @property
    def cost(self) -> float:
        """Estimated wall seconds (see :func:`estimate_seconds`)."""
        return estimate_seconds(self.scenario)
