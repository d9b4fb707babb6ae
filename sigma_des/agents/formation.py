"""Leader–follower formation (paper eqs. 16–19) and the paper's formation scenario.

Slots. Follower of rank ``k = 1, 2, …`` (node order, leader excluded) sits in
row ``j = ceil(k / 2)`` of a V, on the right for odd ``k`` and the left for even
``k``; its offset in the leader's heading frame is ``(-j d cos theta, ±j d sin
theta)`` (behind, beside), and the slot in NED is ``p_L + R(psi_L) offset``.

Errors. The slot minus the follower position, rotated by the follower's heading
into its own frame, gives the along-track error ``e_x`` (ahead positive) and
cross-track error ``e_y`` (right positive).

Commands. Roll ``phi_cmd = P_phi e_y + P_psi (psi_L - psi_F)`` and speed
``v_cmd = v_cru + P_v e_x``; course ``chi_cmd = psi_L`` and altitude ``h_L``.
Paper values: ``P_phi = 0.015 rad/m``, ``P_psi = 0.4``, ``P_v = 0.3 1/s``,
``v_cru = 20 m/s``, ``d = 30 m``, ``theta = 45 deg``. The roll law suits
aircraft that turn by banking; for the others (multirotors, point mass —
``roll_law=False``, the default picked by :func:`formation_behaviour` from the
model) the same errors drive a velocity-field law: velocity = leader velocity
+ ``k_pos`` x (slot − position), ``chi``/``v`` from that vector.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.behaviours import BehaviourSet, Rule, route_rule, separation_rule
from sigma_des.agents.rule_kernels import slots_kernel, velocity_field
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.errors import ConfigError

__all__ = ["formation_slots", "formation_rule", "formation_behaviour", "FormationRoute"]

Array = NDArray[np.float64]


def formation_slots(obs: Array, leader: int, d: float, theta: float) -> Array:
    """``(n, 2)`` NED slot of every node (the leader's own position for the leader)."""
    # followers 1, 2, … in node order: row ceil(rank / 2), right for odd ranks; the
    # arithmetic compiled (rule_kernels.slots_kernel), the cos and sin here as before
    psi = obs[leader, 5]
    return slots_kernel(np.ascontiguousarray(obs, dtype=np.float64), int(leader), float(d),
                        math.cos(theta), math.sin(theta), math.cos(psi), math.sin(psi))


def formation_rule(leader: int = 0, d: float = 30.0, theta_deg: float = 45.0,
                   p_phi: float = 0.015, p_psi: float = 0.4, p_v: float = 0.3,
                   v_cru: float = 20.0, roll_law: bool = True, k_pos: float = 0.3,
                   phi_max: float = 0.6, weight: float = 1.0) -> Rule:
    """Followers hold their V slots behind ``leader`` (see module docstring)."""
    if not d > 0:
        raise ConfigError("formation.d", f"must be > 0, got {d}")
    if not 0 <= theta_deg <= 90:
        raise ConfigError("formation.theta_deg", f"must be in [0, 90], got {theta_deg}")
    theta = math.radians(theta_deg)

    def extract(view: SwarmView) -> Array | None:
        if not view.valid[leader]:
            return None
        return formation_slots(view.obs, leader, d, theta)

    def trigger(slots: Array | None, view: SwarmView) -> Array:
        t = np.zeros(view.obs.shape[0])
        if slots is not None:
            t[:] = 1.0
            t[leader] = 0.0
        return t

    def logic(slots: Any, view: SwarmView) -> Array:
        o = view.obs
        psi_l = o[leader, 5]
        out = np.empty((o.shape[0], 4))
        out[:, 2] = o[leader, 11]
        if roll_law:
            psi_f = o[:, 5]
            dn, de = slots[:, 0] - o[:, 9], slots[:, 1] - o[:, 10]
            ex = np.cos(psi_f) * dn + np.sin(psi_f) * de
            ey = -np.sin(psi_f) * dn + np.cos(psi_f) * de
            dpsi = (psi_l - psi_f + np.pi) % (2 * np.pi) - np.pi
            out[:, 0] = v_cru + p_v * ex
            out[:, 1] = psi_l
            out[:, 3] = np.clip(p_phi * ey + p_psi * dpsi, -phi_max, phi_max)
        else:
            vl = max(float(np.hypot(o[leader, 0], o[leader, 1])), 0.0)
            # vn = vl cos(psi_l) + k_pos (slot - position), compiled; hypot and arctan2
            # stay numpy's (rule_kernels: module docstring)
            vn, ve = velocity_field(np.ascontiguousarray(o, dtype=np.float64), slots,
                                    vl * math.cos(psi_l), vl * math.sin(psi_l), float(k_pos))
            out[:, 0] = np.hypot(vn, ve)
            out[:, 1] = np.arctan2(ve, vn)
            out[:, 3] = np.nan
        return out

    return Rule("formation", extract, trigger, 0.5, logic, weight)


def formation_behaviour(dynamics: DynamicsModel | None = None, leader: int = 0,
                        size: tuple[float, float] = (1000.0, 750.0), altitude: float = 100.0,
                        v_cru: float = 20.0, separation: float = 8.0,
                        roll_law: bool | None = None, **formation: float) -> BehaviourSet:
    """The paper's scenario: the leader flies the rectangle, followers keep the V.

    Args:
        dynamics: the model the swarm flies (picks the roll law for fixed wings).
        leader: leader node.
        size: route rectangle (north, east), m.
        altitude: route altitude (m).
        v_cru: cruise speed (m/s).
        separation: collision-avoidance radius (m), 0 disables it.
        roll_law: force the roll law on/off (default: on for fixed-wing models).
        **formation: further :func:`formation_rule` parameters (d, theta_deg, p_phi…).
    """
    if roll_law is None:
        params = getattr(dynamics, "params", None)
        roll_law = getattr(params, "autopilot", "") == "fixedwing" or \
            str(getattr(dynamics, "name", "")).startswith("jsbsim:c")
    rules = [route_rule((leader,), size, speed=v_cru, altitude=altitude),
             formation_rule(leader, v_cru=v_cru, roll_law=roll_law, **formation)]
    if separation > 0:
        rules.append(separation_rule(separation))
    return BehaviourSet(rules, mode="priority", name="formation")


class FormationRoute(BehaviourSet):
    """Registry-friendly :func:`formation_behaviour` that adapts to the model on first use."""

    def __init__(self, **params: Any) -> None:
        self._params = params
        self._built_for: int | None = None
        super().__init__([route_rule()], name="formation")

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> Array:
        if self._built_for != id(dynamics):
            b = formation_behaviour(dynamics, **self._params)
            self.rules, self.mode = b.rules, b.mode
            self._built_for = id(dynamics)
        return super().commands(view, dynamics)
