"""The results store: failures recorded, nothing recomputed on rerun, interruption resumes."""

from __future__ import annotations

import sqlite3
from dataclasses import replace
from pathlib import Path

import pytest
from sweep_helpers import CountingTask, tiny_base

from sigma_des.sweep import ResultStore, Sweep

GRID = {"nodes": [3, 4]}
METHODS = ["none", "bides"]
SEEDS = [1, 2]
ALL = {(n, s, m) for n in (3, 4) for s in SEEDS for m in METHODS}
BAD = (4, 2, "bides")


def _sweep(store: Path, task: CountingTask) -> Sweep:
    return Sweep(tiny_base(), GRID, METHODS, SEEDS, store, task=task)


def _rows(store: Path) -> list[tuple[int, str, str, int]]:
    """Rows as seen by an independent connection (what survived on disk)."""
    with sqlite3.connect(store) as db:
        return db.execute("SELECT seed, method, status, attempts FROM runs").fetchall()


def test_failure_is_recorded_and_not_rerun_unless_asked(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    t1 = CountingTask(fail_on={BAD})
    with _sweep(store, t1) as sw:
        assert len(sw.pending()) == 8
        rep = sw.run(client="inprocess", progress=False)
        assert (rep.submitted, rep.ok, rep.failed) == (8, 7, 1)
        assert set(t1.calls) == ALL and len(t1.calls) == 8
        recs = sw.results()
        assert len(recs) == 8
        bad = [r for r in recs if r["status"] == "failed"]
        assert len(bad) == 1
        assert (bad[0]["point"]["nodes"], bad[0]["seed"], bad[0]["method"]) == BAD
        assert "Traceback" in bad[0]["error"]
        assert "RuntimeError: injected failure at nodes=4 seed=2" in bad[0]["error"]
        assert bad[0]["metrics"] is None
        for r in recs:
            if r["status"] == "ok":
                assert r["error"] is None
                assert r["metrics"]["aoi_mean"] > 0
                assert r["wall"]["wall_s"] > 0
        assert rep.failures and "injected failure" in rep.failures[0][1]

    # rerun: nothing recomputed, the failure is still reported
    t2 = CountingTask()
    with _sweep(store, t2) as sw:
        assert sw.pending() == []
        assert [t.key[1:] for t in sw.pending(retry_failed=True)] == [(2, "bides")]
        rep = sw.run(client="inprocess", progress=False)
        assert t2.calls == []
        assert (rep.done_before, rep.failed_before, rep.submitted) == (7, 1, 0)
        assert len(rep.failures) == 1 and "retry-failed" in rep.text()

    # retry_failed: only the failed run is recomputed, now it succeeds
    t3 = CountingTask()
    with _sweep(store, t3) as sw:
        rep = sw.run(client="inprocess", progress=False, retry_failed=True)
        assert t3.calls == [BAD]
        assert (rep.submitted, rep.ok, rep.failed, rep.failures) == (1, 1, 0, [])
        assert all(r["status"] == "ok" for r in sw.results())
    rows = _rows(store)
    assert len(rows) == 8
    assert sorted(a for *_, a in rows) == [1] * 7 + [2]  # attempts: the retried run twice


def test_interrupt_after_k_results_then_resume(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    t1 = CountingTask()
    seen: list[tuple[int, str]] = []

    def stop_after_three(task: object, payload: dict[str, object]) -> None:
        seen.append((1, str(payload["status"])))
        if len(seen) == 3:
            raise KeyboardInterrupt

    with _sweep(store, t1) as sw, pytest.raises(KeyboardInterrupt):
        sw.run(client="inprocess", progress=False, on_record=stop_after_three)
    assert len(t1.calls) == 3
    assert len(_rows(store)) == 3  # committed: visible to another connection
    first = set(t1.calls)

    t2 = CountingTask()
    with _sweep(store, t2) as sw:
        assert len(sw.pending()) == 5
        rep = sw.run(client="inprocess", progress=False)
        assert len(t2.calls) == 5 and not first & set(t2.calls)
        assert first | set(t2.calls) == ALL
        assert (rep.done_before, rep.ok) == (3, 5)
    assert [a for *_, a in _rows(store)] == [1] * 8


def test_kill_mid_run_loses_only_the_run_in_flight(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    t1 = CountingTask(interrupt_at=4)
    with _sweep(store, t1) as sw, pytest.raises(KeyboardInterrupt):
        sw.run(client="inprocess", progress=False)
    assert len(_rows(store)) == 3
    killed = t1.calls[3]
    t2 = CountingTask()
    with _sweep(store, t2) as sw:
        sw.run(client="inprocess", progress=False)
    assert len(t2.calls) == 5 and killed in t2.calls
    assert set(t1.calls[:3]) | set(t2.calls) == ALL


def test_store_is_wal_and_keyed_by_hash_seed_method(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    with ResultStore(store) as st:
        mode = st._db.execute("PRAGMA journal_mode").fetchone()[0]
        assert mode == "wal"
        st.put(("abc", 1, "none"), "ok", {"metrics": {"x": 1.0}})
        st.put(("abc", 2, "none"), "failed", {"error": "boom"})
        st.put(("abc", 2, "none"), "ok", {"metrics": {"x": 2.0}})
        assert len(st) == 2
        rec = st.get(("abc", 2, "none"))
        assert rec is not None
        assert (rec["status"], rec["attempts"], rec["metrics"], rec["error"]) == (
            "ok",
            2,
            {"x": 2.0},
            None,
        )
        assert st.statuses() == {("abc", 1, "none"): "ok", ("abc", 2, "none"): "ok"}
        with pytest.raises(ValueError):
            st.put(("abc", 3, "none"), "maybe", {})
    with ResultStore(store) as st:  # reopened: everything is still there
        assert len(st) == 2


def test_changed_base_scenario_is_a_different_run(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    with Sweep(tiny_base(), GRID, ["none"], [1], store, task=CountingTask()) as sw:
        sw.run(client="inprocess", progress=False)
    base2 = replace(tiny_base(), f_render=30.0)
    with Sweep(base2, GRID, ["none"], [1], store, task=CountingTask()) as sw:
        assert len(sw.pending()) == 2  # new config hash: not mistaken for the stored runs
