"""The CPU stage: machines, processes and bursts (docs/MODEL.md, "Deployment and CPU").

Every process of a deployment (the broker, the alignment server, each physics
host's client process) is ONE thread on a machine of ``cores`` cores. A *burst*
of CPU demand ``D`` of a process arriving at ``a`` is allocated at its arrival,
first come first served, the way the broker's Lindley recursion is:

* the core: the lowest-index core of the machine with the smallest free time;
* ``s = a if a > thread_free else thread_free; s = s if s > core_free else core_free``;
* ``end = s + D * scale``, where ``scale = cores / (cores - background)`` is
  computed once per process (background load slows every burst down);
* the thread and the core are free again at ``end``.

Live processes are single-threaded loops that serve one message at a time, and
a message's demand (~0.1 ms) is far below a scheduler quantum, so bursts run to
completion (non-preemptive FCFS); processor sharing would re-time every burst in
service at every arrival. A zero demand is no burst: callers do not call
:meth:`Process.burst` for it, so nothing is touched.

Like SimPy's resources, this module only computes times; the network
(:mod:`sigma_des.net.network`) and the broker (:mod:`sigma_des.net.broker`)
schedule what they say. Each process counts its busy CPU seconds and its longest
wait in the metrics window; :meth:`Cpu.report` hands them over in one
:class:`CpuReport`.
"""

from __future__ import annotations

from dataclasses import dataclass

from sigma_des.net.spec import DeploymentSpec

__all__ = ["Cpu", "CpuReport", "Machine", "Process", "ProcessReport"]


class Machine:
    """A machine's cores: the time each is free again (FCFS, non-preemptive).

    Args:
        name: the machine's name (``all``, ``broker``, ``server``, ``host<h>``).
        cores: number of cores.
    """

    __slots__ = ("name", "free")

    def __init__(self, name: str, cores: int) -> None:
        self.name = name
        self.free = [0.0] * cores

    def pick(self) -> int:
        """The lowest-index core with the smallest free time."""
        free = self.free
        return free.index(min(free))


class Process:
    """One single-threaded process on a machine, serving its bursts in arrival order.

    Args:
        name: the process's name (``broker``, ``server``, ``host<h>``).
        machine: the machine it runs on.
        scale: the slow-down of every burst, ``cores / (cores - background)``.
        warmup: bursts (and busy time) before this time are not counted.
        end: busy time at or after this time is not counted.

    Attributes:
        free: time the thread is free again (s).
        busy: CPU seconds the process held a core inside the metrics window.
        max_wait: longest wait of a burst arriving in the window before its start (s).
        bursts: bursts arriving in the window.
    """

    __slots__ = ("name", "machine", "scale", "warmup", "end", "free", "busy", "max_wait",
                 "bursts")

    def __init__(self, name: str, machine: Machine, scale: float, warmup: float,
                 end: float) -> None:
        self.name = name
        self.machine = machine
        self.scale = scale
        self.warmup = warmup
        self.end = end
        self.free = 0.0
        self.busy = 0.0
        self.max_wait = 0.0
        self.bursts = 0

    def acquire(self, a: float) -> tuple[float, int]:
        """Start time and core of a burst arriving at ``a`` (nothing is held yet)."""
        c = self.machine.pick()
        tf = self.free
        cf = self.machine.free[c]
        s = a if a > tf else tf
        s = s if s > cf else cf
        return s, c

    def hold(self, a: float, s: float, c: int, end: float) -> None:
        """A burst arrived at ``a``, started at ``s`` on core ``c`` and ends at ``end``."""
        self.free = end
        self.machine.free[c] = end
        if self.warmup <= a < self.end:
            self.bursts += 1
            w = s - a
            if w > self.max_wait:
                self.max_wait = w
        lo = s if s > self.warmup else self.warmup
        hi = end if end < self.end else self.end
        if hi > lo:
            self.busy += hi - lo

    def burst(self, a: float, demand: float) -> float:
        """Serve a burst of ``demand`` CPU seconds (> 0) arriving at ``a``; its end."""
        s, c = self.acquire(a)
        end = s + demand * self.scale
        self.hold(a, s, c, end)
        return end


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
        procs = [Process(n, m, scale, warmup, end) for n, m in zip(names, machines, strict=True)]
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
