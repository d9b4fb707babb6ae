"""The suite's runs: live cells (bounded subprocesses), the calibration, the DES predictions.

Live runs and the calibration go through the ``sigma-des`` command line, each in
its own process with a time limit: a user reruns exactly what the suite ran, and a
run that hangs is stopped (SIGTERM first: ``sigma-des live`` then keeps the methods
that finished; SIGKILL after a grace period) without taking the suite down. Each
live run uses our own Mosquitto on a free 127.0.0.1 port (the default of
``sigma-des live``). The 1-minute load average is read before and after each live
run, and the background CPU (cores other processes used during the metrics window)
from the run's own CPU table (``summary.json``, ``live.<method>.cpu``).

The DES's missed-frame fraction follows the live runner's definition (node x frame
states of the window's triggers that never reached the server), counted by a small
recording tap (:class:`MissedTap`) instead of a whole MCAP recording.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.calibrate.target import MissedTap, des_figures, prepare, shift_host_link
from sigma_des.config import Scenario, config_hash, load
from sigma_des.errors import ConfigError
from sigma_des.version import __version__
from sigma_lab.studies.validation.grid import EXTRA_LATENCY_S, Cell, Plan
from sigma_lab.studies.validation.scoring import METRICS

__all__ = ["LIVE_BASE", "UNDER_LOAD", "MissedTap", "background_cores", "bounded_run",
           "calibrate_run", "des_cell", "des_figures", "des_scenario", "live_cell", "live_timeout",
           "load_calibration", "read_json", "shift_host_link", "under_load", "warm_up",
           "write_json"]

#: Keys every live run gets besides the cell's own (no fidelity: not compared).
LIVE_BASE = ("fidelity.enabled=false",)
#: Seconds between SIGTERM and SIGKILL of a live run past its time limit.
GRACE_S = 20.0
#: Time limit of ``sigma-des warmup`` (a cold numba cache compiles in ~1-2 min).
WARMUP_S = 600.0


def write_json(path: Path, obj: Any) -> None:
    """Write ``obj`` as JSON all or nothing (a temporary name, then a rename)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(obj, indent=1, default=float) + "\n")
    os.replace(tmp, path)


def read_json(path: Path) -> Any:
    """The JSON at ``path``, or None if it does not exist or is incomplete."""
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _cli() -> list[str]:
    return [sys.executable, "-c", "import sys; from sigma_des.cli import main; "
            "sys.exit(main(sys.argv[1:]))"]


def warm_up(log: Path) -> int:
    """``sigma-des warmup`` (bounded by :data:`WARMUP_S`), before the first live run: on
    a cold numba cache the live processes compile their kernels inside the first run's
    window, a start-up stall the calibration would then fit (measured on a fresh
    checkout: ``none`` of the calibration run missed 9.4 % of frames, p99 AoI 215 ms,
    against 0 % and 23 ms in its repeats). Returns its exit status (124 if timed out)."""
    code, timed_out = bounded_run([*_cli(), "warmup"], log, WARMUP_S)
    return 124 if timed_out else code


def bounded_run(cmd: list[str], log: Path, timeout: float) -> tuple[int, bool]:
    """Run ``cmd`` with stdout and stderr to ``log``; past ``timeout`` s SIGTERM, then
    after :data:`GRACE_S` SIGKILL. Returns the exit status and whether it timed out."""
    with log.open("wb") as fh:
        p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=fh, stderr=subprocess.STDOUT)
        try:
            return p.wait(timeout=timeout), False
        except subprocess.TimeoutExpired:
            return _stop(p), True
        except BaseException:  # Ctrl-C of the suite: stop the run, then pass it on
            _stop(p)
            raise


def _stop(p: subprocess.Popen[bytes]) -> int:
    """SIGTERM (``sigma-des live`` then keeps its finished methods), SIGKILL if need be."""
    p.send_signal(signal.SIGTERM)
    try:
        return p.wait(timeout=GRACE_S)
    except subprocess.TimeoutExpired:
        p.kill()
        return p.wait(timeout=GRACE_S)


#: Background CPU above this share of the cores marks a live run as under load.
UNDER_LOAD = 0.25


def live_timeout(plan: Plan) -> float:
    """A live cell's time limit: 60 s of start-up plus, per method, its run and 30 s
    (ready, idle window, stop and the hosts' reports, all bounded by the runner)."""
    return 60.0 + len(plan.methods) * (plan.duration + 30.0)


def background_cores(summary: dict[str, Any]) -> float:
    """Mean cores' worth of CPU other processes used during the live run's metrics
    windows (the ``background`` rows of its CPU table); NaN without them."""
    vals = []
    for info in summary.get("live", {}).values():
        for r in info.get("cpu", []):
            if r.get("process") == "background" and r.get("window_s", 0) > 0:
                vals.append(float(r["cpu_s"]) / float(r["window_s"]))
    return float(np.mean(vals)) if vals else math.nan


def under_load(live: dict[str, Any], cores: int) -> bool:
    """Whether a live run ran under load: the background CPU during its metrics window
    (other processes' CPU, from its own CPU table) exceeds :data:`UNDER_LOAD` of the
    machine's ``cores``, or, without that table, the 1-min load average before it
    exceeds the core count."""
    bg = live.get("background_cores", math.nan)
    if isinstance(bg, float) and math.isfinite(bg):
        return bg > UNDER_LOAD * cores
    return float(live.get("load_before", 0.0)) > cores


def live_cell(cell: Cell, plan: Plan, out: Path) -> dict[str, Any]:
    """Run ``cell`` live (every method of ``plan``) into ``out``; its figures.

    Returns:
        ``methods`` (per method, :data:`~sigma_lab.studies.validation.scoring.METRICS`;
        a method that did not finish is absent), ``load_before`` / ``load_after``
        (1-min load average), ``background_cores``, ``exit``, ``timed_out``,
        ``wall_s``, ``seed``, ``config_hash``, ``version`` and the command.
    """
    out.mkdir(parents=True, exist_ok=True)
    sets = [*LIVE_BASE, *cell.live_sets(), f"duration={plan.duration}", f"warmup={plan.warmup}"]
    cmd = [*_cli(), "live", "--methods", ",".join(plan.methods), "--out", str(out),
           "--no-plots", "--no-progress"]
    cmd += [a for s in sets for a in ("--set", s)]
    if cell.mode == "bundle":
        cmd.append("--bundle")
    before = os.getloadavg()[0]
    t0 = time.perf_counter()
    status, timed_out = bounded_run(cmd, out / "live.log", live_timeout(plan))
    wall = time.perf_counter() - t0
    summ = read_json(out / "summary.json") or {}
    methods = {m: {k: _num(v.get(k)) for k in METRICS} for m, v in summ.get("methods", {}).items()}
    return {"methods": methods, "load_before": before, "load_after": os.getloadavg()[0],
            "background_cores": background_cores(summ), "exit": status,
            "timed_out": timed_out, "wall_s": wall, "seed": summ.get("seed"),
            "config_hash": summ.get("config_hash"), "version": summ.get("version", __version__),
            "command": cmd[3:]}


def _num(v: Any) -> float:
    return float(v) if isinstance(v, int | float) else math.nan


def calibrate_run(source: Path | Sequence[Path], cal_dir: Path, timeout: float = 600.0,
                  extra: Sequence[str] = ()) -> tuple[Scenario, dict[str, Any]]:
    """``sigma-des calibrate SOURCE... --out CAL_DIR/calibrated.toml [EXTRA...]`` (with
    its in-sample check on every run), bounded; the calibrated scenario and its report.
    ``extra``: more ``calibrate`` options (e.g. ``--one-thread``).

    Raises:
        ConfigError: (``calibration``) calibrate failed or ran out of time (its log named).
    """
    cal_dir.mkdir(parents=True, exist_ok=True)
    toml = cal_dir / "calibrated.toml"
    log = cal_dir / "calibrate.log"
    sources = [source] if isinstance(source, Path) else list(source)
    status, timed_out = bounded_run([*_cli(), "calibrate", *map(str, sources), "--out",
                                     str(toml), *extra], log, timeout)
    if status != 0 or timed_out:
        tail = log.read_text(errors="replace").strip().splitlines()[-1:] or [""]
        raise ConfigError("calibration", f"`sigma-des calibrate {' '.join(map(str, sources))}` "
                          f"{'timed out' if timed_out else f'exited {status}'}: {tail[0]} "
                          f"(log: {log})")
    return load_calibration(cal_dir)


def load_calibration(cal_dir: Path) -> tuple[Scenario, dict[str, Any]]:
    """The calibrated scenario and report a previous :func:`calibrate_run` wrote."""
    report = read_json(cal_dir / "calibrated.json")
    if report is None:
        raise ConfigError("calibration", f"no readable {cal_dir / 'calibrated.json'}")
    return load(str(cal_dir / "calibrated.toml")), report


def des_scenario(cal: Scenario, report: dict[str, Any], cell: Cell, plan: Plan, d: Path
                 ) -> Scenario:
    """The calibrated scenario prepared for ``cell`` by
    :func:`sigma_des.calibrate.target.prepare` (what ``sigma-des predict`` runs): the
    cell's keys, its message mode, the window of the plan, and the +5 ms of a ``lat5``
    cell."""
    return prepare(cal, report, [*cell.des_sets(), f"duration={plan.duration}",
                                 f"warmup={plan.warmup}"], bundle=cell.mode == "bundle",
                   add_latency_s=EXTRA_LATENCY_S if cell.impairment == "lat5" else 0.0,
                   samples_dir=d)


def des_cell(cal: Scenario, report: dict[str, Any], cell: Cell, plan: Plan, d: Path
             ) -> dict[str, Any]:
    """The DES's prediction of ``cell`` for every method of ``plan``."""
    sc = des_scenario(cal, report, cell, plan, d)
    t0 = time.perf_counter()
    methods = {m: des_figures(sc, m) for m in plan.methods}
    return {"methods": methods, "seed": sc.seed, "config_hash": config_hash(sc),
            "version": __version__, "wall_s": time.perf_counter() - t0}
