"""Name -> factory registries of dynamics models and behaviours.

``make_dynamics("quadrotor")``, ``make_dynamics("jsbsim:F450")``,
``make_behaviour("formation")``. A new behaviour is one factory entry in
:data:`BEHAVIOURS` returning an object with ``commands(view, dynamics)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sigma_des.agents.behaviours import BehaviourSet, route_rule, separation_rule
from sigma_des.agents.cohesion import Cohesion
from sigma_des.agents.formation import FormationRoute, formation_rule
from sigma_des.agents.pointmass import PointMass
from sigma_des.core.models import Behaviour, DynamicsModel
from sigma_des.errors import ConfigError

__all__ = ["DYNAMICS", "BEHAVIOURS", "make_dynamics", "make_behaviour"]


def _aircraft(preset: str) -> Callable[..., DynamicsModel]:
    def make(**params: Any) -> DynamicsModel:
        from sigma_des.agents.aircraft import GeneralAircraft
        return GeneralAircraft(preset, **params)
    return make


def _jsbsim(model: str, **params: Any) -> DynamicsModel:
    from sigma_des.agents.jsbsim_node import JSBSimModel
    return JSBSimModel(model, **params)


#: Built-in dynamics models; ``jsbsim:<model>`` is resolved by :func:`make_dynamics`.
DYNAMICS: dict[str, Callable[..., DynamicsModel]] = {
    "pointmass": PointMass,
    "quadrotor": _aircraft("quadrotor"),
    "fixedwing": _aircraft("fixedwing"),
}

#: Built-in behaviours.
BEHAVIOURS: dict[str, Callable[..., Behaviour]] = {
    "cohesion": Cohesion,
    "route": lambda **p: BehaviourSet([route_rule(**p)], name="route"),
    "formation": FormationRoute,
    "follow": lambda **p: BehaviourSet([formation_rule(**p)], name="follow"),
    "separation": lambda **p: BehaviourSet([separation_rule(**p)], name="separation"),
}


def make_dynamics(name: str, **params: Any) -> DynamicsModel:
    """The dynamics model called ``name`` (``jsbsim:<model>`` for JSBSim aircraft).

    Raises:
        ConfigError: (a ValueError) naming the ``dynamics`` field and the allowed values.
    """
    if name.startswith("jsbsim:"):
        return _jsbsim(name.split(":", 1)[1], **params)
    return _factory(DYNAMICS, "dynamics", name, " or 'jsbsim:<model>'")(**params)


def make_behaviour(name: str, **params: Any) -> Behaviour:
    """The behaviour called ``name``.

    Raises:
        ConfigError: (a ValueError) naming the ``behaviour`` field and the allowed values.
    """
    return _factory(BEHAVIOURS, "behaviour", name)(**params)


def _factory(table: dict[str, Callable[..., Any]], field: str, name: str,
             more: str = "") -> Callable[..., Any]:
    """The factory ``table[name]``; ConfigError naming ``field`` and the allowed names
    (and ``more`` of them) if there is none."""
    try:
        return table[name]
    except KeyError:
        raise ConfigError(field, f"unknown {field} {name!r}; allowed: "
                          f"{sorted(table)}{more}") from None
