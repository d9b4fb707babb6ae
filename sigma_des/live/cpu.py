"""CPU time of the live run's processes, for the Utilization-Law calibration.

A :class:`CpuMeter` reads the CPU seconds (user + system, all threads) of the
alignment server (this process), every host process and our broker through psutil
(``/proc/<pid>/stat`` on Linux, resolution one clock tick, 10 ms), and the busy
CPU seconds of the whole machine, at named marks. The runner marks an **idle
window** (after ``go`` is published, before the first trigger: every process is
connected and waiting, so its CPU rate there is the idle loop's cost) and the
**metrics window** ``[warmup, duration)`` of the method's clock. :meth:`CpuMeter.rows`
turns the marks into one row per process, plus a ``background`` row: the machine's
busy CPU minus ours, i.e. what other processes took from the cores during the
window. ``sigma-des calibrate`` fits the demands from these rows
(:mod:`sigma_des.calibrate.demands`). Each process row also carries its threads' time
waiting on a run queue in the window (:func:`runq_wait_s`, Linux schedstat): time it
was runnable but no core ran it, the wait the DES's CPU stage models as a burst's wait
for a core, and its threads split in two (:func:`thread_times`, :data:`THREAD_COLUMNS`):
the loop's (the process's main thread) and the others' (paho's network thread; in the
server's process also whatever else the runner runs), each its CPU (schedstat, ns) and
its voluntary context switches (each one a wait for something: the thread's
wake-ups), so the network thread's CPU per message and per wake-up can be told apart
from the loop's.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path
from typing import Any

import psutil

from sigma_des.live.cpumark import MarkAhead
from sigma_des.live.ledger import publishes

__all__ = ["CPU_COLUMNS", "CPU_FILE", "RUNQ_COLUMN", "THREAD_COLUMNS", "WAKE_COLUMNS",
           "WALL_COLUMN", "CpuMeter", "machine_busy", "message_counts", "runq_wait_s",
           "thread_times", "wake_columns", "wake_sums", "write_cpu"]

#: The CPU table of a ``sigma-des live --out`` directory.
CPU_FILE = "cpu.csv"

#: Columns of a CPU row (``cpu.csv``; ``summary.json``'s ``live.<method>.cpu``).
CPU_COLUMNS = ("process", "pid", "idle_s", "idle_cpu_s", "window_s", "cpu_s", "messages")
#: The loop thread's wake-up sums of a process (:class:`~sigma_des.live.loop.WakeStats`:
#: wake-ups, calls, the loop thread's CPU seconds in them, the sums of ``k**2`` and
#: ``k * cpu``); NaN for the broker (not our loop) and in files written before them.
WAKE_COLUMNS = ("wakes", "calls", "loop_cpu_s", "skk", "skc")
#: The wake-ups' wall seconds (the loop thread busy, running or not); NaN where
#: :data:`WAKE_COLUMNS` are and in files written before it. Not needed by the fit.
WALL_COLUMN = "loop_wall_s"
#: A process's threads' run-queue wait in the metrics window (s; NaN where not readable).
RUNQ_COLUMN = "runq_wait_s"
#: In the metrics window: the main (loop) thread's CPU (s) and voluntary context
#: switches, the other threads' (paho's network thread) CPU and voluntary switches,
#: and how many other threads there were at its end (NaN where not readable).
THREAD_COLUMNS = ("main_cpu_s", "main_switches", "net_cpu_s", "net_switches", "net_threads")


def message_counts(server_links: dict[str, list[int]], host_stats: dict[int, dict[str, Any]],
                   qos: int) -> dict[str, int]:
    """PUBLISH messages each process handled in the metrics window, from the ledgers: the
    server's, each reporting host's (``stats["links"]``) and the broker's (every PUBLISH a
    client sent came in, every one a client received went out)."""
    out = {"server": publishes(server_links, qos)}
    for h, st in sorted(host_stats.items()):
        out[f"host{h}"] = publishes(st.get("links", {}), qos)
    out["broker"] = sum(out.values())
    return out


def wake_sums(server: dict[str, Any], host_stats: dict[int, dict[str, Any]]
              ) -> dict[str, dict[str, Any]]:
    """The wake-up sums of the server's loop and each reporting host's (``stats["wake"]``),
    by process name (``server``, ``host<H>``)."""
    out = {"server": server}
    for h, st in sorted(host_stats.items()):
        if "wake" in st:
            out[f"host{h}"] = st["wake"]
    return out


def wake_columns(wakes: dict[str, dict[str, Any]] | None, name: str) -> dict[str, Any]:
    """The :data:`WAKE_COLUMNS` and :data:`WALL_COLUMN` of process ``name`` from
    :func:`wake_sums` (NaN if absent)."""
    w = (wakes or {}).get(name)
    if w is None:
        return dict.fromkeys((*WAKE_COLUMNS, WALL_COLUMN), math.nan)
    return {"wakes": w["wakes"], "calls": w["calls"], "loop_cpu_s": w["cpu_s"],
            "skk": w["skk"], "skc": w["skc"], WALL_COLUMN: w.get("wall_s", math.nan)}


def machine_busy() -> float:
    """Busy CPU seconds of the whole machine since boot (all cores; idle and iowait
    excluded)."""
    t = psutil.cpu_times()
    busy = t.user + t.system
    for name in ("nice", "irq", "softirq", "steal"):
        busy += getattr(t, name, 0.0)
    return float(busy)


def runq_wait_s(pid: int) -> float:
    """Seconds the threads of process ``pid`` have waited on a run queue (runnable, no
    core), summed over its live threads (``/proc/<pid>/task/*/schedstat``, second
    field, ns); NaN where not readable (not Linux, the process gone). A thread that
    exits takes its count with it: paho's and the loop's threads live for the run."""
    total = 0
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            try:
                total += int((task / "schedstat").read_text().split()[1])
            except (OSError, IndexError, ValueError):
                continue  # the thread ended meanwhile
    except OSError:
        return math.nan
    return total / 1e9


def _switches(task: Path) -> int:
    for line in (task / "status").read_text().splitlines():
        if line.startswith("voluntary_ctxt_switches:"):
            return int(line.split()[1])
    raise ValueError("no voluntary_ctxt_switches")


def thread_times(pid: int) -> tuple[float, float, float, float, float]:
    """``(main CPU s, main voluntary switches, others' CPU s, others' voluntary
    switches, other threads)`` of process ``pid`` now: each thread's time on a core
    (``/proc/<pid>/task/<tid>/schedstat``, first field, ns) and its voluntary context
    switches (``status``); the main thread is ``tid == pid`` (the loop's). NaN
    everywhere where not readable (not Linux, the process gone); a thread that ends
    meanwhile is left out."""
    main = [0.0, 0.0]
    other = [0.0, 0.0, 0.0]
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            try:
                ns = int((task / "schedstat").read_text().split()[0])
                sw = _switches(task)
            except (OSError, IndexError, ValueError):
                continue
            if task.name == str(pid):
                main = [ns / 1e9, float(sw)]
            else:
                other[0] += ns / 1e9
                other[1] += sw
                other[2] += 1
    except OSError:
        return (math.nan,) * 5
    return main[0], main[1], other[0], other[1], other[2]


class CpuMeter:
    """CPU seconds of named processes (and of the machine) at named marks.

    Args:
        procs: process name (``server``, ``host<H>``, ``broker``) -> pid.
    """

    def __init__(self, procs: dict[str, int]) -> None:
        self._ps: dict[str, psutil.Process | None] = {}
        for name, pid in procs.items():
            try:
                self._ps[name] = psutil.Process(pid)
            except psutil.Error:
                self._ps[name] = None
        self.pids = dict(procs)
        self.marks: dict[str, tuple[float, float, dict[str, float]]] = {}
        self.runq: dict[str, dict[str, float]] = {}
        self.threads: dict[str, dict[str, tuple[float, ...]]] = {}
        self._ahead: dict[str, MarkAhead] = {}
        self._helper: MarkAhead | None = None

    def _cpu(self, p: psutil.Process | None) -> float:
        if p is None:
            return math.nan
        try:
            t = p.cpu_times()
        except psutil.Error:  # exited (killed host, restarted broker)
            return math.nan
        return float(t.user + t.system)

    def mark(self, label: str) -> None:
        """Record the wall clock, the machine's busy CPU and every process's CPU and
        run-queue wait now."""
        cpu = {name: self._cpu(p) for name, p in self._ps.items()}
        self.marks[label] = (time.monotonic(), machine_busy(), cpu)
        self.runq[label] = {name: runq_wait_s(self.pids[name]) for name in self._ps}
        self.threads[label] = {name: thread_times(self.pids[name]) for name in self._ps}

    def helper(self) -> None:
        """Start the helper process of the next :meth:`mark_ahead` now (before the run)."""
        self._helper = MarkAhead(self.pids)

    def mark_ahead(self, label: str, t0: float, when: float, loop: Any) -> None:
        """Have the helper process (:meth:`helper`; started now if it was not) mark
        ``label`` at ``when`` seconds of the run that starts at ``time.monotonic()`` time
        ``t0`` (a mark inside the run, off the server's ``loop``:
        :mod:`sigma_des.live.cpumark`); :meth:`collect` reads it."""
        ahead = self._helper or MarkAhead(self.pids)
        self._helper = None
        ahead.arm(t0 + when)
        self._ahead[label] = ahead

    def collect(self, timeout: float = 10.0) -> list[str]:
        """Read the marks :meth:`mark_ahead` asked for; why any is missing (its window's
        rows are then NaN)."""
        why = []
        for label, ahead in self._ahead.items():
            if time.monotonic() < ahead.at:  # the run ended first (interrupted)
                ahead.cancel()
                why.append(f"CPU mark {label!r} not taken (the run ended before it): its "
                           "window's CPU rows are NaN")
                continue
            got = ahead.result(timeout)
            if isinstance(got, str):
                why.append(f"CPU mark {label!r} not taken ({got}): its window's CPU rows are NaN")
                continue
            self.marks[label], self.runq[label], self.threads[label] = got
        self._ahead.clear()
        return why

    def close(self) -> None:
        """Stop every helper process still waiting (a run that ended early)."""
        for ahead in [*self._ahead.values(), *([self._helper] if self._helper else [])]:
            ahead.cancel()
        self._ahead.clear()
        self._helper = None

    def _thread_columns(self, name: str) -> dict[str, float]:
        """:data:`THREAD_COLUMNS` of process ``name`` over the metrics window (the
        count of other threads: at its end)."""
        nan = (math.nan,) * len(THREAD_COLUMNS)
        a = self.threads.get("w0", {}).get(name, nan)
        b = self.threads.get("w1", {}).get(name, nan)
        vals = [y - x for x, y in zip(a[:-1], b[:-1], strict=True)] + [b[-1]]
        return dict(zip(THREAD_COLUMNS, vals, strict=True))

    def _span(self, a: str, b: str) -> tuple[float, float, dict[str, float]]:
        if a not in self.marks or b not in self.marks:
            return math.nan, math.nan, {n: math.nan for n in self._ps}
        (t0, m0, c0), (t1, m1, c1) = self.marks[a], self.marks[b]
        return t1 - t0, m1 - m0, {n: c1[n] - c0[n] for n in self._ps}

    def rows(self, messages: dict[str, int],
             wakes: dict[str, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
        """One row per process (columns :data:`CPU_COLUMNS` + :data:`WAKE_COLUMNS` +
        :data:`WALL_COLUMN` + :data:`RUNQ_COLUMN` + :data:`THREAD_COLUMNS`) and a
        ``background`` row.

        Args:
            messages: PUBLISH messages each process handled (sent + received) in the
                metrics window; a process without an entry gets NaN.
            wakes: each process's loop wake-up sums (:func:`wake_sums`); a process
                without an entry gets NaN.

        The idle window is marks ``idle0``..``idle1``, the metrics window ``w0``..``w1``.
        """
        idle_s, idle_m, idle = self._span("idle0", "idle1")
        win_s, win_m, win = self._span("w0", "w1")
        q0, q1 = self.runq.get("w0", {}), self.runq.get("w1", {})
        out: list[dict[str, Any]] = []
        for name in self._ps:
            out.append({"process": name, "pid": self.pids[name], "idle_s": idle_s,
                        "idle_cpu_s": idle[name], "window_s": win_s, "cpu_s": win[name],
                        "messages": messages.get(name, math.nan),
                        **wake_columns(wakes, name),
                        RUNQ_COLUMN: q1.get(name, math.nan) - q0.get(name, math.nan),
                        **self._thread_columns(name)})
        ours_idle = sum(v for v in idle.values() if math.isfinite(v))
        ours_win = sum(v for v in win.values() if math.isfinite(v))
        out.append({"process": "background", "pid": -1, "idle_s": idle_s,
                    "idle_cpu_s": max(idle_m - ours_idle, 0.0), "window_s": win_s,
                    "cpu_s": max(win_m - ours_win, 0.0), "messages": math.nan,
                    **wake_columns(None, "background"), RUNQ_COLUMN: math.nan,
                    **dict.fromkeys(THREAD_COLUMNS, math.nan)})
        return out


def write_cpu(live: dict[str, dict[str, Any]], out_dir: Path) -> Path:
    """Write every method's CPU rows (``live[method]["cpu"]``) to ``out_dir/cpu.csv``
    (columns ``method`` + :data:`CPU_COLUMNS` + :data:`WAKE_COLUMNS` + the wall, run-queue
    and thread columns; NaN where not measured)."""
    path = out_dir / CPU_FILE
    cols = (*CPU_COLUMNS, *WAKE_COLUMNS, WALL_COLUMN, RUNQ_COLUMN, *THREAD_COLUMNS)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(("method", *cols))
        for method, info in live.items():
            for r in info.get("cpu", []):
                w.writerow((method, *(r.get(c, math.nan) for c in cols)))
    return path
