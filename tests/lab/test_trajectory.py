"""The formation study's trajectory metrics: slot distances, the turn window, convergence times."""

from __future__ import annotations

import math

import numpy as np
from sigma_lab.studies.trajectory import convergence_time, slot_distances, window_end


def test_convergence_time_is_the_sample_after_the_last_excursion() -> None:
    t = np.arange(6, dtype=float)
    d = np.array([9.0, 5.0, 1.0, 4.0, 1.0, 0.5])
    assert convergence_time(t, d, 3.0, 5.0) == 4.0
    assert convergence_time(t, d, 10.0, 5.0) == 0.0  # always inside
    assert math.isnan(convergence_time(t, d, 3.0, 3.0))  # outside at the window's end
    assert convergence_time(t, d, 3.0, 2.0) == 2.0


def test_window_ends_where_the_first_turn_began() -> None:
    t = np.arange(10, dtype=float)
    course = np.radians([0, 0, 0, 0, 0, 0.5, 5, 20, 40, 60])
    # first sample > 15 deg off is t=7; the last calm one (<= 1 deg) before it is t=5
    assert window_end(t, course, 15.0, 1.0) == 5.0
    assert window_end(t, np.zeros(10), 15.0, 1.0) == 9.0  # no turn: the whole flight
    assert window_end(np.array([2.0]), np.zeros(1), 15.0, 1.0) == 2.0


def test_slot_distances_of_a_leader_flying_east() -> None:
    t = np.array([0.0, 1.0, 2.0])
    pos = np.zeros((3, 2, 3))
    pos[:, 0, 1] = [0.0, 10.0, 20.0]  # leader flies east at 10 m/s, altitude 0
    pos[:, 1] = [3.0, 4.0, 7.0]  # follower fixed at north 3, east 4, altitude 7
    seen: list[float] = []

    def slots_at(p: np.ndarray, course: float) -> np.ndarray:
        seen.append(course)
        return np.array([[p[0, 0], p[0, 1]], [0.0, 0.0]])  # follower's slot: the origin

    dh, dv, course = slot_distances(t, pos, 0, slots_at)
    assert np.allclose(course, math.pi / 2) and np.allclose(seen, math.pi / 2)
    assert np.array_equal(dh[:, 1], [5.0, 5.0, 5.0])  # 3-4-5 triangle to the origin
    assert np.array_equal(dh[:, 0], [0.0, 0.0, 0.0])
    assert np.array_equal(dv[:, 1], [7.0, 7.0, 7.0]) and np.array_equal(dv[:, 0], [0.0] * 3)
