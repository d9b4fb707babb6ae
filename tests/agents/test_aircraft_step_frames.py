"""GeneralAircraft.step_frames: the compiled multi-frame re-simulation of one aircraft."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents.aircraft import GeneralAircraft


@pytest.mark.parametrize("preset", ["quadrotor", "fixedwing"])
def test_step_frames_equals_frame_by_frame_steps_bitwise(preset: str) -> None:
    ac = GeneralAircraft(preset, seed=3)
    state = ac.initial_state(5)
    cmd = ac.default_command(state)
    cmd[:, 0] += 2.0
    node = 3
    dts = np.array([0.01, 0.01, 0.0125, 0.02, 0.01])
    got = ac.step_frames(state[node], cmd[node], dts, 40, node)
    s = state[node : node + 1]
    for j, dt in enumerate(dts):
        s = ac.step(s, cmd[node : node + 1], float(dt), 40 + j, np.array([node]))
        np.testing.assert_array_equal(got[j], s[0])
    # it really moved (a wrong frame key or dt would not match the loop above)
    assert not np.array_equal(got[-1], state[node])


@pytest.mark.parametrize("preset", ["quadrotor", "fixedwing"])
def test_step_into_writes_step_bits_into_the_given_slot(preset: str) -> None:
    ac = GeneralAircraft(preset, seed=5)
    state = ac.initial_state(7)
    cmd = ac.default_command(state)
    cmd[:, 2] += 3.0
    nodes = np.arange(10, 17)
    ring = np.zeros((2, 7, state.shape[1]))
    ring[0] = state
    ac.step_into(ring[0], cmd, 0.0125, 9, nodes, ring[1])
    want = ac.step(state, cmd, 0.0125, 9, nodes)
    assert ring[1].tobytes() == want.tobytes()
    assert ring[0].tobytes() == state.tobytes()  # the input row untouched
    assert not np.array_equal(want, state)
    with pytest.raises(ValueError, match="must not overlap"):
        ac.step_into(ring[0], cmd, 0.0125, 9, nodes, ring[0])
    with pytest.raises(ValueError, match="C-contiguous"):
        ac.step_into(state, cmd, 0.0125, 9, nodes, np.empty((7, 2 * state.shape[1]))[:, ::2])
