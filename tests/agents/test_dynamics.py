"""Rigid body, rotors, trim and the row-independence contract of the general aircraft."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.atmosphere import gravity_scalar
from sigma_des.agents.rigid_body import rigid_body_substep, rotmat
from sigma_des.agents.wind import WindConfig
from sigma_des.core.models import DynamicsModel


def _rotors_off(m: GeneralAircraft, n: int = 1) -> np.ndarray:
    return np.zeros((n, 7))


def test_models_satisfy_protocol() -> None:
    for name in ("quadrotor", "fixedwing"):
        assert isinstance(GeneralAircraft(name), DynamicsModel)


def test_free_fall_matches_half_g_t_squared() -> None:
    m = GeneralAircraft("quadrotor", omega_min=0.0)
    m.prm[L.AERO_S] = 0.0                      # vacuum: no body drag
    s = m.initial_state(1)
    s[:, L.OM0:L.OM0 + 4] = 0.0
    nodes = np.arange(1)
    g = gravity_scalar(100.0)
    t = 0.0
    for k in range(1, 301):
        s = m.step_open_loop(s, _rotors_off(m), 0.01, k, nodes)
        t += 0.01
    fall = 100.0 - s[0, L.H]
    # g varies by ~1e-5 over the 44 m fall; the integrator is exact for constant g.
    assert fall == pytest.approx(0.5 * g * t * t, rel=2e-5)
    assert s[0, L.W] == pytest.approx(g * t, rel=2e-5)          # body z is down


def test_hover_at_computed_rotor_speed_stays_put() -> None:
    m = GeneralAircraft("quadrotor")
    s0 = m.initial_state(1)
    w = m.hover_omega(100.0)
    assert s0[0, L.OM0] == w
    act = np.array([[w] * 4 + [0.0, 0.0, 0.0]])
    s = s0
    for k in range(1, 1001):                   # 10 s open loop
        s = m.step_open_loop(s, act, 0.01, k, np.arange(1))
    assert abs(s[0, L.H] - 100.0) < 1e-3
    assert np.hypot(s[0, L.XN], s[0, L.YE]) < 1e-6
    assert np.abs(s[0, L.P:L.R + 1]).max() < 1e-9
    # A 2 % lower rotor speed must not hover (the test can fail).
    s = s0
    for k in range(1, 201):
        s = m.step_open_loop(s, act * 0.98, 0.01, k, np.arange(1))
    assert s[0, L.H] < 99.9


def test_pure_roll_moment_gives_p_dot_equal_l_over_ixx() -> None:
    for name in ("quadrotor", "fixedwing"):
        m = GeneralAircraft(name)
        x = np.zeros(L.STATE_DIM)
        x[L.Q0] = 1.0
        lm, h = 0.37, 0.001
        for _ in range(50):
            rigid_body_substep(x, m.prm, rotmat(x), 0.0, 0.0, 0.0, lm, 0.0, 0.0, 0.0, h)
        if m.params.ixz == 0.0:
            assert x[L.P] == pytest.approx(lm / m.params.ixx * 0.05, rel=1e-12)
            assert x[L.Q] == 0.0 and x[L.R] == 0.0
        else:   # product of inertia couples roll into yaw: p_dot = Izz L / (Ixx Izz - Ixz^2)
            p = m.params
            assert x[L.P] == pytest.approx(p.izz * lm / (p.ixx * p.izz - p.ixz ** 2) * 0.05,
                                           rel=1e-6)


def test_quaternion_stays_unit_norm_over_1e5_steps() -> None:
    m = GeneralAircraft("fixedwing")
    x = np.zeros(L.STATE_DIM)
    x[L.Q0] = 1.0
    x[L.P], x[L.Q], x[L.R] = 0.6, -0.4, 0.3        # tumbling, asymmetric inertia
    for _ in range(100_000):
        rigid_body_substep(x, m.prm, rotmat(x), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0025)
    norm = np.sqrt((x[L.Q0:L.Q3 + 1] ** 2).sum())
    assert abs(norm - 1.0) < 1e-12
    r = np.array(rotmat(x)).reshape(3, 3)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)


def test_fixedwing_trim_holds_altitude_and_speed_for_60s() -> None:
    m = GeneralAircraft("fixedwing")
    s = m.initial_state(3)
    cmd = m.default_command(s)
    nodes = np.arange(3)
    hs, vs = [], []
    for k in range(1, 6001):
        s = m.step(s, cmd, 0.01, k, nodes)
        if k % 50 == 0:
            hs.append(s[:, L.H].copy())
            vs.append(np.linalg.norm(s[:, L.U:L.W + 1], axis=1))
    assert np.abs(np.array(hs) - 100.0).max() < 1.0          # stated bound: +-1 m
    assert np.abs(np.array(vs) - 20.0).max() < 0.5           # stated bound: +-0.5 m/s
    # Open loop at the trim actuators also stays level for 5 s (trim is right).
    s = m.initial_state(1)
    act = np.array([[m.trim["omega"], 0, 0, 0, 0.0, m.trim["delta_e"], 0.0]])
    for k in range(1, 501):
        s = m.step_open_loop(s, act, 0.01, k, np.arange(1))
    assert abs(s[0, L.H] - 100.0) < 0.5


def test_autopilots_follow_speed_course_and_altitude_with_varying_dt() -> None:
    for name, v in (("quadrotor", 6.0), ("fixedwing", 22.0)):
        m = GeneralAircraft(name)
        s = m.initial_state(1)
        cmd = np.array([[v, np.pi / 2, 115.0, np.nan]])
        for k in range(1, 4001):
            s = m.step(s, cmd, 0.01 if k < 2000 else 0.02, k, np.arange(1))
        obs = m.observe(s)[0]
        vel = np.linalg.norm(s[0, L.U:L.W + 1])
        assert abs(obs[11] - 115.0) < 1.0, name
        assert abs(vel - v) < 0.6, name
        assert abs(obs[5] - np.pi / 2) < 0.05, name


def _random_states(m: GeneralAircraft, n: int, rng: np.random.Generator) -> np.ndarray:
    s = m.initial_state(n)
    s[:, L.U:L.W + 1] += rng.normal(0, 1.0, (n, 3))
    s[:, L.P:L.R + 1] += rng.normal(0, 0.2, (n, 3))
    q = s[:, L.Q0:L.Q3 + 1] + rng.normal(0, 0.1, (n, 4))
    s[:, L.Q0:L.Q3 + 1] = q / np.linalg.norm(q, axis=1, keepdims=True)
    s[:, L.TU:L.TW + 1] = rng.normal(0, 1.0, (n, 3))
    return s


@pytest.mark.parametrize("name", ["quadrotor", "fixedwing"])
def test_batched_step_equals_single_row_steps_bit_for_bit(name: str) -> None:
    rng = np.random.default_rng(5)
    m = GeneralAircraft(name, wind=WindConfig(mean_ned=(2.0, -1.0, 0.0), w20=7.7), seed=9)
    n = 37
    s = _random_states(m, n, rng)
    cmd = m.default_command(s)
    cmd[:, 0] += rng.normal(0, 2, n)
    cmd[::3, 3] = 0.2                             # some rows use the roll override
    nodes = rng.permutation(1000)[:n].astype(np.int64)
    before = s.copy()
    for dt, frame in ((0.01, 17), (0.02, 18), (0.013, 19)):
        batch = m.step(s, cmd, dt, frame, nodes)
        np.testing.assert_array_equal(s, before)          # input not mutated
        for i in range(n):
            one = m.step(s[i:i + 1], cmd[i:i + 1], dt, frame, nodes[i:i + 1])
            assert np.array_equal(one[0], batch[i]), (dt, i)
        perm = rng.permutation(n)
        np.testing.assert_array_equal(m.step(s[perm], cmd[perm], dt, frame, nodes[perm]),
                                      batch[perm])
        s = before = batch


def test_rollback_is_rerun() -> None:
    m = GeneralAircraft("fixedwing", wind=WindConfig(w20=7.7))
    s0 = m.initial_state(4)
    cmd = m.default_command(s0)
    nodes = np.arange(4)
    a = s0
    for k in range(1, 21):
        a = m.step(a, cmd, 0.01, k, nodes)
    b = s0.copy()
    for k in range(1, 21):
        b = m.step(b, cmd, 0.01, k, nodes)
    np.testing.assert_array_equal(a, b)
