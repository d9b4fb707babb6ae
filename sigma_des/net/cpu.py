"""The CPU stage: machines, processes and bursts (docs/MODEL.md, "Deployment and CPU").

Every process of a deployment (the broker, the alignment server, each physics
host's client process) is ONE thread on a machine of ``cores`` cores. A *burst*
of CPU demand ``D`` of a process arriving at ``a`` is placed at its arrival:

* it is ready at ``r = a if a > thread_free else thread_free`` (its thread serves
  one burst at a time, in arrival order);
* it runs for ``L = D * scale``, where ``scale = cores / (cores - background)`` is
  computed once per process (background load slows every burst down); a burst that
  finds its thread idle (``a > thread_free``) is a *wake-up* and runs for
  ``L = (D + wake) * scale``: a live loop pays a fixed cost to leave its wait and
  come back to it, shared by every message it handles before it waits again;
* it starts at the earliest ``s >= r`` at which some core has ``[s, s + L)`` free of
  the reservations already made (the lowest-index core on ties): a core idle in a
  gap before a later reservation takes a burst that fits in the gap (backfilling),
  so a thread's backlog never keeps a core idle;
* the thread is free again at ``s + L``; the core holds ``[s, s + L)``.

Live processes are single-threaded loops that serve one message at a time, and
a message's demand (~0.1 ms) is far below a scheduler quantum, so bursts run to
completion (non-preemptive); processor sharing would re-time every burst in
service at every arrival. A core keeps at most :data:`RESERVATIONS` reservations
(those ended by the arrival are dropped first); beyond that its two earliest merge
into one (the gap between them is then not used), the same rule as the compiled
core's. A zero demand is no burst: callers do not call :meth:`Process.burst` for
it, so nothing is touched.

Like SimPy's resources, this module only computes times; the network
(:mod:`sigma_des.net.network`) and the broker (:mod:`sigma_des.net.broker`)
schedule what they say. Each process counts its busy CPU seconds and its longest
wait in the metrics window; :meth:`Cpu.report` hands them over in one
:class:`CpuReport`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sigma_des.net.spec import DeploymentSpec

__all__ = ["RESERVATIONS", "Cpu", "CpuReport", "Machine", "Process", "ProcessReport"]

#: most reservations a core keeps (beyond: its two earliest merge into one)
RESERVATIONS = 64


class Machine:
    """A machine's cores: each core's reservations ``[start, end)``, in start order.

    Args:
        name: the machine's name (``all``, ``broker``, ``server``, ``host<h>``).
        cores: number of cores.
    """

    __slots__ = ("name", "cores")

    def __init__(self, name: str, cores: int) -> None:
        self.name = name
        self.cores: list[list[tuple[float, float]]] = [[] for _ in range(cores)]

    def place(self, a: float, r: float, length: float) -> tuple[float, int]:
        """The earliest start ``s >= r`` of a burst of ``length`` arriving at ``a``, and
        its core (the lowest index on ties); nothing is reserved yet."""
        best = -1.0
        core = 0
        for c, ivs in enumerate(self.cores):
            while ivs and ivs[0][1] <= a:  # ended by now: no later burst can meet it
                del ivs[0]
            s = r
            for st, en in ivs:
                if en <= s:
                    continue
                if s + length <= st:  # fits in the gap before this reservation
                    break
                s = en
            if c == 0 or s < best:
                best = s
                core = c
        return best, core

    def reserve(self, c: int, s: float, end: float) -> None:
        """Core ``c`` holds ``[s, end)`` (a gap :meth:`place` found)."""
        ivs = self.cores[c]
        i = len(ivs)
        while i > 0 and ivs[i - 1][0] > s:
            i -= 1
        ivs.insert(i, (s, end))
        if len(ivs) > RESERVATIONS:
            ivs[0:2] = [(ivs[0][0], ivs[1][1])]


class Process:
    """One single-threaded process on a machine, serving its bursts in arrival order.

    Args:
        name: the process's name (``broker``, ``server``, ``host<h>``).
        machine: the machine it runs on.
        scale: the slow-down of every burst, ``cores / (cores - background)``.
        warmup: bursts (and busy time) before this time are not counted.
        end: busy time at or after this time is not counted.
        wake: CPU seconds a burst that finds the thread idle costs more (0: none).

    Attributes:
        free: time the thread is free again (s).
        busy: CPU seconds the process held a core inside the metrics window.
        max_wait: longest wait of a burst arriving in the window before its start (s).
        bursts: bursts arriving in the window.
    """

    __slots__ = ("name", "machine", "scale", "warmup", "end", "wake", "free", "busy",
                 "max_wait", "bursts")

    def __init__(self, name: str, machine: Machine, scale: float, warmup: float,
                 end: float, wake: float = 0.0) -> None:
        self.name = name
        self.machine = machine
        self.scale = scale
        self.wake = wake
        self.warmup = warmup
        self.end = end
        self.free = -math.inf  # never busy yet: the first burst is a wake-up
        self.busy = 0.0
        self.max_wait = 0.0
        self.bursts = 0

    def acquire(self, a: float, length: float) -> tuple[float, int]:
        """Start time and core of a burst of ``length`` arriving at ``a`` (nothing is
        held yet)."""
        tf = self.free
        r = a if a > tf else tf
        return self.machine.place(a, r, length)

    def hold(self, a: float, s: float, c: int, end: float) -> None:
        """A burst arrived at ``a``, started at ``s`` on core ``c`` and ends at ``end``."""
        self.free = end
        self.machine.reserve(c, s, end)
        if self.warmup <= a < self.end:
            self.bursts += 1
            w = s - a
            if w > self.max_wait:
                self.max_wait = w
        lo = s if s > self.warmup else self.warmup
        hi = end if end < self.end else self.end
        if hi > lo:
            self.busy += hi - lo

    def carried(self, free: float, busy: float, max_wait: float, bursts: int) -> None:
        """Bursts served elsewhere (the compiled core): free again at ``free`` at the
        latest, ``busy`` more CPU seconds, a longest wait of ``max_wait``, ``bursts``
        more bursts in the window."""
        self.free = max(self.free, free)
        self.busy += busy
        self.max_wait = max(self.max_wait, max_wait)
        self.bursts += bursts

    def span(self, a: float, demand: float) -> tuple[float, float]:
        """Serve a burst of ``demand`` CPU seconds (> 0) arriving at ``a`` (plus ``wake``
        if the thread is idle then); its start and end."""
        w = self.wake
        idle = w > 0.0 and a > self.free
        length = (demand + w) * self.scale if idle else demand * self.scale
        s, c = self.acquire(a, length)
        end = s + length
        self.hold(a, s, c, end)
        return s, end

    def burst(self, a: float, demand: float) -> float:
        """Serve a burst of ``demand`` CPU seconds (> 0) arriving at ``a``; its end."""
        return self.span(a, demand)[1]


@dataclass(frozen=True)
class ProcessReport:
    """One process's counters in the metrics window.

    Attributes:
        name: ``broker``, ``server`` or ``host<h>``.
        machine: the machine it ran on.
        busy: CPU seconds it held a core (demands times the background slow-down).
        max_wait: longest wait of a burst before its start (s).
        bursts: bursts that arrived in the window.
    """

    name: str
    machine: str
    busy: float
    max_wait: float
    bursts: int


@dataclass(frozen=True)
class CpuReport:
    """The CPU stage's counters at the end of a run.

    Attributes:
        processes: per process (broker, server, hosts in order), its counters.
        cores: cores per machine.
        machines: machine names in order.
    """

    processes: tuple[ProcessReport, ...]
    cores: int
    machines: tuple[str, ...]


class Cpu:
    """The machines and processes of a deployment with a CPU stage.

    Machines: ``colocated``: one machine (``all``) holds every process;
    ``dedicated``: ``broker``, ``server`` and ``host<h>`` machines, one per process.

    Args:
        spec: the deployment (its preset must not be ``none``).
        hosts: number of physics hosts.
        warmup: start of the metrics window (s).
        end: end of the metrics window (s).

    Attributes:
        broker: the broker's process.
        server: the alignment server's process.
        hosts: each physics host's client process.
    """

    def __init__(self, spec: DeploymentSpec, hosts: int, warmup: float, end: float) -> None:
        if not spec.cpu:
            raise ValueError("a deployment without a CPU stage (preset 'none') has no Cpu")
        c = spec.cores
        scale = c / (c - spec.background)
        names = ["broker", "server", *(f"host{h}" for h in range(hosts))]
        if spec.preset == "colocated":
            one = Machine("all", c)
            machines = [one] * len(names)
            self.machines = [one]
        else:
            machines = [Machine(n, c) for n in names]
            self.machines = machines
        wakes = [0.0, spec.server_wake, *([spec.host_wake] * hosts)]
        procs = [Process(n, m, scale, warmup, end, w)
                 for n, m, w in zip(names, machines, wakes, strict=True)]
        self.cores = c
        self.broker = procs[0]
        self.server = procs[1]
        self.hosts = procs[2:]
        self.processes = procs

    def report(self) -> CpuReport:
        """Every process's counters (the one hook the results read)."""
        return CpuReport(
            processes=tuple(ProcessReport(p.name, p.machine.name, p.busy, p.max_wait, p.bursts)
                            for p in self.processes),
            cores=self.cores,
            machines=tuple(m.name for m in self.machines),
        )
