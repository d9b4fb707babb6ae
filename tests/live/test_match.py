"""The hop-latency match's steps (sigma_des/live/match.py), by hand."""

from __future__ import annotations

import pytest

from sigma_des.live.match import K_MAX, K_MIN, _next_scale


def test_first_step_spreads_the_difference_over_two_hops() -> None:
    # DES 5 ms, live 4 ms, a hop of 1 ms on average: each hop 0.5 ms shorter -> k = 0.5
    assert _next_scale([(1.0, 5.0)], 4.0, 1e-3) == pytest.approx(0.5)
    assert _next_scale([(1.0, 5.0)], 1.0, 1e-3) == K_MIN  # never below the floor
    assert _next_scale([(1.0, 5.0)], 99.0, 1e-3) == K_MAX


def test_a_bracket_is_closed_by_the_secant_through_its_nearest_pairs() -> None:
    # pairs on both sides of live = 4: (0.5, 3) below, (1, 5) above -> 0.75
    assert _next_scale([(1.0, 5.0), (0.5, 3.0)], 4.0, 1e-3) == pytest.approx(0.75)
    # a farther pair on one side is not used: (0.2, 1) is below but (0.5, 3) is nearer
    assert _next_scale([(0.2, 1.0), (1.0, 5.0), (0.5, 3.0)], 4.0, 1e-3) == pytest.approx(0.75)


def test_without_a_bracket_the_last_two_pairs_extrapolate() -> None:
    # (1, 6) and (0.8, 5): 5 ms per unit of scale; live 4 -> 0.6
    assert _next_scale([(1.0, 6.0), (0.8, 5.0)], 4.0, 1e-3) == pytest.approx(0.6)
    # equal DES means: back to the two-hop step from the last pair
    assert _next_scale([(1.0, 5.0), (0.8, 5.0)], 4.0, 1e-3) == pytest.approx(0.3)
