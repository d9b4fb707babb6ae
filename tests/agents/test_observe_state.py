"""``observe_state`` (its arguments compiled) against the numpy code it replaces, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import observe_state


def _reference(state: np.ndarray) -> np.ndarray:
    """``observe_state`` at 31370a2, verbatim."""
    q0, q1, q2, q3 = (state[:, L.Q0], state[:, L.Q1], state[:, L.Q2], state[:, L.Q3])
    obs = np.empty((state.shape[0], 12))
    obs[:, 0:3] = state[:, L.U:L.W + 1]
    obs[:, 3] = np.arctan2(2.0 * (q0 * q1 + q2 * q3), 1.0 - 2.0 * (q1 * q1 + q2 * q2))
    obs[:, 4] = np.arcsin(np.clip(2.0 * (q0 * q2 - q3 * q1), -1.0, 1.0))
    obs[:, 5] = np.arctan2(2.0 * (q0 * q3 + q1 * q2), 1.0 - 2.0 * (q2 * q2 + q3 * q3))
    obs[:, 6:9] = state[:, L.P:L.R + 1]
    obs[:, 9:12] = state[:, L.XN:L.H + 1]
    return obs


@pytest.mark.parametrize("seed", range(6))
def test_observe_state_matches_numpy_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 2000))
    state = rng.normal(0.0, 30.0, (n, L.STATE_DIM))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[rng.random(n) < 0.1] *= 1.2  # unnormalised: the pitch argument clipped
    state[:, L.Q0:L.Q3 + 1] = q
    state[rng.random(n) < 0.02] = np.nan
    got, want = observe_state(state), _reference(state)
    assert got.shape == want.shape and got.tobytes() == want.tobytes()
    view = state[::2]  # a strided view of the rows
    assert observe_state(view).tobytes() == _reference(view).tobytes()


def test_observe_state_hand_computed() -> None:
    # a quarter turn in yaw: q = (cos 45°, 0, 0, sin 45°) -> phi 0, theta 0, psi pi/2
    state = np.zeros((1, L.STATE_DIM))
    c = math.sqrt(0.5)
    state[0, [L.Q0, L.Q3]] = c
    state[0, [L.U, L.V, L.W, L.P, L.Q, L.R, L.XN, L.YE, L.H]] = range(1, 10)
    obs = observe_state(state)[0]
    assert obs[[0, 1, 2, 6, 7, 8, 9, 10, 11]].tolist() == list(range(1, 10))
    assert obs[3] == 0.0 and obs[4] == 0.0
    assert obs[5] == float(np.arctan2(2.0 * c * c, 1.0 - 2.0 * c * c))
    assert obs[5] == pytest.approx(math.pi / 2, abs=1e-15)


def test_observe_state_into_a_ring_slot_is_the_same_bits() -> None:
    rng = np.random.default_rng(7)
    n = 333
    state = rng.normal(0.0, 30.0, (n, L.STATE_DIM))
    q = rng.normal(size=(n, 4))
    state[:, L.Q0:L.Q3 + 1] = q / np.linalg.norm(q, axis=1, keepdims=True)
    ring = np.full((3, n, 12), -7.0)
    got = observe_state(state, ring[1])
    assert got is ring[1] or np.shares_memory(got, ring[1])
    assert ring[1].tobytes() == _reference(state).tobytes()
    assert (ring[0] == -7.0).all() and (ring[2] == -7.0).all()  # only its slot written
    with pytest.raises(ValueError, match="C-contiguous float64"):
        observe_state(state, np.asfortranarray(np.empty((n, 12))))
    with pytest.raises(ValueError, match=r"\(333, 12\)"):
        observe_state(state, np.empty((n - 1, 12)))
