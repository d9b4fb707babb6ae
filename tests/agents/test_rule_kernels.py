"""The compiled pieces of the built-in rules against the numpy code they replace, bit for bit.

The references below are the numpy expressions of the rules before they were compiled
(behaviours.py and formation.py at 31370a2), copied verbatim.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.spatial import cKDTree

from sigma_des.agents.behaviours import BehaviourSet, Rule, rectangle_carrot, separation_rule
from sigma_des.agents.formation import formation_behaviour, formation_rule, formation_slots
from sigma_des.agents.registry import make_dynamics
from sigma_des.agents.rule_kernels import (
    close_pairs,
    known_positions,
    priority_take,
    separation_push,
    slots_kernel,
    velocity_field,
)
from sigma_des.core.models import SwarmView

Array = np.ndarray


def _ref_separation(obs: Array, radius: float) -> tuple[Array, Array]:
    pos = obs[:, [9, 10, 11]]
    rep = np.zeros_like(pos)
    depth = np.zeros(len(pos))
    known = np.flatnonzero(np.isfinite(pos).all(axis=1))
    pairs = cKDTree(pos[known]).query_pairs(radius, output_type="ndarray")
    if len(pairs):
        i, j = known[pairs[:, 0]], known[pairs[:, 1]]
        d = pos[i] - pos[j]
        dist = np.maximum(np.linalg.norm(d, axis=1), 1e-6)
        push = d / dist[:, None] * ((radius - dist) / radius)[:, None]
        np.add.at(rep, i, push)
        np.add.at(rep, j, -push)
        np.maximum.at(depth, i, radius - dist)
        np.maximum.at(depth, j, radius - dist)
    return rep, depth


def _ref_slots(obs: Array, leader: int, d: float, theta: float) -> Array:
    n = obs.shape[0]
    i = np.arange(n)
    rank = np.where(i < leader, i + 1, i)
    rank[leader] = 0
    row = np.ceil(rank / 2.0)
    side = np.where(rank % 2 == 1, 1.0, -1.0)
    dx = -row * d * math.cos(theta)
    dy = side * row * d * math.sin(theta)
    psi = obs[leader, 5]
    c, s = math.cos(psi), math.sin(psi)
    slots = np.empty((n, 2))
    slots[:, 0] = obs[leader, 9] + c * dx - s * dy
    slots[:, 1] = obs[leader, 10] + s * dx + c * dy
    return slots


def _ref_velocity_law(slots: Array, o: Array, leader: int, k_pos: float) -> Array:
    psi_l = o[leader, 5]
    dn, de = slots[:, 0] - o[:, 9], slots[:, 1] - o[:, 10]
    out = np.empty((o.shape[0], 4))
    out[:, 2] = o[leader, 11]
    vl = max(float(np.hypot(o[leader, 0], o[leader, 1])), 0.0)
    vn = vl * math.cos(psi_l) + k_pos * dn
    ve = vl * math.sin(psi_l) + k_pos * de
    out[:, 0] = np.hypot(vn, ve)
    out[:, 1] = np.arctan2(ve, vn)
    out[:, 3] = np.nan
    return out


def _ref_priority(rules: list[Rule], view: SwarmView) -> Array:
    n = view.obs.shape[0]
    best = np.full((n, 4), np.nan)
    best_w = np.zeros(n)
    for rule in rules:
        info = rule.extract(view)
        active = (rule.trigger(info, view) >= rule.threshold) & view.valid
        if not active.any():
            continue
        a = rule.logic(info, view)
        act = active & ~np.isnan(a[:, 0])
        take = act & (rule.weight > best_w)
        best[take] = a[take]
        best_w[take] = rule.weight
    return best


def _swarm(rng: np.random.Generator, n: int, spread: float, unknown: float = 0.1) -> Array:
    """A crowded swarm: positions within ``spread`` m (many pairs closer than 10 m),
    some rows unknown (NaN), headings and speeds random."""
    obs = rng.normal(size=(n, 12))
    obs[:, 0:2] *= 8.0
    obs[:, 5] = rng.uniform(-math.pi, math.pi, n)
    obs[:, 9:11] = rng.uniform(0.0, spread, (n, 2))
    obs[:, 11] = 100.0 + rng.normal(0.0, 3.0, n)
    obs[rng.random(n) < unknown, 9:12] = np.nan
    if n > 3:
        obs[1, 9:12] = obs[2, 9:12]  # two aircraft at one point (distance clamped at 1e-6)
    return obs


def _same(a: Array, b: Array) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("seed", range(12))
def test_separation_matches_numpy_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    obs = _swarm(rng, n, float(rng.uniform(5.0, 300.0)))
    radius = float(rng.uniform(0.5, 25.0))
    view = SwarmView(obs=obs, frame=np.zeros(n, np.int64), valid=np.ones(n, bool),
                     aligned_frame=0)
    rep, depth = separation_rule(radius).extract(view)
    ref_rep, ref_depth = _ref_separation(obs, radius)
    assert _same(rep, ref_rep) and _same(depth, ref_depth)


def test_separation_hand_computed() -> None:
    # node 0 at the origin, node 1 4 m east, node 2 3 m north (radius 10):
    # pair (0, 1): d = (0, -4, 0), |d| = 4, push = (0, -1, 0) * 0.6
    # pair (0, 2): d = (-3, 0, 0), |d| = 3, push = (-1, 0, 0) * 0.7
    # pair (1, 2): d = (-3, 4, 0), |d| = 5, push = (-0.6, 0.8, 0) * 0.5
    obs = np.zeros((3, 12))
    obs[:, 9:12] = [[0, 0, 100], [0, 4, 100], [3, 0, 100]]
    known, pts = known_positions(obs)
    assert known.tolist() == [0, 1, 2] and pts.tolist() == obs[:, 9:12].tolist()
    pairs = np.array([[0, 1], [0, 2], [1, 2]], dtype=np.int64)
    rep, depth = separation_push(pts, known, pairs, 10.0, 3)
    assert depth.tolist() == [7.0, 6.0, 7.0]
    assert rep.tolist() == [[-0.7, -0.6, 0.0], [-0.3, 0.4 + 0.6, 0.0], [0.7 + 0.3, -0.4, 0.0]]


def _sparse(rng: np.random.Generator, n: int, radius: float) -> Array:
    """``(n, 3)`` points on a jittered grid ``2.2 radius`` apart (no pair closer than
    ``radius`` but by the jitter), and a few points moved next to others (pairs)."""
    side = math.ceil(math.sqrt(n))
    i = np.arange(n)
    pts = np.stack([(i // side) * 2.2 * radius, (i % side) * 2.2 * radius,
                    np.full(n, 100.0)], axis=1) + rng.uniform(-0.1, 0.1, (n, 3)) * radius
    for a in rng.choice(n, size=min(n // 2, 1 + n // 8), replace=False):
        b = int(rng.integers(0, n))
        pts[a] = pts[b] + rng.uniform(-0.7, 0.7, 3) * radius
    return pts


def _tree_pairs(pts: Array, radius: float) -> set[tuple[int, int]]:
    return {(int(a), int(b)) for a, b in cKDTree(pts).query_pairs(radius, output_type="ndarray")}


@pytest.mark.parametrize("seed", range(16))
def test_close_pairs_are_the_trees_pairs(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    radius = float(rng.uniform(0.5, 25.0))
    pts = _sparse(rng, int(rng.integers(2, 600)), radius)
    pairs, exact = close_pairs(pts, radius)
    if exact:
        got = {(int(a), int(b)) for a, b in pairs}
        assert len(got) == len(pairs) and got == _tree_pairs(pts, radius)
        counts = np.bincount(pairs.ravel(), minlength=len(pts))
        assert counts.max(initial=0) <= 2
    else:  # a point in three pairs (the grid's answer would depend on the order)
        assert pairs.shape == (0, 2)
        counts = np.bincount(np.array(sorted(_tree_pairs(pts, radius))).ravel(),
                             minlength=len(pts))
        assert counts.max() >= 3


def test_close_pairs_hand_computed() -> None:
    pts = np.array([[0.0, 0.0, 100.0], [0.0, 4.0, 100.0], [30.0, 0.0, 100.0],
                    [30.0, 3.0, 104.0], [60.0, 60.0, 100.0]])
    pairs, exact = close_pairs(pts, 8.0)  # |(0, 3, 4)| = 5 < 8; the rest > 8 apart
    assert exact and sorted(map(tuple, pairs.tolist())) == [(0, 1), (2, 3)]
    assert close_pairs(pts, 0.5)[1] and close_pairs(pts, 0.5)[0].shape == (0, 2)
    assert close_pairs(pts[:1], 8.0)[1] and close_pairs(pts[:0], 8.0)[1]
    # exactly at the radius: too close to call (the tree's rounding decides)
    assert not close_pairs(pts, 5.0)[1]
    assert close_pairs(pts, 4.0)[0].shape == (0, 2) and not close_pairs(pts, 4.0)[1]
    # node 0 near three others: its repulsion would depend on the pairs' order
    crowd = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert not close_pairs(crowd, 1.2)[1] and close_pairs(crowd[:3], 1.2)[1]
    # a grid far larger than the swarm (two points 1e7 m apart), a radius not > 0
    assert not close_pairs(np.array([[0.0, 0, 0], [1e7, 1e7, 0]]), 8.0)[1]
    assert not close_pairs(pts, 0.0)[1] and not close_pairs(pts, float("nan"))[1]


@pytest.mark.parametrize("seed", range(8))
def test_separation_by_the_grid_matches_numpy_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(2, 500))
    radius = float(rng.uniform(1.0, 20.0))
    obs = _swarm(rng, n, 1.0)
    obs[:, 9:12] = _sparse(rng, n, radius)
    obs[rng.random(n) < 0.1, 9:12] = np.nan
    view = SwarmView(obs=obs, frame=np.zeros(n, np.int64), valid=np.ones(n, bool),
                     aligned_frame=0)
    rep, depth = separation_rule(radius).extract(view)
    ref_rep, ref_depth = _ref_separation(obs, radius)
    assert _same(rep, ref_rep) and _same(depth, ref_depth)


def test_known_positions_skips_rows_with_any_unknown_coordinate() -> None:
    obs = np.zeros((4, 12))
    obs[:, 9:12] = [[1, 2, 3], [np.nan, 0, 0], [4, 5, np.inf], [7, 8, 9]]
    known, pts = known_positions(obs)
    assert known.tolist() == [0, 3] and pts.tolist() == [[1, 2, 3], [7, 8, 9]]


@pytest.mark.parametrize("seed", range(6))
def test_slots_and_velocity_law_match_numpy_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 300))
    obs = _swarm(rng, n, 500.0, unknown=0.0)
    leader = int(rng.integers(0, n))
    d, theta = float(rng.uniform(1.0, 60.0)), float(rng.uniform(0.0, math.pi / 2))
    slots = formation_slots(obs, leader, d, theta)
    assert _same(slots, _ref_slots(obs, leader, d, theta))
    rule = formation_rule(leader, d=d, theta_deg=math.degrees(theta), roll_law=False,
                          k_pos=0.37)
    view = SwarmView(obs=obs, frame=np.zeros(n, np.int64), valid=np.ones(n, bool),
                     aligned_frame=0)
    info = rule.extract(view)
    assert _same(rule.logic(info, view), _ref_velocity_law(info, obs, leader, 0.37))


def test_slots_and_velocity_field_hand_computed() -> None:
    # leader 1 at (10, 20) heading north (c = 1, s = 0); d = 2, cos/sin theta = 0.5, 0.25:
    # node 0 is rank 1 (row 1, right): dx = -1, dy = 0.5 -> (9, 20.5); node 2 rank 2
    # (row 1, left): (9, 19.5); node 3 rank 3 (row 2, right): dx = -2, dy = 1 -> (8, 21)
    obs = np.zeros((4, 12))
    obs[1, 9:11] = [10.0, 20.0]
    slots = slots_kernel(obs, 1, 2.0, 0.5, 0.25, 1.0, 0.0)
    assert slots.tolist() == [[9.0, 20.5], [10.0, 20.0], [9.0, 19.5], [8.0, 21.0]]
    obs[:, 9:11] = [[9.0, 20.0], [10.0, 20.0], [7.0, 19.5], [8.0, 25.0]]
    vn, ve = velocity_field(obs, slots, 3.0, -1.0, 0.5)
    assert vn.tolist() == [3.0, 3.0, 4.0, 3.0] and ve.tolist() == [-0.75, -1.0, -1.0, -3.0]


def _random_rule(rng: np.random.Generator, n: int, name: str) -> Rule:
    trig = rng.choice([0.0, 0.3, 1.0, np.nan], n)
    act = rng.normal(size=(n, 4))
    act[rng.random(n) < 0.2, 0] = np.nan
    w = float(rng.choice([1.0, 2.0, 5.0]))
    return Rule(name, lambda v: None, lambda _, v: trig, 0.5, lambda _, v: act, w)


@pytest.mark.parametrize("seed", range(8))
def test_priority_combination_matches_numpy(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(1, 60))
    rules = [_random_rule(rng, n, f"r{k}") for k in range(int(rng.integers(1, 5)))]
    view = SwarmView(obs=np.zeros((n, 12)), frame=np.zeros(n, np.int64),
                     valid=rng.random(n) < 0.8, aligned_frame=0)
    got = BehaviourSet(rules, mode="priority").guidance(view)
    assert _same(got, _ref_priority(rules, view))


def test_priority_take_hand_computed() -> None:
    best, best_w = np.full((3, 4), np.nan), np.array([0.0, 2.0, 0.0])
    a = np.array([[1.0, 2, 3, 4], [5, 6, 7, 8], [np.nan, 0, 0, 0]])
    priority_take(np.array([1.0, 1.0, 1.0]), 0.5, np.array([True, True, True]), a, 1.0,
                  best, best_w)
    # row 1 keeps the heavier rule taken before, row 2 has no action
    assert best[0].tolist() == [1.0, 2, 3, 4] and np.isnan(best[1:]).all()
    assert best_w.tolist() == [1.0, 2.0, 0.0]


@pytest.mark.parametrize(("seed", "dynamics"), [(0, "quadrotor"), (1, "pointmass"),
                                                (2, "quadrotor"), (3, "fixedwing")])
def test_formation_behaviour_matches_the_numpy_rules(seed: int, dynamics: str) -> None:
    """The whole paper behaviour (route, V, separation; priority) against the numpy rules."""
    rng = np.random.default_rng(300 + seed)
    n = 250
    obs = _swarm(rng, n, 250.0)
    dyn = make_dynamics(dynamics)
    beh = formation_behaviour(dyn, separation=8.0)
    roll = dynamics == "fixedwing"
    valid = rng.random(n) < 0.9
    valid[0] = seed != 2  # seed 2: the leader unknown (no V rule)
    view = SwarmView(obs=obs, frame=np.zeros(n, np.int64), valid=valid, aligned_frame=0)
    ref_rules = list(beh.rules)
    # the reference: the same route rule, the V and separation rules in numpy
    theta = math.radians(45.0)
    sep = Rule("sep", lambda v: _ref_separation(v.obs, 8.0), lambda info, v: info[1], 1e-9,
               beh.rules[2].logic, 5.0)
    ref_rules[2] = sep
    if not roll:
        v_rule = beh.rules[1]
        ref_rules[1] = Rule(
            "v", lambda v: _ref_slots(v.obs, 0, 30.0, theta) if v.valid[0] else None,
            v_rule.trigger, 0.5, _velocity_logic(0, 0.3), 1.0)
    assert _same(beh.guidance(view), _ref_priority(ref_rules, view))


def _velocity_logic(leader: int, k_pos: float) -> Callable[[Array, SwarmView], Array]:
    return lambda slots, view: _ref_velocity_law(slots, view.obs, leader, k_pos)


def _ref_carrot(pos: Array, size: tuple[float, float], origin: tuple[float, float],
                lookahead: float) -> Array:
    a, b = size
    corners = np.array([[0, 0], [a, 0], [a, b], [0, b]], dtype=float) + np.asarray(origin)
    seg_len = np.array([a, b, a, b])
    ends = np.cumsum(seg_len)
    starts = np.concatenate([[0.0], ends[:-1]])
    d = np.roll(corners, -1, axis=0) - corners
    perim = 2 * (a + b)
    rel = pos[:, None, :] - corners[None, :, :]
    t = np.clip((rel * d[None]).sum(-1) / seg_len[None] ** 2, 0, 1)
    proj = corners[None] + t[..., None] * d[None]
    dist = np.linalg.norm(pos[:, None, :] - proj, axis=-1)
    k = np.argmin(dist, axis=1)
    s = (starts[k] + t[np.arange(len(k)), k] * seg_len[k] + lookahead) % perim
    seg = np.searchsorted(ends, s, side="right").clip(0, 3)
    frac = (s - starts[seg]) / seg_len[seg]
    return corners[seg] + frac[:, None] * d[seg]


@pytest.mark.parametrize("seed", range(10))
def test_carrot_matches_numpy_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(300 + seed)
    size = (float(rng.uniform(1.0, 2000.0)), float(rng.uniform(1.0, 2000.0)))
    origin = (float(rng.uniform(-500.0, 500.0)), float(rng.uniform(-500.0, 500.0)))
    lookahead = float(rng.choice([rng.uniform(-100.0, 300.0), 80.0, 2 * sum(size) + 5.0]))
    pos = np.asarray(origin) + rng.uniform(-0.5, 1.5, (200, 2)) * np.asarray(size)
    corners = np.array([[0, 0], [size[0], 0], size, [0, size[1]]]) + np.asarray(origin)
    pos[:4] = corners  # on the corners (ties between two sides)
    pos[4] = corners.mean(axis=0)  # the centre
    pos[5, 1] = np.nan
    got = rectangle_carrot(pos, size, origin, lookahead)
    assert _same(got, _ref_carrot(pos, size, origin, lookahead))


def test_carrot_hand_computed() -> None:
    # a 100 x 50 rectangle: (10, -5) projects to (10, 0) on the first side, 20 m on: (30, 0);
    # (120, 40) to (100, 40): 140 m along, 20 m on: 160 m, (100 - 10, 50) on the third side;
    # (-3, 1) to (0, 1) on the fourth: 299 m along, 20 m on wraps to 19 m: (19, 0)
    pos = np.array([[10.0, -5.0], [120.0, 40.0], [-3.0, 1.0]])
    got = rectangle_carrot(pos, (100.0, 50.0), (0.0, 0.0), 20.0)
    assert got.tolist() == [[30.0, 0.0], [90.0, 50.0], [19.0, 0.0]]
