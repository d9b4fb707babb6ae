"""Swarm fidelity: trajectory logging, formation error and DTW against an ideal run."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.metrics.fidelity import TrajectoryLog, fidelity


def test_log_interpolates_at_exact_sample_times() -> None:
    log = TrajectoryLog(10.0, np.zeros((1, 3)))
    # frames every 0.04 s moving 1 m per frame along x
    for k in range(1, 6):
        log.add(0.04 * k, np.array([[float(k), 0.0, 0.0]]))
    t, pos = log.arrays()
    assert t.tolist() == pytest.approx([0.0, 0.1, 0.2])
    # at 0.1 s the swarm is 2.5 frames along: 2.5 m
    assert pos[:, 0, 0].tolist() == pytest.approx([0.0, 2.5, 5.0])


def test_fidelity_is_zero_against_itself_and_ignores_a_common_shift() -> None:
    rng = np.random.default_rng(1)
    ideal = np.cumsum(rng.normal(size=(50, 4, 3)), axis=0)
    m, err = fidelity(ideal, ideal, 1 / 30, 10)
    assert m == {"formation_err_mean": 0.0, "formation_err_max": 0.0, "dtw_r": 0.0}
    shifted = ideal + np.array([5.0, -2.0, 1.0])
    m2, _ = fidelity(shifted, ideal, 1 / 30, 10)
    assert m2["formation_err_max"] == pytest.approx(0.0, abs=1e-12)
    assert m2["dtw_r"] > 0  # the trajectories themselves are displaced


def test_formation_error_of_one_displaced_node() -> None:
    ideal = np.zeros((20, 4, 3))
    run = ideal.copy()
    run[:, 0, 0] = 4.0  # node 0 is 4 m off; the centroid moves 1 m
    m, err = fidelity(run, ideal, 1 / 30, 10)
    # offsets from centroid: node 0 is 3 m off, the three others 1 m each -> mean 1.5 m
    assert m["formation_err_mean"] == pytest.approx(1.5)
    assert np.allclose(err, 1.5)
    # DTW per node / samples: node 0 deviates 4 m at every one of 20 samples -> D = 80;
    # r = D * T / s with s = 19 periods -> 80/19, averaged over 4 nodes
    assert m["dtw_r"] == pytest.approx(80 / 19 / 4)


def test_default_comparison_flies_6dof_with_fidelity_columns() -> None:
    from sigma_des import Scenario, compare, load

    assert Scenario().dynamics == "quadrotor"
    assert Scenario().commands.behaviour == "formation"
    sc = load(None, ["nodes=6", "hosts=2", "duration=1.0", "warmup=0.2"])
    res = compare(sc, ["none", "bides"], progress=False)
    for m in ("none", "bides"):
        assert np.isfinite(res.metric(m, "formation_err_mean"))
        assert res.metric(m, "dtw_r") >= 0
        assert len(res.fidelity[m]["formation_err"]) > 20
    assert "DTW r" in res.table()


def test_fidelity_read_by_blocks_is_the_fidelity_of_the_arrays() -> None:
    """The log's rows (spilled to a file) and any Rows reader give the very bits of the
    whole arrays, over several formation-error blocks and unequal lengths."""
    from sigma_des.metrics.fidelity import BLOCK, TrajectoryLog
    from sigma_des.metrics.samples import Samples

    rng = np.random.default_rng(5)
    n, t = 7, 2 * BLOCK + 37
    ideal = np.cumsum(rng.normal(size=(t + 5, n, 3)), axis=0)
    log = TrajectoryLog(10.0, ideal[0] + rng.normal(size=(n, 3)))
    log.pos = Samples(spill=64)  # spill early: the rows come back from the file
    log.pos.extend(ideal[0] + 0.5)
    for j in range(1, t):
        log.add(j / 10.0, ideal[j] + rng.normal(scale=0.3, size=(n, 3)))
    times, pos = log.arrays()
    assert log.pos.spilled and log.rows().shape == pos.shape

    class Reader:  # another Rows: what a file reader hands out
        shape = ideal.shape

        def __len__(self) -> int:
            return len(ideal)

        def __getitem__(self, rows: slice) -> np.ndarray:
            return ideal[rows].copy()

    whole, err = fidelity(pos, ideal, 0.1, 4)
    for p, q in ((log.rows(), ideal), (pos, Reader()), (log.rows(), Reader())):
        got, err2 = fidelity(p, q, 0.1, 4)
        assert got == whole and err2.tobytes() == err.tobytes()
    assert len(err) == len(pos)
