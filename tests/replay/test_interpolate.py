"""Interpolants, the eq. (15) window and slerp: exact, hand-computed cases."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from sigma_des.replay import (
    INTERP_METHODS,
    WindowRule,
    interpolate,
    slerp_attitude,
    window_sizes,
)


def test_linear_is_hand_computed() -> None:
    t = np.array([0.0, 1.0, 3.0])
    y = np.array([[0.0, 1.0], [2.0, 1.0], [2.0, 5.0]])
    got = interpolate(t, y, "linear", at=[0.25, 2.0, 3.5])
    np.testing.assert_array_equal(got[:2], [[0.5, 1.0], [2.0, 3.0]])
    assert np.isnan(got[2]).all()  # no extrapolation


def test_cubic_and_akima_reproduce_what_they_must() -> None:
    t = np.linspace(0.0, 2.0, 9)
    q = np.linspace(0.0, 2.0, 41)
    cubic = t**3 - 2 * t
    np.testing.assert_allclose(interpolate(t, cubic, "cubic", at=q), q**3 - 2 * q, atol=1e-12)
    line = 3 * t + 1  # Akima and PCHIP reproduce straight lines
    for m in ("akima", "pchip"):
        np.testing.assert_allclose(interpolate(t, line, m, at=q), 3 * q + 1, atol=1e-12)


def test_pchip_does_not_overshoot_a_step() -> None:
    t = np.arange(6.0)
    y = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    q = np.linspace(0, 5, 101)
    got = interpolate(t, y, "pchip", at=q)
    assert got.min() >= 0.0 and got.max() <= 1.0
    assert interpolate(t, y, "cubic", at=q).max() > 1.0  # the C2 spline does


@pytest.mark.parametrize("rule", ["none", "fixed", "velocity", "both", "literal"])
def test_hermite_dw_is_exact_for_uniform_acceleration(rule: str) -> None:
    """p = t² has a linear velocity: the window's line fit and the cubic Hermite are exact."""
    t = np.array([0.0, 0.4, 1.0, 1.3, 2.0, 2.2, 3.0])  # uneven spacing
    q = np.linspace(0, 3, 31)
    got = interpolate(t, t**2, "hermite-dw", at=q, velocities=2 * t,
                      window=WindowRule(rule=rule, w=2))
    np.testing.assert_allclose(got, q**2, atol=1e-12)


def test_hermite_uses_the_logged_velocity_not_the_positions() -> None:
    """Same knots, different logged velocities: different curves (Akima cannot know)."""
    t = np.array([0.0, 1.0])
    p = np.array([0.0, 0.0])
    up = interpolate(t, p, "hermite-dw", at=[0.5], velocities=np.array([1.0, 1.0]),
                     window=WindowRule(rule="none"))
    # cubic Hermite, p0 = p1 = 0: h10(0.5)·m0 + h11(0.5)·m1 = 0.125·m0 - 0.125·m1
    assert up[0] == pytest.approx(0.0)
    bump = interpolate(t, p, "hermite-dw", at=[0.5], velocities=np.array([1.0, -1.0]),
                       window=WindowRule(rule="none"))
    assert bump[0] == pytest.approx(0.25)


def test_every_method_returns_the_samples_at_the_sample_times() -> None:
    t = np.array([0.0, 0.1, 0.25, 0.3, 0.5, 0.61, 0.7])
    y = np.stack([np.sin(7 * t), np.cos(3 * t), t**2], axis=1) * 123.456789
    for m in INTERP_METHODS:
        got = interpolate(t, y, m, at=t, velocities=np.gradient(y, t, axis=0))
        assert np.array_equal(got, y), m  # bit for bit


def test_window_sizes_hand_computed() -> None:
    """One velocity step of 5 m/s at sample 4 of 8: ‖δ‖₂ = 5/√8, m_v = √8 near it."""
    v = np.array([0, 0, 0, 0, 5, 5, 5, 5], dtype=float)[:, None]
    ours = window_sizes(WindowRule(rule="velocity", w=2), v, None)
    # window max of ‖δ‖ is 5 for j = 2..6 -> W = 2/√8 = 0.71 -> 1; elsewhere m_v = 0 -> w
    assert ours.tolist() == [2, 2, 1, 1, 1, 1, 1, 2]
    lit = window_sizes(WindowRule(rule="literal", w=2), v, None)
    assert lit.tolist() == [0, 0, 2, 2, 2, 2, 2, 0]  # literally: wide at the step
    assert window_sizes(WindowRule(rule="fixed", w=2), v, None).tolist() == [2] * 8
    assert window_sizes(WindowRule(rule="none", w=2), v, None).tolist() == [0] * 8
    att = np.zeros((8, 3))
    att[5, 2] = math.pi / 2  # a 90° yaw change at sample 5: m_θ = 1.5 for j = 3..7 (w=2)
    a = window_sizes(WindowRule(rule="attitude", w=2), v, att)
    assert a.tolist() == [2, 2, 2, 1, 1, 1, 1, 1]  # 2 / 1.5 = 1.33 -> 1
    both = window_sizes(WindowRule(rule="both", w=2, omega=0.5), v, att)
    # j=2: 2/(0.5·√8·1) = 1.41 -> 1; j=3..6: 2/(0.5·√8·1.5) = 0.94 -> 1; j=7: m_v = 0 -> 2
    assert both.tolist() == [2, 2, 1, 1, 1, 1, 1, 2]


def test_slerp_takes_the_short_way_round() -> None:
    t = np.array([0.0, 1.0])
    e = np.array([[0.0, 0.0, math.radians(170)], [0.0, 0.0, math.radians(-170)]])
    mid = slerp_attitude(t, e, [0.5])[0]
    assert abs(abs(mid[2]) - math.pi) < 1e-12 and abs(mid[0]) < 1e-12
    q = slerp_attitude(t, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), [0.25])[0]
    assert q[2] == pytest.approx(0.25)


@pytest.mark.parametrize(
    ("times", "method", "needle"),
    [
        ([0.0, 1.0, 2.0], "cubic", "cubic needs at least 4 samples, got 3"),
        ([0.0, 1.0, 2.0, 3.0], "akima", "akima needs at least 5"),
        ([0.0, 1.0, 1.0, 3.0, 4.0], "linear", "t[2] = 1.0 after t[1] = 1.0"),
        ([0.0, 2.0, 1.0, 3.0, 4.0], "hermite-dw", "increase strictly"),
        ([0.0, 1.0, math.nan], "linear", "finite"),
    ],
)
def test_bad_trajectories_are_refused(times: list[float], method: str, needle: str) -> None:
    t = np.asarray(times)
    with pytest.raises(ValueError, match=re.escape(needle)):
        interpolate(t, np.zeros((t.size, 3)), method, at=[0.5])


def test_unknown_method_and_window_values() -> None:
    with pytest.raises(ValueError, match="unknown method 'spline'"):
        interpolate([0.0, 1.0], [0.0, 1.0], "spline")
    with pytest.raises(ValueError, match="rule"):
        WindowRule(rule="wide")
    with pytest.raises(ValueError, match="omega"):
        WindowRule(omega=0.0)


def test_slerp_segments_equals_slerp_per_trajectory() -> None:
    from sigma_des.replay.interpolate import slerp_segments

    t1, t2 = np.array([0.0, 0.5, 1.0]), np.array([0.2, 0.4, 0.9, 1.3])
    e1 = np.array([[0.0, 0.1, 0.2], [0.3, -0.2, 2.5], [0.1, 0.0, -3.0]])
    e2 = np.array([[0.2, 0.0, 0.0], [0.0, 0.4, 1.0], [-0.3, 0.1, 1.5], [0.0, 0.0, 3.1]])
    q1, q2 = np.linspace(0, 1, 11), np.array([0.2, 0.5, 0.9, 1.1, 1.3])
    got = slerp_segments(np.r_[t1, t2], np.r_[e1, e2], np.array([0, 3, 7]), np.r_[q1, q2],
                         np.r_[np.zeros(11, int), np.ones(5, int)])
    want = np.r_[slerp_attitude(t1, e1, q1), slerp_attitude(t2, e2, q2)]
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert np.array_equal(got[-1], e2[-1]) and np.array_equal(got[11], e2[0])


def test_slerp_segments_matches_scipy_on_random_attitudes() -> None:
    from sigma_des.replay.interpolate import slerp_segments

    rng = np.random.default_rng(3)  # local generator: test data only
    t = np.cumsum(rng.uniform(0.05, 0.5, 40))
    e = np.stack([rng.uniform(-1, 1, 40), rng.uniform(-1.2, 1.2, 40),
                  rng.uniform(-math.pi, math.pi, 40)], axis=1)
    q = np.sort(rng.uniform(t[0], t[-1], 300))
    got = slerp_segments(t, e, np.array([0, 40]), q, np.zeros(300, dtype=np.intp))
    np.testing.assert_allclose(got, slerp_attitude(t, e, q), atol=1e-9)
