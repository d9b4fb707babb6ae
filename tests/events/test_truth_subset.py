"""A truth of some of the swarm's nodes (a live host's) equals the whole truth's rows.

The live host composes :class:`SwarmTruth` over its own nodes: each row must be the
row of that node id in the truth of the whole swarm, stepped and rolled back (the
dynamics is keyed by node id: turbulence draws differ per aircraft), and its frame log
must hold every frame's true positions in frame order.
"""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.pointmass import PointMass
from sigma_des.agents.wind import WindConfig
from sigma_des.events.truth import FrameTrack, SwarmTruth

N, H = 6, 8
SUBSET = np.array([1, 3, 4], dtype=np.int64)


def _turbulent() -> GeneralAircraft:
    return GeneralAircraft("quadrotor", WindConfig(w20=15.4), seed=11)


def _step(truth: SwarmTruth, frames: range, cmd: np.ndarray) -> None:
    for k in frames:
        truth.step_frame(k, 0.01 + 0.001 * (k % 3), cmd, None)


def test_a_subset_truth_steps_and_rolls_back_as_the_whole_swarm_rows() -> None:
    dyn = _turbulent()
    whole = SwarmTruth(dyn, N, H, 10.0, True)
    track = FrameTrack(SUBSET.size)
    part = SwarmTruth(dyn, N, H, 10.0, True, SUBSET, track)
    cmd = dyn.default_command(whole.state)
    cmd[:, 0] += np.linspace(0.5, 3.0, N)  # each aircraft its own command
    _step(whole, range(12), cmd)
    _step(part, range(12), cmd[SUBSET])
    row = np.array([2.0, 0.3, 110.0, np.nan])
    # node 3 (row 1 of the part) rolls back from frame 7: the batched re-simulation path
    assert part.rollback(1, 7, 11, row) == whole.rollback(3, 7, 11, row) == 5
    _step(whole, range(12, 14), cmd)
    _step(part, range(12, 14), cmd[SUBSET])
    held = whole.slot_frame >= 0
    np.testing.assert_array_equal(part.slot_frame, whole.slot_frame)
    np.testing.assert_array_equal(part.obs_hist[held], whole.obs_hist[held][:, SUBSET])
    np.testing.assert_array_equal(part.ckpt[held], whole.ckpt[held][:, SUBSET])
    np.testing.assert_array_equal(part.state, whole.state[SUBSET])
    # the rows differ per aircraft: keying the dynamics by row would fail the above
    assert not np.array_equal(whole.state[1], whole.state[0])
    assert (part.rollbacks, part.resim_steps) == (1, 5)
    with pytest.raises(TypeError, match="FrameTrack"):
        part.trajectory_log()  # its log is every frame's, not the fidelity samples
    part.release()
    frames, t, pos = track.arrays()
    assert frames.tolist() == list(range(14))
    np.testing.assert_array_equal(t, np.cumsum([0.01 + 0.001 * (k % 3) for k in range(14)]))
    last = whole.positions(13)
    assert last is not None
    np.testing.assert_array_equal(pos[13], last[SUBSET])
    assert not part.held(13) and part.positions(13) is None


def test_a_model_without_batched_steps_rolls_back_the_same_rows() -> None:
    dyn = PointMass()
    whole = SwarmTruth(dyn, N, H, 10.0, True)
    part = SwarmTruth(dyn, N, H, 10.0, True, SUBSET, FrameTrack(SUBSET.size))
    cmd = dyn.default_command(whole.state) + 1.0
    _step(whole, range(10), cmd)
    _step(part, range(10), cmd[SUBSET])
    row = np.array([1.0, 0.5, 2.0])
    assert part.rollback(2, 6, 9, row) == whole.rollback(4, 6, 9, row) == 4
    np.testing.assert_array_equal(part.state, whole.state[SUBSET])
    held = whole.slot_frame >= 0
    np.testing.assert_array_equal(part.obs_hist[held], whole.obs_hist[held][:, SUBSET])
