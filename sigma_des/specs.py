"""Section specs of the scenario: frozen, validated dataclasses with their defaults.

Each class is one TOML table of the scenario (``[compute]``, ``[bides]``, …; the
net layer's ``[net]``, ``[broker]`` and ``[dds]`` are in :mod:`sigma_des.net.spec`);
:class:`sigma_des.config.Scenario` embeds them. Validation happens on construction and
raises :class:`~sigma_des.errors.ConfigError` with the local field name (the loader
prefixes the dotted path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sigma_des.core.validate import require, require_in, require_nonneg, require_positive
from sigma_des.net.latency import Dist

__all__ = [
    "BidesSpec",
    "CommandSpec",
    "ComputeSpec",
    "DROP_MESSAGES",
    "FAULT_KINDS",
    "FaultSpec",
    "FidelitySpec",
    "HLCSpec",
    "LockstepSpec",
    "RecordSpec",
]


@dataclass(frozen=True)
class ComputeSpec:
    """Per-node computation: one physics step's CPU time, contending for host cores."""

    step_time: Dist = field(default_factory=lambda: Dist(dist="lognormal", mean=0.0008, std=0.0002))


@dataclass(frozen=True)
class LockstepSpec:
    """Lock-Step barrier parameters.

    Attributes:
        retry_timeout: after this long without a node's state of frame k, re-request it (s).
        eviction_timeout: evict a node missing this long after trigger k (s); 0 = never.
    """

    retry_timeout: float = 0.05
    eviction_timeout: float = 0.0

    def __post_init__(self) -> None:
        require_positive(self, "retry_timeout")
        require_nonneg(self, "eviction_timeout")


@dataclass(frozen=True)
class HLCSpec:
    """HLC consumer: a node silent this long is treated as dead (0 = never)."""

    liveness_timeout: float = 0.5

    def __post_init__(self) -> None:
        require_nonneg(self, "liveness_timeout")


@dataclass(frozen=True)
class BidesSpec:
    """BiDES parts and parameters (each part can be switched off).

    Attributes:
        ring_size: K, states kept per node by the alignment server.
        hole_fill: fill a frame missing from a node's buffer from neighbouring frames.
        lag_exclusion: leave out of the minimum nodes lagging more than ``theta_lag``.
        theta_lag: Θ_lag in frames.
        adaptation: adapt ``f_trig`` to the alignment lag.
        lag_high: lower ``f_trig`` when (latest trigger − aligned frame) > this for
            ``hold_down`` consecutive alignment ticks.
        lag_low: raise it again when the lag < this for ``hold_up`` consecutive ticks.
        rate_down: factor applied when lowering (0 < x < 1).
        rate_up: factor applied when raising (> 1), capped at the nominal ``f_trig``.
        f_trig_min: lowest trigger rate (Hz).
        hold_down: consecutive ticks over ``lag_high`` before lowering.
        hold_up: consecutive ticks under ``lag_low`` before raising.
        time_warp: roll a node back when a command is more than ``theta_warp`` behind.
        theta_warp: Θ_warp in frames.
    """

    ring_size: int = 30
    hole_fill: bool = True
    lag_exclusion: bool = True
    theta_lag: int = 3
    adaptation: bool = True
    lag_high: int = 10
    lag_low: int = 4
    rate_down: float = 0.8
    rate_up: float = 1.1
    f_trig_min: float = 10.0
    hold_down: int = 3
    hold_up: int = 30
    time_warp: bool = True
    theta_warp: int = 10

    def __post_init__(self) -> None:
        require(
            2 <= self.ring_size <= 100_000,
            "ring_size",
            f"must be in 2..100000, got {self.ring_size}",
        )
        require(self.theta_lag >= 1, "theta_lag", f"must be >= 1 frame, got {self.theta_lag}")
        require(self.lag_high >= 1, "lag_high", f"must be >= 1 frame, got {self.lag_high}")
        require(
            0 <= self.lag_low <= self.lag_high,
            "lag_low",
            f"must be in 0..lag_high ({self.lag_high}), got {self.lag_low}",
        )
        require(0 < self.rate_down < 1, "rate_down", f"must be in (0, 1), got {self.rate_down}")
        require(
            self.rate_up > 1 and math.isfinite(self.rate_up),
            "rate_up",
            f"must be > 1, got {self.rate_up}",
        )
        require_positive(self, "f_trig_min")
        require(self.hold_down >= 1, "hold_down", f"must be >= 1, got {self.hold_down}")
        require(self.hold_up >= 1, "hold_up", f"must be >= 1, got {self.hold_up}")
        require(self.theta_warp >= 0, "theta_warp", f"must be >= 0, got {self.theta_warp}")


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
        require(self.payload_bits >= 0, "payload_bits", f"must be >= 0, got {self.payload_bits}")


@dataclass(frozen=True)
class FidelitySpec:
    """Swarm fidelity against an ideal run (zero latency, perfect alignment).

    Attributes:
        enabled: fly the ideal run and compute formation error and DTW.
        log_rate: trajectory sampling rate (Hz of physics time; the paper: 30 Hz).
        dtw_nodes: DTW is averaged over at most this many evenly spread nodes.
    """

    enabled: bool = True
    log_rate: float = 30.0
    dtw_nodes: int = 50

    def __post_init__(self) -> None:
        require_positive(self, "log_rate")
        require(self.dtw_nodes >= 1, "dtw_nodes", f"must be >= 1, got {self.dtw_nodes}")


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


RECORD_MODES = ("full", "incremental")


@dataclass(frozen=True)
class RecordSpec:
    """How ``--record`` stores a run in MCAP (see :mod:`sigma_des.record`).

    Recording never changes a result, so this section is not part of the config hash.

    Attributes:
        mode: ``full`` (every state) or ``incremental`` (per-node deltas; states inside
            the dead-band are not stored; periodic keyframes).
        deadband_pos: incremental: a state is stored when its position is further than
            this from the dead-reckoned one (previous stored position + velocity × time), m.
        deadband_vel: incremental: ... or its velocity changed by more than this, m/s.
        deadband_att: incremental: ... or an Euler angle changed by more than this, rad.
        keyframe_every: incremental: frames between a node's absolute (key) states.
    """

    mode: str = "full"
    deadband_pos: float = 0.05
    deadband_vel: float = 0.1
    deadband_att: float = 0.02
    keyframe_every: int = 100

    def __post_init__(self) -> None:
        require(
            self.mode in RECORD_MODES, "mode", f"must be one of {RECORD_MODES}, got {self.mode!r}"
        )
        for k in ("deadband_pos", "deadband_vel", "deadband_att"):
            v = getattr(self, k)
            require(math.isfinite(v) and v >= 0, k, f"must be a finite number >= 0, got {v}")
        require(
            1 <= self.keyframe_every <= 1_000_000,
            "keyframe_every",
            f"must be in 1..1000000 frames, got {self.keyframe_every}",
        )
