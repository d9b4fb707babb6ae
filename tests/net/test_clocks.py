"""Node clocks: offset, drift (ppm) and NTP resets, against the formulas by hand."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError
from sigma_des.net.clocks import ClockSpec, NodeClocks

S = Stream(11, "clocks")


def test_free_running_clock_formula() -> None:
    spec = ClockSpec(offset_std=0.002, drift_ppm_std=50.0)
    clocks = NodeClocks(spec, S, 4)
    for i in range(4):
        off = 0.002 * S.normal(i, 0)[0]
        ppm = 50.0 * S.normal(i, 1)[0]
        assert clocks.offset[i] == off and clocks.drift_ppm[i] == ppm
        for t in (0.0, 1.5, 1000.0):
            assert clocks.local_time(i, t) == t + off + ppm * 1e-6 * t
    # drift alone: after 1000 s the error is ppm * 1e-3 s
    drift_only = NodeClocks(ClockSpec(drift_ppm_std=50.0), S, 4)
    assert drift_only.error(2, 1000.0) == pytest.approx(drift_only.drift_ppm[2] * 1e-3, rel=1e-9)


def test_ntp_resets_error_to_residual() -> None:
    spec = ClockSpec(offset_std=0.01, drift_ppm_std=20.0, ntp_period=10.0, ntp_residual_std=1e-4)
    clocks = NodeClocks(spec, S, 3)
    i = 1
    off, ppm = clocks.offset[i], clocks.drift_ppm[i]
    assert clocks.local_time(i, 5.0) == 5.0 + off + ppm * 1e-6 * 5.0  # before first sync
    e2 = 1e-4 * S.normal(i, 2, 2)[0]
    assert clocks.local_time(i, 25.0) == 25.0 + e2 + ppm * 1e-6 * (25.0 - 20.0)
    e1 = 1e-4 * S.normal(i, 2, 1)[0]
    assert clocks.local_time(i, 10.0) == 10.0 + e1  # exactly at the sync instant
    assert clocks.local_time(i, 9.999) == 9.999 + off + ppm * 1e-6 * 9.999  # just before


def test_sync_index_is_exact_at_instants() -> None:
    clocks = NodeClocks(ClockSpec(ntp_period=0.1), S, 1)
    t = np.array([0.0, 0.0999, 0.1, 0.3, 3 * 0.1, 0.45])
    # 0.3 < 3 * 0.1 == 0.30000000000000004 in floating point
    np.testing.assert_array_equal(clocks.sync_index(t), [0, 0, 1, 2, 3, 4])


def test_vectorised_matches_scalar_and_shapes() -> None:
    spec = ClockSpec(offset_std=0.001, drift_ppm_std=10.0, ntp_period=1.0, ntp_residual_std=1e-5)
    clocks = NodeClocks(spec, S, 50)
    nodes = np.arange(50)
    t = np.linspace(0.0, 7.3, 50)
    arr = clocks.local_time(nodes, t)
    assert isinstance(arr, np.ndarray) and arr.shape == (50,)
    for i in (0, 13, 49):
        one = clocks.local_time(i, float(t[i]))
        assert isinstance(one, float) and one == arr[i]
    grid = clocks.local_time(nodes[:, None], np.array([0.5, 2.5]))
    assert grid.shape == (50, 2)


def test_draws_keyed_by_node_id() -> None:
    spec = ClockSpec(offset_std=0.003, drift_ppm_std=30.0)
    small, big = NodeClocks(spec, S, 5), NodeClocks(spec, S, 20_000)
    np.testing.assert_array_equal(small.offset, big.offset[:5])
    assert big.offset.std() == pytest.approx(0.003, rel=0.03)
    assert big.drift_ppm.std() == pytest.approx(30.0, rel=0.03)


def test_offsets_and_drifts_are_the_streams_normals_at_ids_0_and_1() -> None:
    """Both are drawn in one call (a row of nodes by a column of ids): each value is the
    stream's own normal at ``(node, 0)`` and ``(node, 1)`` times its std, bit for bit."""
    spec = ClockSpec(offset_std=0.003, drift_ppm_std=30.0)
    for n in (0, 1, 7):
        c = NodeClocks(spec, S, n)
        ids = np.arange(n, dtype=np.int64)
        assert c.offset.shape == c.drift_ppm.shape == (n,)
        assert c.offset.tobytes() == (0.003 * S.normal(ids, 0)).tobytes()
        assert c.drift_ppm.tobytes() == (30.0 * S.normal(ids, 1)).tobytes()
        for i in range(n):  # and one at a time
            assert c.offset[i] == 0.003 * S.normal(i, 0)[0]
    assert not np.array_equal(c.offset / 0.003, c.drift_ppm / 30.0)


def test_perfect_clocks() -> None:
    clocks = NodeClocks(ClockSpec(), S, 2)
    assert clocks.local_time(1, 12.5) == 12.5


def test_bad_node() -> None:
    with pytest.raises(IndexError):
        NodeClocks(ClockSpec(), S, 2).local_time(2, 0.0)
    with pytest.raises(IndexError):
        NodeClocks(ClockSpec(), S, 2).local_time(-1, 0.0)


def test_validation() -> None:
    for field in ("offset_std", "drift_ppm_std", "ntp_period", "ntp_residual_std"):
        with pytest.raises(ConfigError) as e:
            ClockSpec(**{field: -1})
        assert e.value.key == field and ">= 0" in e.value.reason
    spec = ClockSpec(ntp_period=60)
    assert isinstance(spec.ntp_period, float)
