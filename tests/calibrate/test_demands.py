"""CPU records and the Utilization-Law fit: known demands recovered exactly from a
synthetic run, message counts from the ledgers, and the meter on our own process."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from sigma_des.calibrate.demands import fit_demands, read_cpu
from sigma_des.live.cpu import (
    CPU_COLUMNS,
    RUNQ_COLUMN,
    THREAD_COLUMNS,
    WAKE_COLUMNS,
    WALL_COLUMN,
    CpuMeter,
    message_counts,
    write_cpu,
)
from sigma_des.live.ledger import publishes

#: A synthetic run: per process (idle CPU rate, messages, demand per message).
KNOWN = {"server": (0.010, 8000, 40e-6), "host0": (0.002, 3000, 120e-6),
         "host1": (0.0, 2500, 150e-6), "broker": (0.001, 16000, 5e-6)}
IDLE_S, WINDOW_S = 1.25, 4.0


def _synthetic_rows() -> list[dict[str, float | int | str]]:
    rows: list[dict[str, float | int | str]] = []
    for pid, (name, (idle, msgs, demand)) in enumerate(KNOWN.items()):
        rows.append({"process": name, "pid": pid, "idle_s": IDLE_S, "idle_cpu_s": idle * IDLE_S,
                     "window_s": WINDOW_S, "cpu_s": idle * WINDOW_S + msgs * demand,
                     "messages": msgs})
    rows.append({"process": "background", "pid": -1, "idle_s": IDLE_S, "idle_cpu_s": 0.5,
                 "window_s": WINDOW_S, "cpu_s": 3.0, "messages": math.nan})
    return rows


def test_utilization_law_recovers_known_demands_exactly(tmp_path: Path) -> None:
    write_cpu({"bides": {"cpu": _synthetic_rows()}}, tmp_path)
    cpu = read_cpu(tmp_path)
    assert cpu is not None
    assert list(cpu.columns) == ["method", *CPU_COLUMNS, *WAKE_COLUMNS, WALL_COLUMN,
                                 RUNQ_COLUMN, *THREAD_COLUMNS]
    table, bg, warn = fit_demands(cpu)
    assert warn == []
    assert bg == {"bides": pytest.approx(0.75)}  # 3 CPU s in 4 s: 0.75 cores taken
    got = table.set_index("process")
    assert list(got.index) == list(KNOWN)  # background is not a process of ours
    for name, (idle, msgs, demand) in KNOWN.items():
        r = got.loc[name]
        assert r["idle_rate"] == pytest.approx(idle, rel=1e-12, abs=1e-15)
        assert r["demand_s"] == pytest.approx(demand, rel=1e-9)
        assert r["throughput_per_s"] == pytest.approx(msgs / WINDOW_S)
        # U = X * D (the law itself)
        assert r["utilization"] == pytest.approx(r["throughput_per_s"] * demand, rel=1e-9)


def test_rows_without_a_demand_are_warned_about() -> None:
    rows = _synthetic_rows()
    rows[0] = {**rows[0], "messages": 0}  # server: no messages
    rows[1] = {**rows[1], "cpu_s": 0.0}  # host0: less CPU than its idle rate explains
    table, _bg, warn = fit_demands(pd.DataFrame([{"method": "none", **r} for r in rows]))
    assert math.isnan(table.set_index("process").loc["server", "demand_s"])
    assert len(warn) == 2
    assert warn[0].startswith("none/server: no CPU demand")
    assert warn[1].startswith("none/host0: less CPU in the window")


def test_publishes_and_message_counts_from_the_ledgers() -> None:
    # QoS 1: 3 sent + 5 received PUBLISH = 8 packets each way (each with its PUBACK)
    srv = {"server.up": [999, 8], "server.down": [999, 8]}
    assert publishes(srv, 1) == 8
    assert publishes({"x.up": [1, 3], "x.down": [1, 5]}, 0) == 8
    hosts = {1: {"links": {"host1.up": [1, 4], "host1.down": [1, 4]}},
             0: {"links": {"host0.up": [1, 6], "host0.down": [1, 6]}}}
    assert message_counts(srv, hosts, 1) == {"server": 8, "host0": 6, "host1": 4, "broker": 18}


def test_meter_reads_our_own_cpu_time_and_the_background() -> None:
    m = CpuMeter({"server": os.getpid(), "gone": 2**22 + 12345})
    for label in ("idle0", "idle1", "w0"):
        m.mark(label)
    t = time.process_time()
    while time.process_time() - t < 0.2:  # 0.2 s of CPU, whatever the load
        pass
    m.mark("w1")
    rows = {r["process"]: r for r in m.rows({"server": 10})}
    assert rows["server"]["cpu_s"] == pytest.approx(0.2, abs=0.03)  # 10 ms clock ticks
    assert rows["server"]["messages"] == 10 and math.isnan(rows["gone"]["cpu_s"])
    assert rows["background"]["cpu_s"] >= 0.0 and rows["background"]["window_s"] > 0.0


def test_run_queue_wait_is_read_for_live_processes_and_nan_for_gone_ones() -> None:
    """Two busy processes pinned to one core wait on its run queue about half the time
    each (schedstat); a pid that does not exist reads NaN."""
    import multiprocessing as mp

    from sigma_des.live.cpu import runq_wait_s

    if not os.path.exists(f"/proc/{os.getpid()}/task"):
        pytest.skip("no /proc")
    core = sorted(os.sched_getaffinity(0))[0]
    ctx = mp.get_context("spawn")
    pinned = [ctx.Event() for _ in range(2)]
    procs = [ctx.Process(target=_spin, args=(core, 0.5, e)) for e in pinned]
    for p in procs:
        p.start()
    assert all(e.wait(20) for e in pinned)  # both spin on the one core from here
    time.sleep(0.2)
    waits = [runq_wait_s(p.pid) for p in procs if p.pid is not None]
    for p in procs:
        p.join(5)
    assert len(waits) == 2 and all(math.isfinite(w) and w >= 0.0 for w in waits)
    assert sum(waits) > 0.02  # one core for two spinning processes: someone waited
    assert math.isnan(runq_wait_s(2**22 + 12345))


def _spin(core: int, seconds: float, pinned: Any) -> None:
    """Burn CPU on ``core`` for ``seconds`` (a child of the run-queue test)."""
    os.sched_setaffinity(0, {core})
    pinned.set()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


def test_thread_times_split_the_main_thread_from_the_others() -> None:
    """This process's main thread sleeps while a second thread burns 0.2 s of CPU and
    then blocks on a pipe 20 times, the main thread writing a byte every 5 ms (each read
    a voluntary switch when it finds none waiting): the others' CPU grows by about
    0.2 s and their voluntary switches; the main thread's CPU by little, its switches
    (its sleeps) by at least 20; a gone pid reads NaN."""
    import threading

    from sigma_des.live.cpu import thread_times

    if not os.path.exists(f"/proc/{os.getpid()}/task"):
        pytest.skip("no /proc")
    go, done = threading.Event(), threading.Event()
    r, w = os.pipe()

    def work() -> None:
        go.wait(10)
        t0 = time.thread_time()
        while time.thread_time() - t0 < 0.2:
            pass
        for _ in range(20):
            os.read(r, 1)  # blocks: the byte comes 5 ms later
        done.wait(10)  # alive at the second reading: a thread gone takes its counts

    th = threading.Thread(target=work)
    th.start()
    try:
        before = thread_times(os.getpid())
        go.set()
        time.sleep(0.3)
        for _ in range(20):
            time.sleep(0.005)
            os.write(w, b"x")
        time.sleep(0.05)
        after = thread_times(os.getpid())
    finally:
        done.set()
        th.join(5)
        os.close(r)
        os.close(w)
    diff = (y - x for x, y in zip(before, after, strict=True))
    main_cpu, main_sw, net_cpu, net_sw, n_other = diff
    assert 0.15 < net_cpu < 0.6
    # each sleep of the main thread is a voluntary switch; the worker blocks on reads
    # (at least once: a loaded machine may let bytes pile up before it reads them)
    assert 0.0 <= main_cpu < 0.15 and main_sw >= 20
    assert net_sw >= 1
    assert after[4] >= 1 and n_other == 0  # the same other threads at both readings
    assert all(math.isnan(v) for v in thread_times(2**22 + 12345))
