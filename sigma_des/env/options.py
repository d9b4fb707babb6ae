"""Options of the swarm environments: the scenario under the env and the episode length.

An env runs a full :class:`~sigma_des.config.Scenario`; :data:`ENV_DEFAULTS` make
it small (5 point-mass nodes on one host, 50 Hz triggers, 20 Hz alignment, a
decision every 2nd alignment tick = 10 Hz, datagram MQTT QoS 0, so the compiled
cohort engine runs it). Any scenario key may be overridden (dotted keys, Python
values, e.g. ``{"net.host_link.latency": 0.05, "nodes": 11}``). The env owns four
keys: ``duration`` (from ``max_steps``), ``warmup`` (0), ``commands.enabled``
(true) and ``fidelity.enabled`` (false, no ideal run); setting them is an error.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from sigma_des.config import METHODS, Scenario, load
from sigma_des.errors import ConfigError

__all__ = ["AUTORESET_MODES", "ENV_DEFAULTS", "EnvOptions", "build_scenario"]

#: Autoreset modes of the vectorised env (Gymnasium's names, lower case).
AUTORESET_MODES = ("next_step", "same_step", "disabled")

#: Scenario values of the env when the caller does not override them.
ENV_DEFAULTS: dict[str, Any] = {
    "nodes": 5,
    "hosts": 1,
    "dynamics": "pointmass",
    "f_trig": 50.0,
    "f_align": 20.0,
    "f_render": 5.0,
    "history_frames": 64,
    "commands.every": 2,
    "net.transport": "datagram",
    "net.qos": 0,
}
_OWNED = ("duration", "warmup", "commands.enabled", "fidelity.enabled")


@dataclass(frozen=True)
class EnvOptions:
    """Validated env options.

    Attributes:
        task: task name (``formation`` or ``goal``).
        method: alignment method (``none``, ``lockstep``, ``hlc``, ``bides``).
        max_steps: decisions per episode (then every agent is truncated).
        perfect_info: observe the true current state instead of the aligned view
            (what peer environments give; commands still travel over the network).
        n_scenes: scenes of a vectorised env (1 for the PettingZoo env).
        autoreset: when a finished scene restarts: ``next_step`` (the next ``step``
            ignores its actions and returns the new episode's first observation),
            ``same_step`` (at once; the final observation goes into the infos) or
            ``disabled`` (stepping a finished scene is an error).
    """

    task: str = "formation"
    method: str = "bides"
    max_steps: int = 100
    perfect_info: bool = False
    n_scenes: int = 1
    autoreset: str = "next_step"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError("method", f"unknown method {self.method!r}; allowed: {METHODS}")
        for key in ("max_steps", "n_scenes"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(key, f"must be an integer >= 1, got {v!r}")
        if not isinstance(self.perfect_info, bool):
            raise ConfigError("perfect_info", f"must be true or false, got {self.perfect_info!r}")
        if self.autoreset not in AUTORESET_MODES:
            raise ConfigError("autoreset", f"unknown mode {self.autoreset!r}; allowed: "
                              f"{AUTORESET_MODES}")


def build_scenario(opts: EnvOptions, scenario: Mapping[str, Any] | None) -> Scenario:
    """The env's scenario: :data:`ENV_DEFAULTS`, then ``scenario``, then the owned keys.

    Raises:
        ConfigError: an unknown key, a bad value, or a key the env owns.
    """
    over = dict(scenario or {})
    for key in _OWNED:
        if key in over:
            raise ConfigError(key, "is set by the env (duration from max_steps); "
                              "do not override it")
    values = {**ENV_DEFAULTS, **over}
    base = load(None, (), **values)
    period = base.commands.every / base.f_align
    # room for max_steps decisions plus the ticks before the first shown state
    duration = (opts.max_steps + 10) * period + 1.0
    return load(None, (), **values, duration=duration, warmup=0.0,
                **{"commands.enabled": True, "fidelity.enabled": False})
