"""The run spec of the events layer: what the engine needs to run one scenario.

:class:`RunSpec` holds the scalars the engine reads (rates, phases, duration,
warmup, payload sizes, history length, stall threshold, placement) and the
engine-side sections of a scenario: per-node computation (:class:`ComputeSpec`),
behaviour commands (:class:`CommandSpec`) and injected faults (:class:`FaultSpec`).
:class:`sigma_des.config.Scenario` embeds these section classes under its TOML
keys and builds the run spec (``Scenario.run_spec``): configuration depends on
the engine, never the reverse. Validation happens on construction and raises
:class:`~sigma_des.errors.ConfigError` with the local field name (the scenario
loader prefixes the dotted path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sigma_des.core.validate import require, require_in, require_positive
from sigma_des.events.align.spec import AlignParams
from sigma_des.metrics.collector import CollectorSpec
from sigma_des.net.clocks import ClockSpec
from sigma_des.net.latency import Dist
from sigma_des.net.spec import NetSetup
from sigma_des.net.wire import require_payload

__all__ = [
    "CommandSpec",
    "ComputeSpec",
    "DROP_MESSAGES",
    "FAULT_KINDS",
    "FaultSpec",
    "RunSpec",
]


#: Largest ``compute.host_share`` (1 would make a host's nodes step in lock-step exactly:
#: no node component at all; the copula needs ``1 - ρ > 0``).
HOST_SHARE_MAX = 1.0


@dataclass(frozen=True)
class ComputeSpec:
    """Per-node computation: one physics step's CPU time, contending for host cores.

    Attributes:
        step_time: distribution of one frame's step (s).
        host_share: ρ in [0, 1): correlation of the normal scores of two nodes' step
            draws of one host and frame (a Gaussian copula, ``sigma_des.events.jobs.
            step_draws``); each draw keeps ``step_time``. 0 (the default): independent
            nodes, today's draws bit for bit, and the key is not written out (the
            scenario's hash is as before it existed).
    """

    step_time: Dist = field(default_factory=lambda: Dist(dist="lognormal", mean=0.0008, std=0.0002))
    host_share: float = 0.0

    def __post_init__(self) -> None:
        v = self.host_share
        require(not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
                and 0.0 <= v < HOST_SHARE_MAX, "host_share",
                f"must be in [0, 1) (the share of a step's variance common to its host), "
                f"got {v!r}")
        object.__setattr__(self, "host_share", float(v))



@dataclass(frozen=True)
class CommandSpec:
    """Behaviour commands sent from the server back to the physics nodes.

    Attributes:
        enabled: send commands at all.
        behaviour: behaviour name (see ``sigma_des.agents`` registry).
        every: send at every ``every``-th alignment tick.
        payload_bits: command payload size.
    """

    enabled: bool = True
    behaviour: str = "formation"
    every: int = 3
    payload_bits: int = 96

    def __post_init__(self) -> None:
        require(self.every >= 1, "every", f"must be >= 1, got {self.every}")
        require_payload("payload_bits", self.payload_bits, 0)



FAULT_KINDS = ("crash", "slow", "degrade", "drop")
#: Largest ``slow`` fault factor (a step 1000 times slower is a stopped node).
MAX_SLOW_FACTOR = 1000.0
#: Largest ``degrade`` fault extra one-way delay (s).
MAX_EXTRA_DELAY = 3600.0
DROP_MESSAGES = ("trigger", "state", "command")


@dataclass(frozen=True)
class FaultSpec:
    """An injected fault.

    Attributes:
        kind: ``crash`` (node stops for good at ``start``), ``slow`` (node's steps take
            ``factor`` times longer in [start, end)), ``degrade`` (host link gets
            ``extra_delay`` seconds and ``extra_loss`` probability in [start, end)),
            ``drop`` (the first transmission of one message on its broker-to-receiver
            hop is lost: ``message`` of ``node`` for ``frame``; for commands ``frame``
            is the alignment tick number).
        node: target node of crash/slow/drop.
        host: target host of degrade.
        start: start time (s), finite.
        end: end time (s); inf = until the end.
        factor: slow-down factor, 1..1000.
        extra_delay: extra one-way delay (s), 0..3600.
        extra_loss: extra loss probability in [0, 1).
        message: ``drop``: ``trigger``, ``state`` or ``command``.
        frame: ``drop``: frame (or command tick) of the dropped message.
    """

    kind: str = "crash"
    node: int = -1
    host: int = -1
    start: float = 0.0
    end: float = math.inf
    factor: float = 1.0
    extra_delay: float = 0.0
    extra_loss: float = 0.0
    message: str = "state"
    frame: int = -1

    def __post_init__(self) -> None:
        require(
            self.kind in FAULT_KINDS, "kind", f"must be one of {FAULT_KINDS}, got {self.kind!r}"
        )
        require(
            0 <= self.start < math.inf, "start", f"must be a finite time >= 0 s, got {self.start}"
        )
        require(self.end > self.start, "end", f"must be > start ({self.start}), got {self.end}")
        require_in(self, "factor", 1.0, MAX_SLOW_FACTOR)
        require_in(self, "extra_delay", 0.0, MAX_EXTRA_DELAY, " s")
        require(0 <= self.extra_loss < 1, "extra_loss", f"must be in [0, 1), got {self.extra_loss}")
        require(
            self.message in DROP_MESSAGES,
            "message",
            f"must be one of {DROP_MESSAGES}, got {self.message!r}",
        )
        if self.kind == "drop":
            require(self.frame >= 0, "frame", f"a drop fault needs frame >= 0, got {self.frame}")
        if self.kind in ("crash", "slow", "drop"):
            require(self.node >= 0, "node", f"a {self.kind} fault needs node >= 0")
        else:
            require(self.host >= 0, "host", "a degrade fault needs host >= 0")


@dataclass(frozen=True)
class RunSpec:
    """The engine's view of a scenario (built by ``Scenario.run_spec``).

    Attributes:
        seed: root seed of all random streams.
        nodes: number of physics nodes.
        hosts: number of physics hosts.
        cores_per_host: CPU cores per host shared by its nodes.
        host_of: host index of every node.
        f_trig: nominal trigger rate (Hz).
        f_align: alignment ticks per second.
        f_render: render ticks per second.
        align_phase: alignment tick j is at ``(j + align_phase) / f_align``.
        render_phase: render tick j is at ``(j + render_phase) / f_render``.
        duration: simulated time (s); events at or after it are not processed.
        warmup: metrics ignore everything before this time (s).
        payload_bits: state payload size.
        trigger_payload_bits: trigger (and re-request) payload size.
        history_frames: frames kept in the truth ring and the draw tables.
        stall_threshold: a gap between new aligned snapshots longer than this is a stall (s).
        net: what the net layer takes (its specs, topology, window, link faults).
        align: what the alignment method is built from.
        collect: what the metrics collector takes.
        engine: ``cohort`` or ``events``.
        compute: per-node computation.
        commands: behaviour commands.
        faults: injected faults.
        clocks: the nodes' local clocks (HLC physical time).
        time_warp: BiDES time-warp rollbacks on.
        theta_warp: a command stamped more than this many frames behind rolls back.
        log_rate: fidelity log rate (Hz of physics time).
    """

    seed: int
    nodes: int
    hosts: int
    cores_per_host: int
    host_of: tuple[int, ...]
    f_trig: float
    f_align: float
    f_render: float
    align_phase: float
    render_phase: float
    duration: float
    warmup: float
    payload_bits: int
    trigger_payload_bits: int
    history_frames: int
    stall_threshold: float
    net: NetSetup
    align: AlignParams
    collect: CollectorSpec
    engine: str = "cohort"
    compute: ComputeSpec = field(default_factory=ComputeSpec)
    commands: CommandSpec = field(default_factory=CommandSpec)
    faults: tuple[FaultSpec, ...] = ()
    clocks: ClockSpec = field(default_factory=ClockSpec)
    time_warp: bool = True
    theta_warp: int = 10
    log_rate: float = 30.0

    def __post_init__(self) -> None:
        require(self.nodes >= 1, "nodes", f"must be >= 1, got {self.nodes}")
        require(
            len(self.host_of) == self.nodes
            and all(0 <= h < self.hosts for h in self.host_of),
            "host_of",
            f"must give each of the {self.nodes} nodes a host in 0..{self.hosts - 1}",
        )
        require(self.cores_per_host >= 1, "cores_per_host", "must be >= 1")
        require_positive(
            self, "f_trig", "f_align", "f_render", "duration", "stall_threshold", "log_rate"
        )
        require(0 <= self.warmup < self.duration, "warmup", "must be in [0, duration)")
        require(self.history_frames >= 1, "history_frames", "must be >= 1")
        require(self.theta_warp >= 0, "theta_warp", "must be >= 0")
