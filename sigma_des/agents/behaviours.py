"""Behaviour library (paper eqs. 2–3): rules that turn a swarm view into guidance commands.

A rule (eq. 2) is ``B = <I, T, tau, L, w>``: an information-extraction function
``I`` (what the node reads from the shown swarm), a trigger function ``T`` and
threshold ``tau`` (the rule is active for node i when ``T_i >= tau``), the logic
``L`` producing an action (a guidance row ``[v, chi, h, phi]``, NaN = no opinion)
and a priority weight ``w``. A :class:`BehaviourSet` (eq. 3) combines the active
rules of each node: ``weighted`` takes the weight-normalised mean of their actions
(courses averaged as unit vectors, ``phi`` over the rules that set it),
``priority`` keeps the action of the highest-weight active rule. An optional
consistency term blends in the swarm's previous mean action with weight
``kappa``: ``a_i <- (1 - kappa) a_i + kappa mean_j a_j(prev)`` — our reading of the
paper's "consistency with the swarm's previous actions".

Guidance is the common command of the general aircraft (aircraft.py); for a
model with another command convention (the point mass's NED velocity)
:func:`to_command` converts it, so every behaviour works on every model.
Users add a behaviour by writing one :class:`Rule` (or any object with a
``commands(view, dynamics)`` method) and registering a factory in registry.py.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sigma_des.agents.rule_kernels import (
    any_active,
    carrot_kernel,
    close_pairs,
    known_positions,
    priority_take,
    separation_push,
)
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.errors import ConfigError

__all__ = ["Rule", "BehaviourSet", "to_command", "route_rule", "separation_rule",
           "rectangle_carrot"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Rule:
    """One behaviour rule (paper eq. 2), see module docstring."""

    name: str
    extract: Callable[[SwarmView], Any]
    trigger: Callable[[Any, SwarmView], Array]
    threshold: float
    logic: Callable[[Any, SwarmView], Array]
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not self.weight > 0:
            raise ConfigError(f"{self.name}.weight", f"must be > 0, got {self.weight}")


def to_command(guidance: Array, dynamics: DynamicsModel, obs: Array) -> Array:
    """Guidance ``(n, 4)`` in ``dynamics``' own command columns (NaN rows stay NaN)."""
    names = tuple(getattr(dynamics, "command_names", ("vn", "ve", "vh")))
    if names[:3] == ("v_cmd", "chi_cmd", "h_cmd"):
        return np.ascontiguousarray(guidance[:, :dynamics.command_dim])
    v, chi, h = guidance[:, 0], guidance[:, 1], guidance[:, 2]
    cols = {"vn": v * np.cos(chi), "ve": v * np.sin(chi),
            # Altitude hold as a climb-rate demand: 0.5 1/s, limited to 3 m/s.
            "vh": np.clip(0.5 * (h - obs[:, 11]), -3.0, 3.0)}
    out = np.full((guidance.shape[0], dynamics.command_dim), np.nan)
    for j, name in enumerate(names[:dynamics.command_dim]):
        if name not in cols:
            raise ValueError(f"cannot express guidance as command column {name!r}")
        out[:, j] = cols[name]
    return out


class BehaviourSet:
    """Combination of rules (paper eq. 3); implements the ``Behaviour`` protocol.

    Args:
        rules: the rules.
        mode: ``weighted`` (weighted mean of active actions) or ``priority``.
        consistency: ``kappa`` in [0, 1) of the consistency term.
        name: behaviour name.
    """

    def __init__(self, rules: Sequence[Rule], mode: str = "weighted",
                 consistency: float = 0.0, name: str = "behaviours") -> None:
        if mode not in ("weighted", "priority"):
            raise ConfigError(f"{name}.mode", f"must be 'weighted' or 'priority', got {mode!r}")
        if not 0 <= consistency < 1:
            raise ConfigError(f"{name}.consistency", f"must be in [0, 1), got {consistency}")
        if not rules:
            raise ConfigError(f"{name}.rules", "needs at least one rule")
        self.rules = list(rules)
        self.mode = mode
        self.consistency = consistency
        self.name = name
        self._prev_mean: Array | None = None

    def guidance(self, view: SwarmView) -> Array:
        """Combined ``(n, 4)`` guidance; rows with no active rule are NaN."""
        n = view.obs.shape[0]
        if self.mode == "priority":
            out = self._priority(view)
            return self._blend(out) if self.consistency > 0 else out
        acc = np.zeros((n, 6))       # w*v, w*cos chi, w*sin chi, w*h, w*phi, w(phi)
        wsum = np.zeros(n)
        for rule in self.rules:
            info = rule.extract(view)
            active = (rule.trigger(info, view) >= rule.threshold) & view.valid
            if not active.any():
                continue
            a = rule.logic(info, view)
            act = active & ~np.isnan(a[:, 0])
            w = np.where(act, rule.weight, 0.0)
            aa = np.where(act[:, None], a, 0.0)
            acc[:, 0] += w * aa[:, 0]
            acc[:, 1] += w * np.cos(aa[:, 1])
            acc[:, 2] += w * np.sin(aa[:, 1])
            acc[:, 3] += w * aa[:, 2]
            has_phi = act & ~np.isnan(a[:, 3])
            acc[:, 4] += np.where(has_phi, rule.weight * np.nan_to_num(a[:, 3]), 0.0)
            acc[:, 5] += np.where(has_phi, rule.weight, 0.0)
            wsum += w
        out = np.full((n, 4), np.nan)
        on = wsum > 0
        out[on, 0] = acc[on, 0] / wsum[on]
        out[on, 1] = np.arctan2(acc[on, 2], acc[on, 1])
        out[on, 2] = acc[on, 3] / wsum[on]
        ph = on & (acc[:, 5] > 0)
        out[ph, 3] = acc[ph, 4] / acc[ph, 5]
        if self.consistency > 0:
            out = self._blend(out)
        return out

    def _priority(self, view: SwarmView) -> Array:
        """The ``priority`` combination: each row takes the action of its highest-weight
        active rule (the first of equal weights), NaN where none is active."""
        n = view.obs.shape[0]
        valid = np.ascontiguousarray(view.valid, dtype=np.bool_)
        best = np.full((n, 4), np.nan)
        best_w = np.zeros(n)
        for rule in self.rules:
            info = rule.extract(view)
            trig = np.ascontiguousarray(np.broadcast_to(
                np.asarray(rule.trigger(info, view), dtype=np.float64), (n,)))
            threshold = float(rule.threshold)
            if not any_active(trig, threshold, valid):
                continue
            a = np.ascontiguousarray(rule.logic(info, view), dtype=np.float64)
            priority_take(trig, threshold, valid, a, float(rule.weight), best, best_w)
        return best

    def _blend(self, out: Array) -> Array:
        on = ~np.isnan(out[:, 0])
        k = self.consistency
        prev = self._prev_mean
        if on.any():
            cur = np.array([out[on, 0].mean(), np.arctan2(np.sin(out[on, 1]).mean(),
                                                          np.cos(out[on, 1]).mean()),
                            out[on, 2].mean()])
        if prev is not None:
            out = out.copy()
            out[on, 0] = (1 - k) * out[on, 0] + k * prev[0]
            out[on, 1] = np.arctan2((1 - k) * np.sin(out[on, 1]) + k * np.sin(prev[1]),
                                    (1 - k) * np.cos(out[on, 1]) + k * np.cos(prev[1]))
            out[on, 2] = (1 - k) * out[on, 2] + k * prev[2]
        if on.any():
            self._prev_mean = cur
        return out

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> Array:
        """``(n, command_dim)`` commands for ``dynamics``; NaN rows = no new command."""
        return to_command(self.guidance(view), dynamics, view.obs)


# --- built-in rules ------------------------------------------------------------------------

@lru_cache(maxsize=64)
def _rectangle(
    size: tuple[float, float], origin: tuple[float, float]
) -> tuple[Array, Array, Array, Array, Array, float]:
    """The route rectangle's constant arrays (computed once per rectangle, read-only):
    corners, side lengths, start and end of each side along the perimeter, side
    vectors, perimeter."""
    a, b = size
    corners = np.array([[0, 0], [a, 0], [a, b], [0, b]], dtype=float) + np.asarray(origin)
    seg_len = np.array([a, b, a, b])
    ends = np.cumsum(seg_len)
    starts = np.concatenate([[0.0], ends[:-1]])
    d = np.roll(corners, -1, axis=0) - corners
    for x in (corners, seg_len, ends, starts, d):
        x.flags.writeable = False
    return corners, seg_len, starts, ends, d, 2 * (a + b)


def rectangle_carrot(pos: Array, size: tuple[float, float], origin: tuple[float, float],
                     lookahead: float) -> Array:
    """Carrot points ``lookahead`` metres ahead along a clockwise rectangle.

    The rectangle has corners ``origin``, ``origin + (size[0], 0)``,
    ``origin + size`` and ``origin + (0, size[1])`` (north, east). Each position
    is projected onto the nearest point of the perimeter; the carrot is the
    perimeter point ``lookahead`` further along. Being a pure function of the
    position, the route needs no waypoint index (safe under rollback).
    """
    corners, seg_len, starts, ends, d, perim = _rectangle(tuple(size), tuple(origin))
    # the projections, nearest side and carrot, compiled (the numpy expressions' very
    # operations: rule_kernels.carrot_kernel)
    return carrot_kernel(np.ascontiguousarray(pos, dtype=np.float64), corners, seg_len,
                         starts, ends, d, float(perim), float(lookahead))


def route_rule(leaders: Sequence[int] = (0,), size: tuple[float, float] = (1000.0, 750.0),
               origin: tuple[float, float] = (0.0, 0.0), speed: float = 20.0,
               altitude: float = 100.0, lookahead: float = 80.0, weight: float = 1.0) -> Rule:
    """Waypoint route: ``leaders`` fly a clockwise rectangle (the paper's 1 km x 0.75 km)."""
    if min(size) <= 0:
        raise ConfigError("route.size", f"must be two lengths > 0, got {size}")
    lead = np.asarray(leaders, dtype=int)

    def trigger(_: Any, view: SwarmView) -> Array:
        t = np.zeros(view.obs.shape[0])
        t[lead[lead < len(t)]] = 1.0
        return t

    def logic(_: Any, view: SwarmView) -> Array:
        # only the leaders' rows: the trigger leaves every other row inactive, and
        # guidance reads a rule's action on its active rows only (every figure of a
        # row depends on that row alone, so the leaders' values are the same bits)
        obs = view.obs
        out = np.full((obs.shape[0], 4), np.nan)
        rows = lead[lead < len(out)]
        rows = rows[~np.isnan(obs[rows, 9])]
        pos = obs[rows, 9:11]
        c = rectangle_carrot(pos, size, origin, lookahead)
        out[rows, 0] = speed
        out[rows, 1] = np.arctan2(c[:, 1] - pos[:, 1], c[:, 0] - pos[:, 0])
        out[rows, 2] = altitude
        return out

    return Rule("route", lambda v: None, trigger, 0.5, logic, weight)


def separation_rule(radius: float = 10.0, gain: float = 2.0, weight: float = 5.0) -> Rule:
    """Collision avoidance: steer away from every neighbour closer than ``radius``.

    Trigger = deepest intrusion ``radius - d_min`` (active when > 0); action =
    course of own velocity + ``gain`` x the summed repulsion (unit vectors scaled
    by intrusion fraction), same speed, altitude nudged apart by 1 m per metre
    of vertical intrusion. Neighbours come from a k-d tree, so the cost is
    ``O(n log n)``.
    """
    if not radius > 0:
        raise ConfigError("separation.radius", f"must be > 0, got {radius}")

    def extract(view: SwarmView) -> tuple[Array, Array]:
        obs = np.ascontiguousarray(view.obs, dtype=np.float64)
        # Only nodes with a known position: unknown ones (NaN) are nobody's neighbour,
        # and mapping them all to one far point made every pair of them "intrude".
        known, pts = known_positions(obs)
        # the sums below follow the order of the pairs: the grid's pairs where that order
        # changes no bit, else scipy's tree and its order (rule_kernels)
        pairs, exact = close_pairs(pts, float(radius))
        if not exact:
            pairs = cKDTree(pts).query_pairs(radius, output_type="ndarray")
            pairs = pairs.astype(np.int64, copy=False).reshape(-1, 2)
        return separation_push(pts, known, pairs, float(radius), obs.shape[0])

    def logic(info: tuple[Array, Array], view: SwarmView) -> Array:
        rep, _ = info
        o = view.obs
        speed = np.hypot(o[:, 0], o[:, 1])
        vn, ve = np.cos(o[:, 5]) * np.maximum(speed, 1.0), np.sin(o[:, 5]) * np.maximum(speed, 1.0)
        out = np.empty((len(o), 4))
        out[:, 0] = speed
        out[:, 1] = np.arctan2(ve + gain * rep[:, 1] * speed.clip(1.0),
                               vn + gain * rep[:, 0] * speed.clip(1.0))
        out[:, 2] = o[:, 11] + rep[:, 2] * radius
        out[:, 3] = np.nan
        return out

    return Rule("separation", extract, lambda info, view: info[1], 1e-9, logic, weight)
