"""Concurrent sweeps on one store share the work through leases (issue 9.10)."""

from __future__ import annotations

import os
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from sweep_helpers import CountingTask, tiny_base

from sigma_des.sweep import ResultStore, Sweep
from sigma_des.sweep.executors import sigint_ignored

GRID = {"nodes": [3, 4]}
METHODS = ["none"]
SEEDS = [1, 2, 3]


def test_a_second_sweep_takes_the_runs_the_first_has_not_claimed(tmp_path: Path) -> None:
    """Sweep A claims one run at a time (in process); after its first result, sweep
    B starts on the same store and takes every run A has not claimed. No run is
    executed twice (attempts 1 everywhere); A then finds nothing left."""
    store = tmp_path / "s.sqlite"
    a_task, b_task = CountingTask(), CountingTask()
    reports = []

    def start_b(_task, _payload):  # type: ignore[no-untyped-def]
        if not reports:
            with Sweep(tiny_base(), GRID, METHODS, SEEDS, store, task=b_task) as b:
                reports.append(b.run(client="inprocess", progress=False))

    with Sweep(tiny_base(), GRID, METHODS, SEEDS, store, task=a_task) as a:
        rep_a = a.run(client="inprocess", progress=False, on_record=start_b)
    assert len(a_task.calls) == 1 and len(b_task.calls) == 5
    assert rep_a.submitted == 1 and reports[0].submitted == 5
    assert not set(a_task.calls) & set(b_task.calls)
    with sqlite3.connect(store) as db:
        assert db.execute("SELECT COUNT(*), MAX(attempts) FROM runs").fetchone() == (6, 1)
        assert db.execute("SELECT COUNT(*) FROM leases").fetchone() == (0,)


def test_live_dead_and_expired_leases(tmp_path: Path) -> None:
    key = ("h", 1, "none")
    with ResultStore(tmp_path / "s.sqlite") as st:
        assert st.claim([key], "A", 60.0, 10) == [key]
        assert st.claim([key], "B", 60.0, 10) == []  # A's process (this one) is alive
        assert st.leased([key], "B") == [(key, f"{socket.gethostname()}:{os.getpid()}")]
        assert st.claim([key], "A", 60.0, 10) == [key]  # an owner may renew
        # a lease of a process that has exited is dead at once
        p = subprocess.Popen([sys.executable, "-c", "pass"])
        p.wait()
        st._db.execute("UPDATE leases SET owner='C', pid=?", (p.pid,))
        assert st.claim([key], "B", 60.0, 10) == [key]
        # an expired lease is dead even if its process lives
        st._db.execute("UPDATE leases SET owner='C', pid=?, expires=?",
                       (os.getppid(), time.time() - 1))
        assert st.claim([key], "B", 60.0, 10) == [key]
        st.put(key, "ok", {"metrics": {}})
        assert st.claim([key], "D", 60.0, 10) == []  # stored: nothing to claim
        assert st._db.execute("SELECT COUNT(*) FROM leases").fetchone() == (0,)
        st.release("B")


def test_interrupted_sweep_releases_its_leases(tmp_path: Path) -> None:
    store = tmp_path / "s.sqlite"
    task = CountingTask(interrupt_at=2)
    with Sweep(tiny_base(), GRID, METHODS, SEEDS, store, task=task) as sw:
        try:
            sw.run(client="inprocess", progress=False)
        except KeyboardInterrupt:
            pass
    with sqlite3.connect(store) as db:
        assert db.execute("SELECT COUNT(*) FROM leases").fetchone() == (0,)
    with Sweep(tiny_base(), GRID, METHODS, SEEDS, store, task=CountingTask()) as sw:
        assert sw.run(client="inprocess", progress=False).submitted == 5


def test_workers_started_with_sigint_ignored() -> None:
    """Processes started while the cluster starts inherit SIGINT ignored, so Ctrl-C
    gives them no KeyboardInterrupt traceback."""
    code = "import signal; print(signal.getsignal(signal.SIGINT) == signal.SIG_IGN)"
    with sigint_ignored():
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "True"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "False"
