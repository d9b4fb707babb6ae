"""The sweep runner: grid × methods × seeds on Dask (or in-process), resumable.

>>> from sigma_des import load
>>> from sigma_des.sweep import Sweep
>>> base = load(None, ["hosts=1", "duration=0.3", "warmup=0.1"])
>>> sw = Sweep(base, {"nodes": [3, 4]}, methods=["none", "bides"], seeds=2,
...            store="/tmp/doctest-sweep.sqlite")           # doctest: +SKIP
>>> sw.run(client="inprocess", progress=False)               # doctest: +SKIP
>>> sw.aggregate()[0]["mean"]                                # doctest: +SKIP

Each task is one (scenario, method) run through a *task function* (default
:func:`run_task`, which calls :func:`sigma_des.api.run_method`). It runs on a Dask
worker (or in this process), and its result travels back to this process, which
alone writes it to the :class:`~sigma_des.sweep.store.ResultStore` as soon as it
arrives. A task that raises is stored as ``failed`` with its traceback text and
the sweep goes on; rerunning skips every stored run (failed ones too, unless
``retry_failed``).
"""

from __future__ import annotations

import os
import socket
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from sigma_des.config import Scenario, to_dict
from sigma_des.metrics.collector import METRIC_UNITS, WALL_METRICS
from sigma_des.outputs import check_out_dir, write_files
from sigma_des.sweep.aggregate import aggregate_rows, csv_writer
from sigma_des.sweep.executors import executor
from sigma_des.sweep.grid import (
    Grid,
    expand_grid,
    format_point,
    grid_keys,
    parse_methods,
    parse_seeds,
    validate_points,
)
from sigma_des.sweep.store import ResultStore, RunKey
from sigma_des.sweep.tasks import Task, TaskFn, run_task

__all__ = ["RunReport", "Sweep"]


@dataclass
class RunReport:
    """What one :meth:`Sweep.run` did.

    Attributes:
        total: runs in the sweep.
        done_before: runs already stored as ``ok`` (skipped).
        failed_before: runs stored as ``failed`` and not retried (skipped).
        submitted: runs executed this time.
        ok: of those, finished fine.
        failed: of those, failed (stored with their error).
        wall_s: wall time of this call.
        failures: (key, last line of the error) of every failed run of the sweep.
        elsewhere: (key, ``host:pid``) of runs left to another live sweep on the store.
    """

    total: int = 0
    done_before: int = 0
    failed_before: int = 0
    submitted: int = 0
    ok: int = 0
    failed: int = 0
    wall_s: float = 0.0
    failures: list[tuple[RunKey, str]] = field(default_factory=list)
    elsewhere: list[tuple[RunKey, str]] = field(default_factory=list)

    def text(self) -> str:
        """One-paragraph human summary."""
        s = (
            f"{self.total} runs: {self.done_before} already done, {self.submitted} run now "
            f"({self.ok} ok, {self.failed} failed) in {self.wall_s:.1f} s"
        )
        if self.failed_before:
            s += f"; {self.failed_before} failed earlier and not retried (use --retry-failed)"
        if self.elsewhere:
            who = sorted({w for _k, w in self.elsewhere})
            s += (
                f"; {len(self.elsewhere)} being run by another sweep on this store "
                f"({', '.join(who)}): rerun this command when it is done to include them"
            )
        for key, err in self.failures:
            s += f"\n  FAILED {key[2]} seed={key[1]} config={key[0]}: {err}"
        return s


class Sweep:
    """A grid over scenario keys × methods × seeds, stored run by run.

    Args:
        base: the base scenario; every grid point overrides some of its keys.
        grid: ``{dotted key: [values]}`` (Cartesian product) or a list of points.
        methods: methods to run (default: ``base.methods``); a list or ``"a,b"``.
        seeds: a list of seeds, or N (= seeds 1..N), or text (``"5"``, ``"1,2,3"``).
        store: path of the SQLite results store.
        task: the task function (default :func:`run_task`); must be picklable by
            reference (module-level) to run on Dask worker processes.

    Raises:
        ConfigError: a grid point, method or seed is invalid (raised here, before any
            work), naming the key.
    """

    def __init__(
        self,
        base: Scenario,
        grid: Grid,
        methods: Sequence[str] | str | None = None,
        seeds: Sequence[int] | int | str = 1,
        store: str | Path = "sweep.sqlite",
        task: TaskFn = run_task,
    ) -> None:
        self.base = base
        self.points = expand_grid(grid)
        self.keys = grid_keys(self.points)
        self.methods = parse_methods(base.methods if methods is None else methods)
        self.seeds = parse_seeds(seeds)
        self.scenarios = validate_points(base, self.points)
        self.task = task
        self.store = ResultStore(store)
        self._stored_configs: set[str] = set()
        self._tasks = [
            Task(i, p, replace(sc, seed=seed, methods=(m,)), m)
            for i, (p, sc) in enumerate(zip(self.points, self.scenarios, strict=True))
            for m in self.methods
            for seed in self.seeds
        ]

    # ------------------------------------------------------------ planning

    def tasks(self) -> list[Task]:
        """Every run of the sweep, in grid order (point, method, seed)."""
        return list(self._tasks)

    def pending(self, retry_failed: bool = False) -> list[Task]:
        """Runs not stored yet (plus the failed ones if ``retry_failed``), without repeats."""
        st = self.store.statuses()
        out: list[Task] = []
        seen: set[RunKey] = set()
        for t in self._tasks:
            k = t.key
            if k in seen:
                continue
            seen.add(k)
            s = st.get(k)
            if s is None or (s == "failed" and retry_failed):
                out.append(t)
        return out

    def failed(self) -> list[dict[str, Any]]:
        """Stored failed runs of this sweep (records with ``error``)."""
        return [r for r in self.results() if r["status"] == "failed"]

    def estimate(self, n_workers: int = 1, retry_failed: bool = False) -> float:
        """Rough wall seconds to finish the pending runs on ``n_workers`` workers."""
        costs = sorted((t.cost for t in self.pending(retry_failed)), reverse=True)
        return max(sum(costs) / max(n_workers, 1), costs[0] if costs else 0.0)

    # ------------------------------------------------------------ running

    def run(
        self,
        client: Any = None,
        n_workers: int = 2,
        progress: bool = True,
        retry_failed: bool = False,
        on_record: Callable[[Task, dict[str, Any]], None] | None = None,
    ) -> RunReport:
        """Run the pending tasks and store each result as it completes.

        Args:
            client: ``None`` or ``"local"`` (a new Dask ``LocalCluster`` on 127.0.0.1
                with ``n_workers`` single-threaded worker processes), a scheduler
                address (``"tcp://host:8786"``), a ``distributed.Client``,
                ``"processes"`` (``n_workers`` local worker processes, no Dask) or
                ``"inprocess"`` (run here, one after another; no Dask).
            n_workers: workers of the ``LocalCluster`` (or of ``"processes"``).
            progress: show a progress bar with ETA on stderr.
            retry_failed: run the stored failed runs again.
            on_record: called with (task, payload) after each result is stored.

        Returns:
            A :class:`RunReport`. An interrupt (``KeyboardInterrupt``) propagates
            after the runs in flight are cancelled; everything stored stays.
        """
        t0 = time.perf_counter()
        st = self.store.statuses()
        keys = list(dict.fromkeys(t.key for t in self._tasks))
        todo = self.pending(retry_failed)
        todo.sort(key=lambda t: -t.cost)  # longest first: shorter makespan
        rep = RunReport(total=len(keys))
        rep.done_before = sum(1 for k in keys if st.get(k) == "ok")
        rep.failed_before = 0 if retry_failed else sum(1 for k in keys if st.get(k) == "failed")
        inprocess = client == "inprocess" or not todo
        # claim a few runs at a time, so concurrent sweeps on this store share the work
        chunk = 1 if inprocess else 4 * max(1, n_workers)
        owner = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._tried: set[RunKey] = set()
        bar = None
        try:
            with executor("inprocess" if inprocess else client, n_workers) as submit:
                bar = self._bar(todo) if progress and todo else None  # once connected
                while True:
                    batch = self._claim(todo, owner, chunk, retry_failed)
                    if not batch:
                        break
                    rep.submitted += len(batch)
                    for task, payload in submit(self.task, batch):
                        self._store(task, payload, rep, bar, len(todo))
                        if on_record is not None:
                            on_record(task, payload)
        finally:
            self.store.release(owner)
            if bar is not None:
                bar.close()
        rep.elsewhere = self.store.leased([t.key for t in todo], owner)
        rep.wall_s = time.perf_counter() - t0
        rep.failures = [
            ((r["config_hash"], r["seed"], r["method"]), _last_line(r["error"]))
            for r in self.failed()
        ]
        return rep

    def _claim(
        self, todo: list[Task], owner: str, chunk: int, retry_failed: bool
    ) -> list[Task]:
        """Claim (lease) the next up to ``chunk`` unclaimed runs of ``todo``."""
        by_key = {t.key: t for t in todo if t.key not in self._tried}
        lease_s = max(600.0, 20.0 * max((t.cost for t in todo), default=0.0))
        got = self.store.claim(list(by_key), owner, lease_s, chunk, retry_failed)
        self._tried.update(got)  # a run is tried once per call, even if it fails again
        return [by_key[k] for k in got]

    def _store(
        self, task: Task, payload: dict[str, Any], rep: RunReport, bar: Any, n: int
    ) -> None:
        """Store one result (and its scenario, once) and count it."""
        h = task.key[0]
        if h not in self._stored_configs:
            self.store.put_config(h, _scenario_record(task.scenario))
            self._stored_configs.add(h)
        self.store.put(task.key, payload["status"], payload)
        if payload["status"] == "ok":
            rep.ok += 1
        else:
            rep.failed += 1
        if bar is not None:
            bar.set_postfix_str(
                f"runs {rep.ok + rep.failed}/{n}, failed {rep.failed}", refresh=False
            )
            bar.update(task.cost)

    def _bar(self, todo: Sequence[Task]) -> Any:
        from tqdm import tqdm

        return tqdm(
            total=sum(t.cost for t in todo),
            desc="sweep",
            bar_format="{l_bar}{bar}| [{elapsed}<{remaining}{postfix}]",
            postfix=f"runs 0/{len(todo)}, failed 0",
            leave=False,
            disable=None,  # no bar when stderr is not a terminal (no \r frames in logs)
        )

    # ------------------------------------------------------------ results

    def results(self) -> list[dict[str, Any]]:
        """Stored records of this sweep's runs, in grid order, each with its ``point``."""
        out: list[dict[str, Any]] = []
        for t in self._tasks:
            rec = self.store.get(t.key)
            if rec is not None:
                out.append({"point": dict(t.point), "point_index": t.point_index, **rec})
        return out

    def rows(self, include_wall: bool = True) -> list[dict[str, Any]]:
        """Tidy rows of the successful runs: grid values, config_hash, seed, method,
        metric, value, unit (link rates as ``link_mbps.<link>``)."""
        out: list[dict[str, Any]] = []
        for r in self.results():
            if r["status"] != "ok":
                continue
            base = {k: r["point"].get(k, "") for k in self.keys}
            base.update(config_hash=r["config_hash"], seed=r["seed"], method=r["method"])
            groups: list[tuple[str, dict[str, float], Mapping[str, str], str]] = [
                ("", r["metrics"], METRIC_UNITS, "")
            ]
            groups.append(("link_mbps.", r.get("links_mbps") or {}, {}, "Mbps"))
            if include_wall:
                groups.append(("", r.get("wall") or {}, WALL_METRICS, ""))
            for prefix, vals, units, unit in groups:
                for name, v in vals.items():
                    out.append(
                        {
                            **base,
                            "metric": prefix + name,
                            "value": v,
                            "unit": units.get(name, unit),
                        }
                    )
        return out

    def row_columns(self) -> list[str]:
        """Columns of :meth:`rows`."""
        return [*self.keys, "config_hash", "seed", "method", "metric", "value", "unit"]

    def aggregate(self, include_wall: bool = True) -> list[dict[str, Any]]:
        """Seed aggregates per (grid point, method, metric): n, mean, std, ci95."""
        by = [*self.keys, "config_hash", "method", "metric"]
        return aggregate_rows(self.rows(include_wall), by)

    def aggregate_columns(self) -> list[str]:
        """Columns of :meth:`aggregate`."""
        return [*self.keys, "config_hash", "method", "metric", "unit", "n", "mean", "std", "ci95"]

    def write(self, out_dir: str | Path) -> tuple[Path, Path]:
        """Write ``runs.csv`` (tidy per-run rows) and ``aggregate.csv`` (deterministic:
        no wall-time figures) and ``wall.csv`` (the per-run wall-time rows) into ``out_dir``."""
        d = check_out_dir(out_dir)
        wall = [r for r in self.rows() if r["metric"] in WALL_METRICS]
        runs, agg, _wall = write_files(
            d,
            {
                "runs.csv": csv_writer(self.rows(include_wall=False), self.row_columns()),
                "aggregate.csv": csv_writer(
                    self.aggregate(include_wall=False), self.aggregate_columns()
                ),
                "wall.csv": csv_writer(wall, self.row_columns()),
            },
        )
        return runs, agg

    def describe(self) -> str:
        """One line: points × methods × seeds."""
        pts = ", ".join(format_point(p) for p in self.points[:4])
        if len(self.points) > 4:
            pts += ", …"
        return (
            f"{len(self.points)} grid points ({pts}) × {len(self.methods)} methods "
            f"({','.join(self.methods)}) × {len(self.seeds)} seeds = {len(self._tasks)} runs"
        )

    def close(self) -> None:
        """Close the results store."""
        self.store.close()

    def __enter__(self) -> Sweep:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _scenario_record(sc: Scenario) -> dict[str, Any]:
    d = to_dict(sc)
    d.pop("seed")
    d.pop("methods")
    return d


def _last_line(text: str | None) -> str:
    lines = [ln for ln in (text or "").strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else "(no error text)"
