"""Behaviour rules, formation convergence in the ideal run, DTW, registry and errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.behaviours import (
    BehaviourSet,
    Rule,
    rectangle_carrot,
    route_rule,
    separation_rule,
    to_command,
)
from sigma_des.agents.formation import formation_rule, formation_slots
from sigma_des.agents.ideal import fly
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.pointmass import PointMass
from sigma_des.agents.presets import preset, quadrotor_f450
from sigma_des.agents.registry import BEHAVIOURS, DYNAMICS, make_behaviour, make_dynamics
from sigma_des.core.models import SwarmView
from sigma_des.errors import ConfigError
from sigma_des.metrics.dtw import dtw, dtw_normalised


def _view(obs: np.ndarray) -> SwarmView:
    n = obs.shape[0]
    return SwarmView(obs=obs, frame=np.zeros(n, np.int64), valid=np.ones(n, bool), aligned_frame=0)


def _const_rule(name: str, v: float, chi: float, w: float, active: list[bool]) -> Rule:
    return Rule(name, lambda view: None, lambda _, view: np.array(active, float), 0.5,
                lambda _, view: np.tile([v, chi, 100.0, np.nan], (len(active), 1)), w)


def test_weighted_and_priority_combination() -> None:
    obs = np.zeros((3, 12))
    a = _const_rule("a", 10.0, 0.0, 1.0, [True, True, False])
    b = _const_rule("b", 20.0, math.pi / 2, 3.0, [True, False, False])
    g = BehaviourSet([a, b]).guidance(_view(obs))
    assert g[0, 0] == pytest.approx(17.5)
    assert g[0, 1] == pytest.approx(math.atan2(3, 1))         # circular weighted mean
    assert g[1, 0] == 10.0 and np.isnan(g[2]).all()
    p = BehaviourSet([a, b], mode="priority").guidance(_view(obs))
    assert p[0, 0] == 20.0 and p[1, 0] == 10.0


def test_consistency_term_pulls_towards_previous_swarm_action() -> None:
    obs = np.zeros((2, 12))
    fast = _const_rule("a", 20.0, 0.0, 1.0, [True, True])
    slow = _const_rule("a", 10.0, 0.0, 1.0, [True, True])
    bs = BehaviourSet([fast], consistency=0.25)
    bs.guidance(_view(obs))
    bs.rules = [slow]
    assert bs.guidance(_view(obs))[0, 0] == pytest.approx(0.75 * 10 + 0.25 * 20)


def test_rectangle_carrot_goes_clockwise() -> None:
    pos = np.array([[500.0, -5.0], [1005.0, 300.0], [0.0, 0.0]])
    c = rectangle_carrot(pos, (1000.0, 750.0), (0.0, 0.0), 50.0)
    np.testing.assert_allclose(c, [[550.0, 0.0], [1000.0, 350.0], [50.0, 0.0]])


def test_separation_steers_apart_only_when_close() -> None:
    obs = np.zeros((3, 12))
    obs[:, 0] = 10.0
    obs[:, 9:12] = [[0, 0, 100], [0, 4, 100], [0, 100, 100]]
    g = BehaviourSet([separation_rule(10.0)]).guidance(_view(obs))
    assert g[0, 1] < 0 < g[1, 1]                  # west one turns west, east one east
    assert np.isnan(g[2]).all()


def test_separation_ignores_unknown_positions() -> None:
    # Two known aircraft 4 m apart and three unknown ones (NaN): the unknown ones are
    # nobody's neighbour (they used to share one far point, so each pair of them
    # "intruded": N^2/2 pairs at the start of a 10 000-node run).
    obs = np.zeros((5, 12))
    obs[:, 9:12] = [[0, 0, 100], [np.nan] * 3, [0, 4, 100], [np.nan] * 3, [np.nan] * 3]
    rep, depth = separation_rule(10.0).extract(_view(obs))
    assert depth.tolist() == [6.0, 0.0, 6.0, 0.0, 0.0]
    # push = d / |d| * (radius - |d|) / radius = (0, -4) / 4 * 0.6 for node 0
    assert rep.tolist() == [[0.0, -0.6, 0.0], [0.0] * 3, [0.0, 0.6, 0.0], [0.0] * 3, [0.0] * 3]


def test_guidance_converts_to_pointmass_velocity() -> None:
    obs = np.zeros((1, 12))
    obs[0, 11] = 90.0
    cmd = to_command(np.array([[10.0, math.pi / 2, 100.0, np.nan]]), PointMass(), obs)
    np.testing.assert_allclose(cmd, [[0.0, 10.0, 3.0]], atol=1e-12)


def test_formation_slots_follow_leader_heading() -> None:
    obs = np.zeros((3, 12))
    obs[0, 5] = math.pi / 2                      # leader heading east at the origin
    s = formation_slots(obs, 0, 30.0, math.radians(45))
    k = 30 * math.sqrt(0.5)
    # Behind = west; rank 1 on the leader's right (south), rank 2 on its left (north).
    np.testing.assert_allclose(s, [[0, 0], [-k, -k], [k, -k]], atol=1e-9)
    obs[0, 5] = 0.0
    np.testing.assert_allclose(formation_slots(obs, 1, 30.0, math.radians(45))[0], [-k, k])


@pytest.mark.parametrize(("name", "seconds", "bound"), [("quadrotor", 40.0, 0.5),
                                                       ("fixedwing", 80.0, 1.0)])
def test_formation_followers_converge_in_ideal_run(name: str, seconds: float,
                                                   bound: float) -> None:
    dyn = make_dynamics(name)
    beh = BehaviourSet([formation_rule(0, roll_law=(name == "fixedwing"))])
    t, traj = fly(dyn, beh, 5, seconds, 0.01, log_rate=30)
    assert traj.shape == (len(t), 5, 3) and t[1] == pytest.approx(1 / 30)
    obs = np.zeros((5, 12))
    obs[:, 9:12] = traj[-1]                      # leader flies north (default command)
    err = np.hypot(*(formation_slots(obs, 0, 30.0, math.radians(45)) - traj[-1, :, :2]).T)
    obs[:, 9:12] = traj[0]
    err0 = np.hypot(*(formation_slots(obs, 0, 30.0, math.radians(45)) - traj[0, :, :2]).T)
    assert err0[1:].min() > 5.0
    assert err[1:].max() < bound
    assert np.abs(traj[-1, :, 2] - 100.0).max() < 1.0


def test_paper_formation_behaviour_runs_on_every_model() -> None:
    for name in ("pointmass", "quadrotor", "fixedwing"):
        dyn = make_dynamics(name)
        t, traj = fly(dyn, make_behaviour("formation"), 4, 5.0, 0.02)
        assert np.isfinite(traj).all() and traj.shape[1] == 4


def test_dtw() -> None:
    a = np.array([[0.0, 0], [1, 0], [2, 0], [3, 0]])
    assert dtw(a, a) == 0.0
    b = np.array([[0.0, 0], [0, 0], [1, 0], [2, 0], [3, 0]])      # same path, delayed
    assert dtw(a, b) == 0.0
    c = a + [0.0, 1.0]
    assert dtw(a, c) == pytest.approx(4.0)
    per_node = dtw(np.stack([a, a], 1), np.stack([a, c], 1))
    np.testing.assert_allclose(per_node, [0.0, 4.0])
    assert dtw_normalised(4.0, 1 / 30, 2.0) == pytest.approx(4.0 / 60)


def test_registry_names_and_errors() -> None:
    assert set(DYNAMICS) == {"pointmass", "quadrotor", "fixedwing"}
    assert {"route", "formation", "separation"} <= set(BEHAVIOURS)
    with pytest.raises(ValueError, match="dynamics.*'pointmass'"):
        make_dynamics("helicopter")
    with pytest.raises(ValueError, match="behaviour.*allowed"):
        make_behaviour("swarm-dance")
    with pytest.raises(ValueError, match="dynamics.*unknown JSBSim model 'nosuch'"):
        make_dynamics("jsbsim:nosuch")
    assert route_rule().name == "route"


def test_bad_parameters_name_the_field() -> None:
    import dataclasses
    with pytest.raises(ConfigError, match=r"quadrotor\.mass.*> 0"):
        dataclasses.replace(quadrotor_f450(), mass=-1.0)
    with pytest.raises(ConfigError, match=r"quadrotor\.mass"):
        GeneralAircraft("quadrotor", mass=-0.5)
    with pytest.raises(ConfigError, match="preset.*allowed"):
        preset("blimp")
    with pytest.raises(ConfigError, match=r"quadrotor\.wingspan.*unknown parameter"):
        GeneralAircraft("quadrotor", wingspan=2.0)
    with pytest.raises(ConfigError, match=r"fixedwing\.v_cruise"):
        GeneralAircraft("fixedwing", v_cruise=60.0)          # beyond the propeller
    with pytest.raises(ConfigError, match="formation.d"):
        formation_rule(d=-3.0)
    assert isinstance(quadrotor_f450(), AircraftParams)
