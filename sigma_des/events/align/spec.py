"""The alignment methods' own parameters: one frozen, validated spec per method.

Each class is one TOML table of the scenario (``[lockstep]``, ``[hlc]``, ``[bides]``,
``[rpc]``); :class:`sigma_des.config.Scenario` embeds them and keeps their keys,
defaults and messages. :class:`AlignParams` bundles what an aligner may be built
from (its method's spec and a few scalars of the run), so the methods never see the
whole scenario (docs/concepts/methods.md). Validation happens on
construction and raises :class:`~sigma_des.errors.ConfigError` with the local field
name (the loader prefixes the dotted path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sigma_des.core.validate import require, require_nonneg, require_positive
from sigma_des.net.latency import Dist

__all__ = ["AlignParams", "BidesSpec", "HLCSpec", "LockstepSpec", "RpcSpec"]


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
class RpcSpec:
    """AirSim-style synchronous RPC: the server calls every vehicle each frame.

    One frame: the server sends a request (a trigger) to each vehicle, at most
    ``in_flight`` calls outstanding (0 = one per vehicle, all at once, as
    independent blocking clients); each vehicle steps and responds with its state;
    the server's game thread handles each response (``call_time``), then renders
    the frame (``render_time`` + ``render_per_vehicle`` × N); the next frame starts
    when the render is done, not sooner than ``1/f_trig`` after the previous one.
    Rendering and the calls share that one thread, so render load delays physics.

    Attributes:
        in_flight: most calls outstanding at once (0 = one per vehicle) [AIRSIM:
            a msgpack-rpc client's ``call`` blocks, so one outstanding call per client].
        call_time: game-thread time per handled call (API dispatch, msgpack
            serialization of the vehicle state); estimate (s).
        render_time: render time of a frame at zero vehicles; estimate for an Unreal
            scene at ~60-100 fps (s).
        render_per_vehicle: extra render time per vehicle drawn; estimate (s).
    """

    in_flight: int = 0
    call_time: Dist = field(default_factory=lambda: Dist(dist="constant", value=0.0003))
    render_time: Dist = field(
        default_factory=lambda: Dist(dist="lognormal", mean=0.008, std=0.003)
    )
    render_per_vehicle: float = 0.0002

    def __post_init__(self) -> None:
        require_nonneg(self, "in_flight", "render_per_vehicle")


@dataclass(frozen=True)
class AlignParams:
    """What the alignment server's method is built from (the scenario builds it).

    Attributes:
        f_trig: nominal trigger rate (Hz): BiDES's adaptation never goes above it.
        seed: the run's root seed (RPC's call and render times are drawn from it).
        middleware: ``net.middleware`` (RPC needs ``"mqtt"``).
        lockstep: Lock-Step's barrier parameters.
        hlc: the HLC consumer's liveness parameter.
        bides: BiDES's parts and parameters.
        rpc: the AirSim-style RPC frame loop's parameters.
    """

    f_trig: float = 100.0
    seed: int = 0
    middleware: str = "mqtt"
    lockstep: LockstepSpec = field(default_factory=LockstepSpec)
    hlc: HLCSpec = field(default_factory=HLCSpec)
    bides: BidesSpec = field(default_factory=BidesSpec)
    rpc: RpcSpec = field(default_factory=RpcSpec)
