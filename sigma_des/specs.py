"""Section specs of the scenario: frozen, validated dataclasses with their defaults.

Each class is one TOML table of the scenario (``[compute]``, ``[bides]``, …; the
net layer's ``[net]``, ``[broker]`` and ``[dds]`` are in :mod:`sigma_des.net.spec`);
:class:`sigma_des.config.Scenario` embeds them. Validation happens on construction and
raises :class:`~sigma_des.errors.ConfigError` with the local field name (the loader
prefixes the dotted path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sigma_des.core.validate import require, require_nonneg, require_positive

__all__ = [
    "BidesSpec",
    "FidelitySpec",
    "HLCSpec",
    "LockstepSpec",
    "RecordSpec",
]


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
