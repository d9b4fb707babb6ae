"""Determinism across workers: a Dask LocalCluster run equals the in-process run."""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cloudpickle
import pytest
from sweep_helpers import tiny_base

from sigma_des import METHODS, Scenario
from sigma_des.sweep import Sweep, run_task

pytest.importorskip("distributed")


def fail_hlc_at_4(sc: Scenario, method: str) -> Mapping[str, Any]:
    """The default task, except that hlc at nodes=4, seed=2 raises."""
    if (sc.nodes, sc.seed, method) == (4, 2, "hlc"):
        raise ValueError("injected failure on a worker")
    return run_task(sc, method)


# ship this module's task by value: workers need not import the test module
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _outcome(sw: Sweep) -> dict[tuple[Any, ...], Any]:
    return {
        (r["point"]["nodes"], r["seed"], r["method"]): (
            r["status"],
            r["metrics"],
            r["links_mbps"],
            r["ts_summary"],
            r["error"].strip().splitlines()[-1] if r["error"] else None,
        )
        for r in sw.results()
    }


def test_local_cluster_equals_in_process(tmp_path: Path) -> None:
    kw: dict[str, Any] = {"methods": METHODS, "seeds": [2, 5], "task": fail_hlc_at_4}
    with Sweep(tiny_base(), {"nodes": [4]}, store=tmp_path / "a.sqlite", **kw) as ref:
        rep = ref.run(client="inprocess", progress=False)
        assert (rep.ok, rep.failed) == (7, 1)
        expected = _outcome(ref)
    with Sweep(tiny_base(), {"nodes": [4]}, store=tmp_path / "b.sqlite", **kw) as sw:
        rep = sw.run(n_workers=2, progress=True)  # default: a LocalCluster on 127.0.0.1
        assert (rep.ok, rep.failed) == (7, 1)
        got = _outcome(sw)
        workers = {r["worker"] for r in sw.results()}
    assert len(got) == 8
    assert got == expected  # bit-identical metrics, same failure
    assert got[(4, 2, "hlc")][4] == "ValueError: injected failure on a worker"
    assert all(not w.endswith(f":{os.getpid()}") for w in workers)  # ran on the workers
