"""JSBSim nodes behind the DynamicsModel interface."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jsbsim")

from sigma_des.agents.jsbsim_node import JSBSimModel, available_models  # noqa: E402
from sigma_des.agents.registry import make_dynamics  # noqa: E402
from sigma_des.errors import ConfigError  # noqa: E402


def test_shipped_models_include_f450_and_c172x() -> None:
    assert {"F450", "c172x"} <= set(available_models())


def test_f450_hovers_and_follows_commands_under_its_autopilot() -> None:
    m = make_dynamics("jsbsim:F450")
    assert m.name == "jsbsim:F450"
    s = m.initial_state(2)
    nodes = np.arange(2)
    cmd = m.default_command(s)
    for k in range(1, 301):                            # 3 s hover
        s = m.step(s, cmd, 0.01, k, nodes)
    assert np.abs(s[:, 11] - 100.0).max() < 0.3
    assert np.abs(s[:, 9:11] - m.initial_state(2)[:, 9:11]).max() < 0.3
    cmd[:, 2] = 105.0
    for k in range(301, 801):                          # climb 5 m in 5 s
        s = m.step(s, cmd, 0.02 if k > 500 else 0.01, k, nodes)
    assert np.abs(s[:, 11] - 105.0).max() < 0.7


def test_rollback_reinitialises_from_the_row() -> None:
    m = JSBSimModel("F450")
    s0 = m.initial_state(1)
    cmd = m.default_command(s0)
    s1 = m.step(s0, cmd, 0.01, 1, np.arange(1))
    s = s1
    for k in range(2, 50):
        s = m.step(s, cmd, 0.01, k, np.arange(1))
    again = m.step(s0, cmd, 0.01, 1, np.arange(1))      # s0 != node's last row -> re-init
    # Approximate, not bit-exact: the rotors keep their current rpm (not in the row),
    # so velocities differ slightly; positions are restored from the row.
    np.testing.assert_allclose(again[0, 9:12], s1[0, 9:12], atol=2e-3)
    np.testing.assert_allclose(again[0, 0:3], s1[0, 0:3], atol=0.2)
    assert abs(s[0, 11] - 100.0) < 0.3
    assert abs(again[0, 12] - 0.01) < 1e-12


def test_unknown_jsbsim_model_names_the_field() -> None:
    with pytest.raises(ConfigError, match="dynamics.*unknown JSBSim model.*allowed"):
        JSBSimModel("F451")


def test_c172x_holds_altitude_and_speed_under_its_autopilot() -> None:
    m = make_dynamics("jsbsim:c172x")
    s = m.initial_state(1)
    cmd = m.default_command(s)
    hs = []
    for k in range(1, 1001):                           # 10 s at 50 m/s
        s = m.step(s, cmd, 0.01, k, np.arange(1))
        hs.append(s[0, 11])
    assert np.abs(np.array(hs) - 100.0).max() < 6.0
    assert abs(np.linalg.norm(s[0, 0:3]) - 50.0) < 3.0
