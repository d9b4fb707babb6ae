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

from sigma_des.core.validate import require, require_in
from sigma_des.net.latency import Dist

__all__ = [
    "CommandSpec",
    "ComputeSpec",
    "DROP_MESSAGES",
    "FAULT_KINDS",
    "FaultSpec",
    "RecordSpec",
]


@dataclass(frozen=True)
class ComputeSpec:
    """Per-node computation: one physics step's CPU time, contending for host cores."""

    step_time: Dist = field(default_factory=lambda: Dist(dist="lognormal", mean=0.0008, std=0.0002))


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
