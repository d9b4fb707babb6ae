"""Resolve the scenario's dynamics and behaviour names to objects."""

from __future__ import annotations

from sigma_des.agents.base import Behaviour, DynamicsModel
from sigma_des.agents.cohesion import Cohesion
from sigma_des.agents.pointmass import PointMass
from sigma_des.config import Scenario
from sigma_des.errors import ConfigError

__all__ = ["make_dynamics", "make_behaviour"]


def make_dynamics(sc: Scenario) -> DynamicsModel:
    """The dynamics model named by ``sc.dynamics``."""
    if sc.dynamics == "pointmass":
        return PointMass()
    try:
        from sigma_des.agents import registry  # type: ignore[attr-defined]
    except ImportError:
        raise ConfigError(
            "dynamics", f"{sc.dynamics!r} is not available in this build; use 'pointmass'"
        ) from None
    try:
        return registry.make_dynamics(sc.dynamics)  # type: ignore[no-any-return]
    except ValueError as e:
        raise ConfigError("dynamics", str(e)) from None


def make_behaviour(sc: Scenario) -> Behaviour | None:
    """The behaviour named by ``sc.commands.behaviour`` (None: commands disabled)."""
    if not sc.commands.enabled or sc.commands.behaviour == "none":
        return None
    if sc.commands.behaviour == "cohesion":
        return Cohesion()
    try:
        from sigma_des.agents import registry  # type: ignore[attr-defined]

        return registry.make_behaviour(sc.commands.behaviour)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        pass
    except ValueError as e:
        raise ConfigError("commands.behaviour", str(e)) from None
    raise ConfigError(
        "commands.behaviour",
        f"unknown behaviour {sc.commands.behaviour!r}; allowed: cohesion, none",
    )
