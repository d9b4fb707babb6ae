"""Section specs of the scenario: frozen, validated dataclasses with their defaults.

Each class is one TOML table of the scenario that belongs to no layer below
(``[record]``); the others live with the layer that reads them: ``[net]``,
``[broker]`` and ``[dds]`` in :mod:`sigma_des.net.spec`; ``[lockstep]``, ``[hlc]``,
``[bides]`` and ``[rpc]`` in :mod:`sigma_des.events.align.spec`; ``[compute]``,
``[commands]`` and ``[faults]`` in :mod:`sigma_des.events.spec`; ``[fidelity]`` in
:mod:`sigma_des.metrics.fidelity`. :class:`sigma_des.config.Scenario` embeds them.
Validation happens on construction and raises :class:`~sigma_des.errors.ConfigError`
with the local field name (the loader prefixes the dotted path).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sigma_des.core.validate import require

__all__ = ["RecordSpec"]


RECORD_MODES = ("full", "incremental")


@dataclass(frozen=True)
class RecordSpec:
    """How ``--record`` stores a run in MCAP (see :mod:`sigma_des.record`).

    Recording never changes a result, so this section is not part of the config hash.

    Attributes:
        mode: ``full`` (every state) or ``incremental`` (per-node deltas; states inside
            the dead-band are not stored; periodic keyframes; snapshot poses rounded to
            1 cm).
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
