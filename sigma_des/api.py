"""Public Python API: run several alignment methods on one scenario, side by side.

>>> from sigma_des import Scenario, compare
>>> res = compare(Scenario(nodes=5, hosts=1, duration=0.5, warmup=0.1), methods=["bides"],
...               progress=False)
>>> res.metric("bides", "aoi_mean") > 0
True
"""

from __future__ import annotations

import csv
import gc
import json
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.ideal import fly
from sigma_des.budget import check_memory
from sigma_des.cache.ideal import cache_dir, cached, cached_rows
from sigma_des.config import ALL_METHODS, Scenario, config_hash, to_dict
from sigma_des.errors import ConfigError, ctrl_c_inside
from sigma_des.events.cohort import execute
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.metrics.collector import METRIC_UNITS, WALL_METRICS
from sigma_des.metrics.fidelity import add_fidelity
from sigma_des.metrics.reports import MethodReport
from sigma_des.outputs import check_out_dir, write_files
from sigma_des.tables import text_table
from sigma_des.version import __version__

if TYPE_CHECKING:
    from sigma_des.record.parts import RecordParts

__all__ = ["Results", "compare", "ideal_run", "run_method"]

TIDY_COLUMNS = ("seed", "config_hash", "version", "method", "metric", "value", "unit")


@dataclass
class Results:
    """Results of :func:`compare`.

    Attributes:
        scenario: the scenario that ran.
        methods: per method, its metrics (see ``METRIC_UNITS``).
        wall: per method, the simulator's own cost (wall time, events/s, RSS).
        links_mbps: per method, wire Mbps of every link direction.
        timeseries: per method, per-render-tick arrays (t, aoi_mean, f_trig, …).
        fidelity: per method, formation error per logged sample (``t``, ``formation_err``).
        engines: per method, the engine ``requested`` and ``used`` and why it fell back
            to the per-message engine (``fallback``, empty if it did not).
        mode: ``des`` (simulated) or ``live`` (``sigma_des.live``: real processes and broker).
        live: live mode only: per method, its live counters (rejected messages, reconnects, …).
        interrupted: the run was stopped early (Ctrl-C): only the methods that finished
            are here.
    """

    scenario: Scenario
    methods: dict[str, dict[str, float]] = field(default_factory=dict)
    wall: dict[str, dict[str, float]] = field(default_factory=dict)
    links_mbps: dict[str, dict[str, float]] = field(default_factory=dict)
    timeseries: dict[str, dict[str, Any]] = field(default_factory=dict)
    fidelity: dict[str, dict[str, Any]] = field(default_factory=dict)
    engines: dict[str, dict[str, str]] = field(default_factory=dict)
    mode: str = "des"
    live: dict[str, dict[str, Any]] = field(default_factory=dict)
    interrupted: bool = False

    @property
    def config_hash(self) -> str:
        """Hash of the scenario (seed and method list excluded)."""
        return config_hash(self.scenario)

    def add(self, method: str, report: MethodReport) -> None:
        """File ``method``'s finished run (in the order methods are added)."""
        self.methods[method] = report.metrics
        self.wall[method] = report.wall
        self.links_mbps[method] = report.links_mbps
        self.timeseries[method] = report.timeseries
        self.engines[method] = report.engine
        if report.fidelity:
            self.fidelity[method] = report.fidelity

    def metric(self, method: str, name: str) -> float:
        """One metric of one method."""
        return self.methods[method][name]

    def rows(self, include_wall: bool = False) -> list[dict[str, Any]]:
        """Tidy rows: one per method × metric, carrying seed, config hash and version.

        Args:
            include_wall: also add the run-cost rows of :meth:`wall_rows` (they vary
                from run to run, so the deterministic table leaves them out).
        """
        out: list[dict[str, Any]] = []
        base = self._base()
        for method, ms in self.methods.items():
            out += _tidy(base, method, ms, METRIC_UNITS)
            out += _tidy(base, method, self.links_mbps[method], {}, "link_mbps.", "Mbps")
            if include_wall:
                out += _tidy(base, method, self.wall[method], WALL_METRICS)
        return out

    def wall_rows(self) -> list[dict[str, Any]]:
        """Tidy rows of the simulator's own cost (wall time, events/s, peak RSS)."""
        out: list[dict[str, Any]] = []
        base = self._base()
        for method in self.methods:
            out += _tidy(base, method, self.wall[method], WALL_METRICS)
        return out

    def _base(self) -> dict[str, Any]:
        """The columns every tidy row carries (the config hash computed once a table)."""
        return {"seed": self.scenario.seed, "config_hash": self.config_hash, "version": __version__}

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary; wall-time figures are under ``wall`` only."""
        extra: dict[str, Any] = {}
        if self.mode == "live":
            extra = {"live": self.live, "interrupted": self.interrupted}
        elif self.interrupted:
            extra = {"interrupted": True}
        return _json_safe(
            {
                **extra,
                "mode": self.mode,
                "version": __version__,
                "seed": self.scenario.seed,
                "config_hash": self.config_hash,
                "scenario": to_dict(self.scenario),
                "methods": self.methods,
                "links_mbps": self.links_mbps,
                "wall": self.wall,
                "engines": self.engines,
            }
        )

    def table(self) -> str:
        """The per-method comparison table printed by ``sigma-des compare``."""
        head = (
            "method",
            "AoI mean±std ms",
            "p99",
            "t-avg",
            "peak",
            "lat ms",
            "lat p99",
            "Mbps",
            "snap Hz",
            "trig Hz",
            "spread",
            "form m",
            "DTW r",
            "rollbk",
            "wall s",
        )
        lines = [head]
        for method, m in self.methods.items():
            lines.append(
                (
                    method,
                    f"{m['aoi_mean']:.2f} ± {m['aoi_std']:.2f}",
                    f"{m['aoi_p99']:.2f}",
                    f"{m['aoi_time_avg']:.2f}",
                    f"{m['aoi_peak_mean']:.2f}",
                    f"{m['latency_state_mean']:.2f}",
                    f"{m['latency_state_p99']:.2f}",
                    f"{m['throughput_mbps']:.2f}",
                    f"{m['snapshot_rate_hz']:.1f}",
                    f"{m['trigger_rate_hz']:.1f}",
                    f"{m['spread_mean']:.2f}",
                    f"{m.get('formation_err_mean', math.nan):.2f}",
                    f"{m.get('dtw_r', math.nan):.2f}",
                    f"{int(m['rollbacks'])}",
                    f"{self.wall[method]['wall_s']:.2f}",
                )
            )
        return text_table(lines) + "\n" + self.engine_note()

    def engine_note(self) -> str:
        """One line per engine used, naming methods that fell back and why."""
        used = {m: e.get("used", "?") for m, e in self.engines.items()}
        lines = []
        for eng in sorted(set(used.values())):
            ms = [m for m, u in used.items() if u == eng]
            lines.append(f"engine {eng}: {', '.join(ms)}")
        for m, e in self.engines.items():
            if e.get("fallback"):
                lines.append(f"  {m} fell back to the per-message engine: {e['fallback']}")
        return "\n".join(lines)

    def write(self, out_dir: str | Path) -> tuple[Path, Path]:
        """Write ``results.csv`` (tidy, deterministic), ``wall.csv`` (run cost) and
        ``summary.json`` into ``out_dir``, all or none (temporary names, then renames).

        Raises:
            ConfigError: ``out_dir`` is not a writable directory or a write failed.
        """
        d = check_out_dir(out_dir)

        def tidy(rows: list[dict[str, Any]]) -> Callable[[IO[str]], None]:
            def write(fh: IO[str]) -> None:
                w = csv.DictWriter(fh, fieldnames=TIDY_COLUMNS)
                w.writeheader()
                w.writerows(rows)

            return write

        def summary(fh: IO[str]) -> None:
            fh.write(json.dumps(self.summary(), indent=2, sort_keys=True) + "\n")

        csv_path, _wall, json_path = write_files(
            d,
            {"results.csv": tidy(self.rows()), "wall.csv": tidy(self.wall_rows()),
             "summary.json": summary},
        )
        return csv_path, json_path


def _tidy(
    base: dict[str, Any],
    method: str,
    values: dict[str, float],
    units: dict[str, str],
    prefix: str = "",
    unit: str = "",
) -> list[dict[str, Any]]:
    """One tidy row per value of ``values``: ``base``'s columns, the method, the metric."""
    return [
        {
            **base,
            "method": method,
            "metric": prefix + name,
            "value": value,
            "unit": units.get(name, unit),
        }
        for name, value in values.items()
    ]


def _json_safe(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v) for v in x]
    if isinstance(x, float) and (math.isnan(x) or math.isinf(x)):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if hasattr(x, "item"):
        return _json_safe(x.item())
    return x


def ideal_run(sc: Scenario) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The reference flight: same aircraft and behaviour, zero latency, perfect alignment.

    Computed once per scenario and then read from the on-disk cache of
    :mod:`sigma_des.cache.ideal` (shared by every method, process and run).
    """
    return cached(sc, fly_ideal)


def fly_ideal(sc: Scenario) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`ideal_run` computed, bypassing the cache: ``(times (T,), positions (T, n, 3))``."""
    return fly(
        make_dynamics(sc),
        make_behaviour(sc),
        sc.nodes,
        sc.duration,
        1.0 / sc.f_trig,
        log_rate=sc.fidelity.log_rate,
    )


def run_method(
    sc: Scenario,
    method: str,
    progress: Callable[[float], None] | None = None,
    ideal: NDArray[np.float64] | None = None,
    record: str | Path | None = None,
) -> dict[str, Any]:
    """Run one method on ``sc`` and return its raw result dict.

    Args:
        sc: the scenario.
        method: alignment method.
        progress: called with the simulated time after every simulated second.
        ideal: ideal-run positions for the fidelity metrics, when
            ``sc.fidelity.enabled`` (None: the cache entry, read a block at a time, so
            a long run's logs need not fit in memory; flown and stored if missing).
        record: record this method's run to this MCAP file (``sc.record`` settings).
    """
    if method not in ALL_METHODS:
        raise ConfigError("methods", f"unknown method {method!r}; allowed: {ALL_METHODS}")
    tap = None
    if record is not None:
        from sigma_des.record.tap import RecordTap

        def tap() -> RecordTap:
            return RecordTap(record, to_dict(sc), method, sc.record)

    run, out, engine = execute(
        sc.run_spec(), method, lambda: make_dynamics(sc), lambda: make_behaviour(sc), progress, tap
    )
    out["engine"] = engine
    if sc.fidelity.enabled:
        # both logs read a block at a time (the run's from its spill file, the ideal
        # run's from its cache entry): a long run's logs need not fit in memory
        rows = ideal if ideal is not None else cached_rows(sc, fly_ideal)[1]
        log = run.trajectory_log()
        add_fidelity(out, np.asarray(log.times), log.rows(), rows, sc.fidelity)
        del rows
    # The finished run is cyclic garbage (its parts call each other back), which only a
    # collection frees: left to the automatic ones it lingers for many runs, with its
    # samples and tables, when a sweep or compare runs one after another in a process.
    # It sits in the young generations (run() ends with a young collection), so a
    # collection of those frees it for ~1 ms; a full one would cost ~0.1 s.
    del run
    gc.collect(1)
    return out


def compare(
    sc: Scenario,
    methods: Iterable[str] | None = None,
    progress: bool = True,
    jobs: int = 1,
    record: str | Path | None = None,
    force: bool = False,
) -> Results:
    """Run every method on the same scenario and seed (identical random draws).

    Ctrl-C (``KeyboardInterrupt``) stops the runs; the methods that finished are kept:
    they are returned (``interrupted`` set) and recorded, the unfinished ones dropped.
    If none finished, the ``KeyboardInterrupt`` propagates.

    Args:
        sc: the scenario.
        methods: methods to run (default: ``sc.methods``), in the given order;
            each runs independently, so the order never changes a result.
        progress: show a progress bar on stderr for runs longer than ~2 s.
        jobs: run up to this many methods at once in worker processes (results are
            identical; only the wall-time figures change).
        record: also record every method's run into this MCAP file (replaced if it
            exists, only once the recording is complete; settings from ``sc.record``;
            see :mod:`sigma_des.record`). Checked writable before the runs.
        force: run even when the memory estimate exceeds the available memory.

    Raises:
        ConfigError: ``jobs`` < 1, an unknown method, ``record`` cannot be written
            (key ``--record``: before the runs, or a write failing during them, the
            disk full included), or (key ``memory``) the run's memory estimate exceeds
            the available memory (see :mod:`sigma_des.budget`).
    """
    if jobs < 1:
        raise ConfigError("jobs", f"must be >= 1, got {jobs}")
    ms: Sequence[str] = tuple(methods) if methods is not None else sc.methods
    sc = replace(sc, methods=tuple(ms))  # validates the names
    check_memory(sc, min(jobs, len(ms)), force)
    parts = None
    if record is not None:
        from sigma_des.record.cli import check_record_path
        from sigma_des.record.parts import RecordParts

        check_record_path(record)
        parts = RecordParts(record, ms)
    res = Results(sc)
    bar = None
    if progress:
        from tqdm import tqdm

        # disable=None: no bar when stderr is not a terminal (no \r frames in logs)
        bar = tqdm(total=round(sc.duration * len(ms), 3), unit="sim-s", delay=2.0,
                   leave=False, desc="sigma-des", disable=None)
    outs: dict[str, dict[str, Any]] = {}
    try:
        _run_methods(sc, ms, jobs, parts, bar, outs)
    except KeyboardInterrupt:
        if not outs:
            if parts is not None:
                parts.remove()
            raise
        res.interrupted = True
    except OSError as e:
        if parts is None:
            raise
        raise parts.error(e) from None
    except BaseException:
        if parts is not None:  # no part file outlives a failed run
            parts.remove()
        raise
    finally:
        if bar is not None:
            bar.close()
    done = [m for m in ms if m in outs]  # the caller's order, whatever finished first
    for m in done:
        res.add(m, MethodReport.of(outs[m]))
    if parts is not None:
        parts.join(done, to_dict(sc), sc.record)
    return res


def _run_methods(
    sc: Scenario, ms: Sequence[str], jobs: int, parts: RecordParts | None, bar: Any,
    outs: dict[str, dict[str, Any]],
) -> None:
    """Every method's raw result into ``outs`` as it finishes: here in turn, or on
    ``jobs`` workers of the local executor (an interrupted call leaves the others)."""
    def part(m: str) -> Path | None:
        return None if parts is None else parts.get(m)

    if jobs > 1 and len(ms) > 1:
        from sigma_des.pool import local_pool

        with local_pool(min(jobs, len(ms))) as submit:
            if cache_dir() is None:
                ideal = ideal_run(sc)[1] if sc.fidelity.enabled else None
                done = submit(run_method, [(sc, m, None, ideal, part(m)) for m in ms])
            else:
                # the workers read the ideal run from the cache once they need it (after
                # their simulation); meanwhile this process flies and stores it
                done = submit(run_method, [(sc, m, None, None, part(m)) for m in ms])
                if sc.fidelity.enabled:
                    ideal_run(sc)
            for i, out in done:
                outs[ms[i]] = out
                if bar is not None:
                    bar.set_postfix_str(ms[i])
                    bar.update(sc.duration)
        return
    ideal = None
    if sc.fidelity.enabled:
        if cache_dir() is None:
            ideal = ideal_run(sc)[1]
        else:  # flown and stored now if need be; each run reads it a block at a time
            cached_rows(sc, fly_ideal)
    for m in ms:
        last = [0.0]

        def tick(t: float, last: list[float] = last) -> None:
            if bar is not None:
                bar.update(round(t - last[0], 6))
                last[0] = t

        if bar is not None:
            bar.set_postfix_str(m)
        try:
            outs[m] = run_method(sc, m, tick, ideal, part(m))
        except SystemError as e:  # a Ctrl-C wrapped by a compiled call is still Ctrl-C
            if ctrl_c_inside(e):
                raise KeyboardInterrupt from e
            raise
