"""The block-vectorised aircraft kernel against the one-row physics functions, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.approx import sqrt
from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar
from sigma_des.agents.forces import forces_moments
from sigma_des.agents.kernel import LANES
from sigma_des.agents.rigid_body import rigid_body_substep, rotmat, to_body
from sigma_des.agents.wind import WindConfig


@njit(cache=True)
def _sqrt_all(v: np.ndarray) -> np.ndarray:
    out = np.empty_like(v)
    for i in range(v.shape[0]):
        out[i] = sqrt(v[i])
    return out


def test_sqrt_intrinsic_is_math_sqrt_bit_for_bit() -> None:
    v = np.concatenate([np.random.default_rng(1).random(1000) * 1e6,
                        [0.0, -0.0, 1e-310, np.inf, 2.0, 1e300]])
    got = _sqrt_all(v)
    want = np.array([math.sqrt(x) for x in v])
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
    assert math.copysign(1.0, got[1001]) == -1.0          # sqrt(-0.0) = -0.0
    assert np.isnan(_sqrt_all(np.array([-1.0]))[0])       # no exception, NaN


@pytest.mark.parametrize("name", ["quadrotor", "fixedwing"])
def test_open_loop_step_is_the_row_physics_composed(name: str) -> None:
    """One sub-step, still air: lags, then rotor + aero forces, then the rigid body."""
    m = GeneralAircraft(name)
    h = m.params.max_substep
    n = LANES + 7                                   # a full block and a partial one
    rng = np.random.default_rng(3)
    s = m.initial_state(n)
    s[:, L.U:L.W + 1] += rng.normal(0, 2, (n, 3))
    s[:, L.P:L.R + 1] += rng.normal(0, 0.5, (n, 3))
    act = np.abs(rng.normal(400, 150, (n, 7)))
    act[:, 4:] = rng.normal(0, 0.1, (n, 3))
    got = m.step_open_loop(s, act, h, 1, np.arange(n))
    am = 1.0 - math.exp(-h / m.prm[L.TAU_MOTOR])
    asv = 1.0 - math.exp(-h / m.prm[L.TAU_SERVO])
    for i in range(n):
        x = s[i].copy()
        rm = rotmat(x)
        rho = isa_scalar(x[L.H])[2]
        g = gravity_scalar(x[L.H])
        bx, by, bz = to_body(rm, 0.0, 0.0, 0.0)
        for j in range(len(m.params.rotors)):
            x[L.OM0 + j] += am * (act[i, j] - x[L.OM0 + j])
        for c, a in ((L.DA, 4), (L.DE, 5), (L.DR, 6)):
            x[c] += asv * (act[i, a] - x[c])
        f = forces_moments(x, m.prm, bx, by, bz, rho)
        rigid_body_substep(x, m.prm, rm, *f, g, h)
        assert np.array_equal(x.view(np.uint64), got[i].view(np.uint64)), i


def test_rows_at_different_times_cross_turbulence_updates_on_their_own() -> None:
    """Rows of one block at times that do / do not cross a 20 Hz turbulence update."""
    m = GeneralAircraft("quadrotor", wind=WindConfig(w20=7.7), seed=4)
    n = 2 * LANES + 5
    s = m.initial_state(n)
    # Alternate runs of equal times (the kernel reuses the update indices of equal
    # times): t = 0.045 crosses 0.05 with dt = 0.01, t = 0.02 does not.
    s[:, L.TIME] = np.where((np.arange(n) // 3) % 2 == 0, 0.045, 0.02)
    cmd = m.default_command(s)
    nodes = np.arange(n, dtype=np.int64)
    batch = m.step(s, cmd, 0.01, 5, nodes)
    crossed = s[:, L.TIME] == 0.045
    moved = np.any(batch[:, L.TU:L.TW + 1] != s[:, L.TU:L.TW + 1], axis=1)
    np.testing.assert_array_equal(moved, crossed)
    for i in range(n):
        one = m.step(s[i:i + 1], cmd[i:i + 1], 0.01, 5, nodes[i:i + 1])
        assert np.array_equal(one[0], batch[i]), i
