"""The ``[deployment]`` table: machines, CPU demands and MQTT clients (docs/concepts/deployment.md).

A frozen, validated dataclass the CPU stage (:mod:`sigma_des.net.cpu`) and the network
(:mod:`sigma_des.net.network`) take; :mod:`sigma_des.net.spec` re-exports it with the
other network specs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sigma_des.core.validate import require, require_in

__all__ = ["CLIENTS", "CPU_SECONDS", "LATER_KEYS", "MAX_CORES", "MAX_DEMAND", "MAX_RUNQ",
           "PRESETS", "RUNQ_KEYS", "DeploymentSpec"]

#: ``deployment.preset`` choices (docs/concepts/deployment.md).
PRESETS: tuple[str, ...] = ("none", "colocated", "dedicated")
#: ``deployment.clients`` choices: one MQTT client per node, or per physics host.
CLIENTS: tuple[str, ...] = ("node", "host")
#: Largest ``deployment.cores``.
MAX_CORES = 4096
#: Largest per-message or per-tick CPU demand (s).
MAX_DEMAND = 1.0
#: ``[deployment]`` keys added after the table: not written (nor hashed) at 0.
LATER_KEYS = ("host_wake", "server_wake", "host_record", "server_record", "lock_switch",
              "host_runq", "server_runq", "broker_runq", "runq_growth", "host_wake_side",
              "server_wake_side", "host_net_wake", "server_net_wake", "host_net_msg",
              "server_net_msg", "broker_runq_growth", "server_runq_growth")
#: Largest run-queue wait per CPU second a deployment accepts.
MAX_RUNQ = 100.0
#: ``[deployment]`` keys in seconds of CPU (0..:data:`MAX_DEMAND`), and run-queue keys.
CPU_SECONDS = ("host_demand", "server_demand", "server_tick", "host_wake", "server_wake",
               "host_record", "server_record", "lock_switch", "host_wake_side",
               "server_wake_side", "host_net_wake", "server_net_wake", "host_net_msg",
               "server_net_msg")
RUNQ_KEYS = ("host_runq", "server_runq", "broker_runq")


@dataclass(frozen=True)
class DeploymentSpec:
    """Where the processes run and the CPU they spend (docs/concepts/deployment.md).

    Each process (the broker, the alignment server, each physics host's client
    process) is one thread; its CPU bursts are served first come first served on
    its machine's cores (:mod:`sigma_des.net.cpu`). All defaults: no CPU stage,
    today's model exactly (the table is then not written out nor hashed).

    Attributes:
        preset: ``none`` (no CPU stage), ``colocated`` (broker, server and every host
            process on one machine of ``cores`` cores: ``sigma-des live`` on a laptop)
            or ``dedicated`` (broker, server and each host on a machine of its own).
        cores: cores of each machine, 1..4096.
        background: cores' worth of CPU other processes use on each machine, in
            ``[0, cores)``: every burst takes ``cores / (cores - background)`` longer.
        host_demand: CPU a physics host's client process spends per PUBLISH it sends
            or receives (s), 0..1.
        server_demand: CPU the server's process spends per PUBLISH it sends or
            receives (s), 0..1.
        server_tick: CPU the server's process spends per alignment tick (s), 0..1.
        host_wake: CPU a physics host's process spends more on a burst that finds its
            thread idle (a *wake-up*: leaving the wait, the loop's own work), 0..1 s;
            needs ``host_demand > 0``.
        server_wake: the same for the server's process; needs ``server_demand > 0``.
        host_wake_side: CPU a physics host's wake-up spends more on the process's
            other thread (paho's network thread), 0..1 s, needs ``host_wake > 0``: it
            runs on the machine's cores from the burst's arrival, beside the thread's
            own burst, without holding the thread; it counts in the process's CPU, its
            machine's load and the burst's run-queue wait.
        server_wake_side: the same for the server's process.
        host_net_msg: CPU a physics host's process spends per PUBLISH it sends or
            receives on its network thread (paho's), 0..1 s, needs ``host_demand > 0``:
            with it or ``host_net_wake`` the process is two threads in tandem
            (docs/concepts/deployment.md, "The network thread";
            :meth:`~sigma_des.net.cpu.Process.net_span`).
        server_net_msg: the same for the server's process.
        host_net_wake: CPU a network-thread burst that finds that thread idle costs
            more, 0..1 s, needs ``host_demand > 0``.
        server_net_wake: the same for the server's process.
        host_record: CPU a physics host's process spends more per record beyond the
            first of a bundled PUBLISH it sends or receives (encoding, decoding and
            handling each state or command), 0..``host_demand`` s: a bundle of ``k``
            records costs ``host_demand + (k - 1)·host_record``; one record (every
            unbundled message) costs ``host_demand``.
        server_record: the same for the server's process (0..``server_demand``).
        lock_switch: a PUBLISH whose burst ends while its process's thread is busy
            leaves when the thread next waits, at most this long after its burst's
            end (Python's interpreter-lock switch interval: live's paho network thread
            writes it), in publish order; 0 (default): it leaves at its burst's end.
            0..1 s.
        host_runq: a physics host process's run-queue wait floor: every burst waits
            this many seconds per CPU second of the burst for a core once its thread is
            free (a woken thread waits behind the runnable ones), 0..100.
        server_runq: the same for the server's process.
        broker_runq: the same for the broker's.
        runq_growth: every burst also waits :func:`~sigma_des.net.cpu.queue_wait`
            (Erlang C) per CPU second at its machine's utilisation over the last whole
            :data:`~sigma_des.net.cpu.LOAD_WINDOW` (the machine's queue).
        broker_runq_growth: the broker's bursts also wait that queue (every
            process's with ``runq_growth``): live's broker, one single-threaded C
            process, waits more per CPU second as its machine gets busier.
        server_runq_growth: the server's bursts also wait that queue: live's server
            waits as its machine's queue does once the machine is nearly full (a
            bundled swarm on many hosts), the hosts far less than it.
        clients: ``node`` (one MQTT client per node) or ``host`` (one per physics
            host process, as live runs).
        bundle: a host's states of one loop turn leave as one PUBLISH, and the
            server's commands of one turn to one host (live ``--bundle``): those of one
            instant, and with a CPU stage those published while the sender's process
            is busy; needs ``clients = "host"``.
    """

    preset: str = "none"
    cores: int = 2
    background: float = 0.0
    host_demand: float = 0.0
    server_demand: float = 0.0
    server_tick: float = 0.0
    host_wake: float = 0.0
    server_wake: float = 0.0
    host_record: float = 0.0
    server_record: float = 0.0
    lock_switch: float = 0.0
    host_runq: float = 0.0
    server_runq: float = 0.0
    broker_runq: float = 0.0
    runq_growth: bool = False
    broker_runq_growth: bool = False
    server_runq_growth: bool = False
    host_wake_side: float = 0.0
    server_wake_side: float = 0.0
    host_net_wake: float = 0.0
    server_net_wake: float = 0.0
    host_net_msg: float = 0.0
    server_net_msg: float = 0.0
    clients: str = "node"
    bundle: bool = False

    def __post_init__(self) -> None:
        require(self.preset in PRESETS, "preset",
                f"must be one of {', '.join(PRESETS)}, got {self.preset!r}")
        require(1 <= self.cores <= MAX_CORES, "cores",
                f"must be in 1..{MAX_CORES}, got {self.cores}")
        require(0.0 <= self.background < self.cores and math.isfinite(self.background),
                "background", f"must be in [0, cores={self.cores}) cores, got {self.background}")
        for name in CPU_SECONDS:
            require_in(self, name, 0.0, MAX_DEMAND, " s")
        for name in RUNQ_KEYS:
            require_in(self, name, 0.0, MAX_RUNQ, " s per CPU second")
        for who in ("host", "server"):
            wake, demand = getattr(self, f"{who}_wake"), getattr(self, f"{who}_demand")
            require(wake == 0.0 or demand > 0.0, f"{who}_wake",
                    f"needs deployment.{who}_demand > 0 (a wake-up is charged on a burst, "
                    f"and a zero demand is no burst; got {who}_wake = {wake})")
            side = getattr(self, f"{who}_wake_side")
            require(side == 0.0 or wake > 0.0, f"{who}_wake_side",
                    f"needs deployment.{who}_wake > 0 (it is a wake-up's part; got "
                    f"{who}_wake_side = {side})")
            for key in (f"{who}_net_msg", f"{who}_net_wake"):
                require(getattr(self, key) == 0.0 or demand > 0.0, key,
                        f"needs deployment.{who}_demand > 0 (a process's second thread; "
                        f"got {key} = {getattr(self, key)})")
            rec = getattr(self, f"{who}_record")
            require(rec <= demand, f"{who}_record",
                    f"must be in [0, deployment.{who}_demand = {demand}] s (a record's share "
                    f"of a one-record message's CPU), got {rec}")
        if self.preset == "none":
            for name in ("background", *CPU_SECONDS, *RUNQ_KEYS, "runq_growth",
                         "broker_runq_growth", "server_runq_growth"):
                v = getattr(self, name)
                require(v == 0.0, name,
                        f"needs deployment.preset colocated or dedicated (got {v} with "
                        "preset 'none', which has no CPU stage)")
        require(self.clients in CLIENTS, "clients",
                f"must be one of {', '.join(CLIENTS)}, got {self.clients!r}")
        require(not self.bundle or self.clients == "host", "bundle",
                "needs deployment.clients = 'host' (a bundle is one host client's PUBLISH)")

    @property
    def cpu(self) -> bool:
        """True if the run has a CPU stage (a preset other than ``none``)."""
        return self.preset != "none"

    def grows(self, kind: str) -> bool:
        """True if the run-queue wait of ``kind``'s processes (``broker``, ``server``,
        ``host``) grows with its machine's load (``runq_growth``, ``broker_runq_growth``,
        ``server_runq_growth``)."""
        return (self.runq_growth or (kind == "broker" and self.broker_runq_growth)
                or (kind == "server" and self.server_runq_growth))
