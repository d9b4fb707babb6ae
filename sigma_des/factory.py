"""Resolve the scenario's dynamics and behaviour names to objects (via the agents registry)."""

from __future__ import annotations

from sigma_des.agents.registry import make_behaviour as _make_behaviour
from sigma_des.agents.registry import make_dynamics as _make_dynamics
from sigma_des.config import Scenario
from sigma_des.core.models import Behaviour, DynamicsModel
from sigma_des.errors import ConfigError

__all__ = ["make_dynamics", "make_behaviour"]


def make_dynamics(sc: Scenario) -> DynamicsModel:
    """The dynamics model named by ``sc.dynamics`` (with ``sc.dynamics_params`` applied)."""
    if sc.dynamics_params:
        from sigma_des.agents.aircraft import GeneralAircraft
        from sigma_des.agents.fitted import fitted_params

        return GeneralAircraft(fitted_params(sc.dynamics_params, sc.dynamics))
    try:
        return _make_dynamics(sc.dynamics)
    except ConfigError as e:
        raise ConfigError("dynamics", e.reason) from None
    except ValueError as e:
        raise ConfigError("dynamics", str(e)) from None


def make_behaviour(sc: Scenario) -> Behaviour | None:
    """The behaviour named by ``sc.commands.behaviour`` (None: commands disabled)."""
    if not sc.commands.enabled or sc.commands.behaviour == "none":
        return None
    try:
        return _make_behaviour(sc.commands.behaviour)
    except ConfigError as e:
        raise ConfigError("commands.behaviour", f"{e.reason}, or 'none'") from None
    except ValueError as e:
        raise ConfigError("commands.behaviour", str(e)) from None
