"""ISA atmosphere, gravity, wind and the counter-based kernel RNG."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.atmosphere import gravity, isa, isa_scalar
from sigma_des.agents.wind import WindConfig, dryden_scales
from sigma_des.core.counter_rng import normals, uniform3
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError


@pytest.mark.parametrize(("h", "rho", "t", "p"), [
    (0.0, 1.2250, 288.15, 101325.0),
    (1000.0, 1.1117, 281.65, 89876.0),     # standard table (geometric 1 km)
    (5000.0, 0.7364, 255.68, 54048.0),
])
def test_isa_matches_standard_table(h: float, rho: float, t: float, p: float) -> None:
    tt, pp, rr = isa(h)
    assert float(rr) == pytest.approx(rho, abs=2e-4)
    assert float(tt) == pytest.approx(t, abs=0.05)
    assert float(pp) == pytest.approx(p, rel=2e-4)
    assert isa_scalar(h)[2] == pytest.approx(float(rr), rel=1e-12)


def test_gravity_decreases_with_altitude() -> None:
    assert float(gravity(0.0)) == pytest.approx(9.80665)
    assert float(gravity(10000.0)) == pytest.approx(9.80665 * (6356766 / 6366766) ** 2)


def test_kernel_uniforms_equal_stream_uniforms_and_normals_close() -> None:
    st = RandomStreams(7).stream("x")
    for a, b, c in [(0, 0, 0), (5, 123456, 2), (-3, 7, 11)]:
        assert uniform3(st.key, a, b, c) == float(st.uniform(a, b, c)[0])
    z = normals(st.key, 4, 9, 50)
    ref = st.normal(4, 9, np.arange(50))
    np.testing.assert_allclose(z, ref, rtol=2e-9, atol=1e-12)


def test_dryden_scales_low_altitude() -> None:
    luv, lw, suv, sw = dryden_scales(100.0, 15.4)
    hf = 100 / 0.3048
    assert lw == pytest.approx(100.0)
    assert luv == pytest.approx(hf / (0.177 + 0.000823 * hf) ** 1.2 * 0.3048)
    assert sw == pytest.approx(1.54)
    assert suv > sw


def test_turbulence_variance_and_determinism() -> None:
    m = GeneralAircraft("fixedwing", wind=WindConfig(w20=15.4), seed=3)
    n = 400
    s0 = m.initial_state(n)
    s = s0
    nodes = np.arange(n)
    cmd = m.default_command(s0)
    samples = []
    for k in range(1, 601):
        s = m.step(s, cmd, 0.02, k, nodes)
        if k > 300:
            samples.append(s[:, 23].copy())     # vertical turbulence state
    w = np.array(samples)
    _, _, _, sw = dryden_scales(100.0, 15.4)
    assert w.std() == pytest.approx(sw, rel=0.15)
    # Same (node, frame) keys -> identical gusts when re-run.
    again = m.step(s0, cmd, 0.02, 1, nodes)
    np.testing.assert_array_equal(again, m.step(s0, cmd, 0.02, 1, nodes))


def test_mean_wind_decays_and_drifts_a_hovering_quad() -> None:
    still = GeneralAircraft("quadrotor")
    windy = GeneralAircraft("quadrotor", wind=WindConfig(mean_ned=(0.0, 5.0, 0.0), decay_tau=2.0))
    nodes = np.arange(1)
    a = b = still.initial_state(1)
    act = np.array([[still.trim["omega"]] * 4 + [0.0, 0.0, 0.0]])
    for k in range(1, 101):
        a = still.step_open_loop(a, act, 0.01, k, nodes)
        b = windy.step_open_loop(b, act, 0.01, k, nodes)
    assert abs(a[0, 11]) < 1e-6 and b[0, 11] > 0.01      # pushed east by the wind


def test_wind_config_errors_name_the_field() -> None:
    with pytest.raises(ConfigError, match="wind.decay_tau"):
        WindConfig(decay_tau=-1.0)
    with pytest.raises(ConfigError, match="wind.w20"):
        WindConfig(w20=math.nan)
