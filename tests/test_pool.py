"""pool.py: the one local executor (in-process, process pool, fresh process per call)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sigma_des import load
from sigma_des.pool import local_pool, run_all
from sigma_des.sweep import Sweep, run_task


def test_in_process_keeps_call_order_and_runs_here() -> None:
    assert run_all(divmod, [(7, 2), (9, 4), (1, 1)]) == [(3, 1), (2, 1), (1, 0)]
    assert run_all(os.getpid, [(), ()]) == [os.getpid()] * 2


def test_pool_returns_results_in_call_order() -> None:
    calls = [(n, 3) for n in range(10)]
    assert run_all(divmod, calls, jobs=2) == [divmod(n, 3) for n in range(10)]


def test_submit_yields_every_index_once() -> None:
    with local_pool(2) as submit:
        got = dict(submit(pow, [(2, 3), (3, 2), (5, 0)]))
    assert got == {0: 8, 1: 9, 2: 1}


def test_fresh_runs_every_call_in_a_new_process() -> None:
    pids = run_all(os.getpid, [(), (), ()], jobs=1, fresh=True)
    assert len(set(pids)) == 3
    assert os.getpid() not in pids


def test_a_failing_call_raises_in_the_caller() -> None:
    with pytest.raises(ValueError, match="invalid literal"):
        run_all(int, [("12",), ("x",)], jobs=2)
    with pytest.raises(ValueError, match="invalid literal"):
        run_all(int, [("x",)])


def test_jobs_below_one_is_an_error() -> None:
    with pytest.raises(ValueError, match="jobs must be >= 1"):
        with local_pool(0):
            pass


def test_a_sweep_on_local_processes_stores_what_in_process_stores(tmp_path: Path) -> None:
    base = load(None, ["hosts=1", "duration=0.3", "warmup=0.1"])
    got = {}
    for client in ("inprocess", "processes"):
        with Sweep(base, {"nodes": [2, 3]}, ["none", "bides"], 2, tmp_path / f"{client}.sqlite",
                   task=run_task) as sw:
            rep = sw.run(client=client, n_workers=2, progress=False)
            assert (rep.submitted, rep.ok, rep.failed) == (8, 8, 0)
            got[client] = {(r["point"]["nodes"], r["seed"], r["method"]): r["metrics"]
                           for r in sw.results()}
    assert len(got["processes"]) == 8
    assert got["processes"] == got["inprocess"]
