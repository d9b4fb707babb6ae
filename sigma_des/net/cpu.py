"""The CPU stage: machines, processes and bursts (docs/concepts/deployment.md).

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

A process may have a second thread, its *network thread* (``net_msg``, ``net_wake``:
paho's, which reads, parses and stamps what the process receives and writes what it
sends): its bursts (:meth:`Process.net_span`) are served in arrival order on a thread
of their own, placed on the same cores, and a burst that finds that thread idle costs
``net_wake`` more.

Bursts run to completion (non-preemptive; why: docs/concepts/decisions.md). A core
keeps at most :data:`RESERVATIONS` reservations; beyond that its two earliest merge. A
zero demand is no burst. This module only computes times; the network and the broker
schedule them; :meth:`Cpu.report` hands the CPU figures over (:class:`CpuReport`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sigma_des.net.spec import DeploymentSpec

__all__ = ["LOAD_WINDOW", "RESERVATIONS", "U_CAP", "Cpu", "CpuReport", "Machine", "Process",
           "ProcessReport", "queue_wait"]

#: most reservations a core keeps (beyond: its two earliest merge into one)
RESERVATIONS = 64
#: length of the windows a machine's utilisation is measured over (s): a burst's
#: run-queue wait follows the previous window's utilisation
LOAD_WINDOW = 0.05
#: highest utilisation :func:`queue_wait` is evaluated at (its wait grows without bound
#: towards 1)
U_CAP = 0.95


def queue_wait(cores: int, u: float) -> float:
    """Mean wait for a core over mean service of an M/M/c queue (Erlang C), ``c = cores``
    at utilisation ``u`` (capped at :data:`U_CAP`; 0 at ``u <= 0``).

    Erlang B by its stable recursion ``B_k = A·B_{k-1} / (k + A·B_{k-1})`` with
    ``A = c·u``, then ``C = B / (1 - u·(1 - B))`` and ``W_q / S = C / (c·(1 - u))``.
    """
    if u <= 0.0:
        return 0.0
    if u > U_CAP:
        u = U_CAP
    a = cores * u
    b = 1.0
    for k in range(1, cores + 1):
        b = a * b / (k + a * b)
    c = b / (1.0 - u * (1.0 - b))
    return c / (cores * (1.0 - u))


class Machine:
    """A machine's cores: each core's reservations ``[start, end)``, in start order.

    Args:
        name: the machine's name (``all``, ``broker``, ``server``, ``host<h>``).
        cores: number of cores.
    """

    __slots__ = ("name", "cores", "growth", "bg", "w_end", "w_busy", "q")

    def __init__(self, name: str, cores: int, growth: bool = False,
                 background: float = 0.0) -> None:
        self.name = name
        self.cores: list[list[tuple[float, float]]] = [[] for _ in range(cores)]
        self.growth = growth
        self.bg = background
        self.w_end = LOAD_WINDOW  # end of the current load window
        self.w_busy = 0.0  # CPU seconds of the bursts arriving in it
        self.q = queue_wait(cores, background / cores) if growth else 0.0

    def load_wait(self, a: float) -> float:
        """The queue's run-queue wait per CPU second for a burst arriving at ``a``:
        :func:`queue_wait` at the utilisation of the last whole window before ``a``
        (our CPU plus the background, over the cores); 0 without growth."""
        if not self.growth:
            return 0.0
        if a >= self.w_end:
            n = len(self.cores)
            busy = self.w_busy if a < self.w_end + LOAD_WINDOW else 0.0
            self.q = queue_wait(n, (busy / LOAD_WINDOW + self.bg) / n)
            self.w_end += LOAD_WINDOW * (1.0 + math.floor((a - self.w_end) / LOAD_WINDOW))
            self.w_busy = 0.0
        return self.q

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
        side: CPU seconds a wake-up costs more on the process's other thread, beside
            its own: placed on the machine's cores from the arrival, not holding the
            thread (0: none).
        net: ``(net_msg, net_wake)``: CPU seconds of a burst on the network thread, and
            what one that finds that thread idle costs more (both 0: no such thread).
        switch: the interpreter lock's switch interval (s): a received copy's
            network-thread burst waits for the loop thread to be free at most this long.
        grow: its bursts also wait the machine's queue (:meth:`Machine.load_wait`; the
            machine must have ``growth``).

    Attributes:
        free: time the thread is free again (s).
        busy: CPU seconds the process held a core inside the metrics window.
        max_wait: longest wait of a burst arriving in the window before its start (s).
        bursts: bursts arriving in the window.
        net_free: time the network thread is free again (s).
    """

    __slots__ = ("name", "machine", "scale", "warmup", "end", "wake", "side", "runq", "free",
                 "busy", "max_wait", "bursts", "queued", "net_msg", "net_wake", "net_free",
                 "switch", "grow")

    def __init__(self, name: str, machine: Machine, scale: float, warmup: float,
                 end: float, wake: float = 0.0, runq: float = 0.0, side: float = 0.0,
                 net: tuple[float, float] = (0.0, 0.0), switch: float = 0.0,
                 grow: bool = True) -> None:
        self.name = name
        self.grow = grow
        self.net_msg, self.net_wake = net
        self.net_free = -math.inf
        self.switch = switch
        self.machine = machine
        self.scale = scale
        self.wake = wake
        self.side = side
        self.runq = runq
        self.queued = 0.0
        self.warmup = warmup
        self.end = end
        self.free = -math.inf  # never busy yet: the first burst is a wake-up
        self.busy = 0.0
        self.max_wait = 0.0
        self.bursts = 0

    def acquire(self, a: float, length: float, wait: float = 0.0) -> tuple[float, int]:
        """Start time and core of a burst of ``length`` arriving at ``a`` that waits
        ``wait`` on the run queue once its thread is free (nothing is held yet)."""
        tf = self.free
        r = a if a > tf else tf
        nf = self.net_free
        if self.switch > 0.0 and nf > r:  # the network thread holds the interpreter lock
            lock = r + self.switch
            r = nf if nf < lock else lock
        if wait > 0.0:
            r += wait
        return self.machine.place(a, r, length)

    def run_wait(self, a: float, cpu: float, length: float) -> float:
        """The run-queue wait of a burst of ``cpu`` CPU seconds (``length`` on a core)
        arriving at ``a``: ``(runq + machine's load wait) · length`` (the load wait only
        if the process ``grow``s); the burst's CPU counts in its machine's load window
        whether or not. 0, and nothing counted, with neither."""
        m = self.machine
        if not (m.growth or self.runq > 0.0):
            return 0.0
        g = m.load_wait(a)  # also closes the load window: every burst's arrival does
        wait = (self.runq + g if self.grow else self.runq) * length
        m.w_busy += cpu
        if self.warmup <= a < self.end:
            self.queued += wait
        return wait

    def hold(self, a: float, s: float, c: int, end: float) -> None:
        """A burst arrived at ``a``, started at ``s`` on core ``c`` and ends at ``end``."""
        self.free = end
        self.machine.reserve(c, s, end)
        if self.warmup <= a < self.end:
            self.bursts += 1
            w = s - a
            if w > self.max_wait:
                self.max_wait = w
        self._count(s, end)

    def _count(self, s: float, end: float) -> None:
        """``[s, end)`` on a core: its part inside the metrics window is busy time."""
        lo = s if s > self.warmup else self.warmup
        hi = end if end < self.end else self.end
        if hi > lo:
            self.busy += hi - lo

    def beside(self, a: float, length: float) -> None:
        """A wake-up's part on the process's other thread: ``length`` on a core from
        ``a`` on (the earliest gap, as any burst), the thread untouched."""
        s, c = self.machine.place(a, a, length)
        self.machine.reserve(c, s, s + length)
        self._count(s, s + length)

    def carried(self, free: float, busy: float, max_wait: float, bursts: int,
                queued: float = 0.0) -> None:
        """Bursts served elsewhere (the compiled core): free again at ``free`` at the
        latest, ``busy`` more CPU seconds, a longest wait of ``max_wait``, ``bursts``
        more bursts in the window, ``queued`` more run-queue wait."""
        self.free = max(self.free, free)
        self.busy += busy
        self.max_wait = max(self.max_wait, max_wait)
        self.bursts += bursts
        self.queued += queued

    def span(self, a: float, demand: float) -> tuple[float, float]:
        """Serve a burst of ``demand`` CPU seconds (> 0) arriving at ``a`` (plus ``wake``
        if the thread is idle then); its start and end."""
        w = self.wake
        idle = w > 0.0 and a > self.free
        cpu = demand + w if idle else demand
        length = cpu * self.scale
        side = self.side if idle and not self.threaded else 0.0
        if side > 0.0:  # in the machine's load, not in this thread's run-queue wait
            side_len = side * self.scale
            wait = self.run_wait(a, cpu + side, length)
            self.beside(a, side_len)
        else:
            wait = self.run_wait(a, cpu, length)
        s, c = self.acquire(a, length, wait)
        end = s + length
        self.hold(a, s, c, end)
        return s, end

    @property
    def threaded(self) -> bool:
        """True if the process has a network thread (``net_msg`` or ``net_wake``)."""
        return self.net_msg > 0.0 or self.net_wake > 0.0

    def net_span(self, a: float, gil: bool) -> tuple[float, float]:
        """A burst on the network thread arriving at ``a`` (its cost ``net_msg``, plus
        ``net_wake`` if that thread is idle then); its start and end. With ``gil`` (a
        received copy) it is ready no earlier than the loop thread is free or
        ``switch`` after it was ready, whichever is first: the loop thread holds the
        interpreter lock while it serves and gives it up when it waits or at the
        switch interval; a burst that waits so costs ``net_wake`` too (the thread
        blocks on the lock and wakes again, a voluntary switch as live counts them).
        It waits on the run queue as any burst."""
        idle = a > self.net_free
        r = a if idle else self.net_free
        if gil and self.switch > 0.0 and self.free > r:  # blocked on the lock: it waits
            idle = True
            lock = r + self.switch
            r = self.free if self.free < lock else lock
        cpu = self.net_msg + self.net_wake if idle else self.net_msg
        length = cpu * self.scale
        side = self.side if idle else 0.0
        wait = self.run_wait(a, cpu + side, length)
        if side > 0.0:  # a network wake-up's part beside the thread
            self.beside(a, side * self.scale)
        s, c = self.machine.place(a, r + wait, length)
        end = s + length
        self.machine.reserve(c, s, end)
        self.net_free = end
        self._count(s, end)
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
        queued: run-queue wait of the bursts that arrived in the window (s; 0 without
            ``*_runq`` and ``runq_growth``).
    """

    name: str
    machine: str
    busy: float
    max_wait: float
    bursts: int
    queued: float = 0.0


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
        grows = [spec.grows(n.rstrip("0123456789")) for n in names]
        # a machine keeps load windows when a process on it grows
        if spec.preset == "colocated":
            one = Machine("all", c, any(grows), spec.background)
            machines = [one] * len(names)
            self.machines = [one]
        else:
            machines = [Machine(n, c, g, spec.background) for n, g in zip(names, grows,
                                                                           strict=True)]
            self.machines = machines
        wakes = [0.0, spec.server_wake, *([spec.host_wake] * hosts)]
        runqs = [spec.broker_runq, spec.server_runq, *([spec.host_runq] * hosts)]
        sides = [0.0, spec.server_wake_side, *([spec.host_wake_side] * hosts)]
        nets = [(0.0, 0.0), (spec.server_net_msg, spec.server_net_wake),
                *([(spec.host_net_msg, spec.host_net_wake)] * hosts)]
        procs = [Process(n, m, scale, warmup, end, w, q, d, t, spec.lock_switch, g)
                 for n, m, w, q, d, t, g in zip(names, machines, wakes, runqs, sides, nets,
                                                grows, strict=True)]
        self.cores = c
        self.broker = procs[0]
        self.server = procs[1]
        self.hosts = procs[2:]
        self.processes = procs

    def report(self) -> CpuReport:
        """Every process's counters (the one hook the results read)."""
        return CpuReport(
            processes=tuple(ProcessReport(p.name, p.machine.name, p.busy, p.max_wait, p.bursts,
                                          p.queued)
                            for p in self.processes),
            cores=self.cores,
            machines=tuple(m.name for m in self.machines),
        )
