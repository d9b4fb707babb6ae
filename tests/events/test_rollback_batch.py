"""Batched time-warp rollbacks and block-fetched rollback draws equal the one-by-one spec, exactly.

The compiled core defers a rollback's physics re-simulation
(:meth:`SwarmTruth.defer_rollback`) and re-simulates every pending aircraft in one
step call per frame (:meth:`SwarmTruth.flush_rollbacks`); its job starts read a
target's rollback draws as one block (:class:`JobCosts`). Both must give the bits
of the per-message engine's one-by-one path (:meth:`SwarmTruth.rollback`,
:func:`job_cost`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import sigma_des.events.fast.driver as driver
from sigma_des import load
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.pointmass import PointMass
from sigma_des.core.draws import DrawCache
from sigma_des.events.fast import layout as L
from sigma_des.events.jobs import JobCosts, job_cost
from sigma_des.events.truth import SwarmTruth
from tests.events.test_cohort import run_both

N, H = 6, 8


def _truth(dyn: Any, frames: int) -> SwarmTruth:
    """A truth of ``N`` aircraft stepped to ``frames - 1`` under varied commands."""
    truth = SwarmTruth(dyn, N, H, 10.0, True)
    rng = np.random.default_rng(7)
    cmd = dyn.default_command(truth.state)
    for k in range(frames):
        cmd = cmd + rng.normal(0.0, 0.5, cmd.shape)
        truth.step_frame(k, 0.01 + 0.001 * (k % 3), cmd, None)
    return truth


def _same_truth(a: SwarmTruth, b: SwarmTruth) -> None:
    np.testing.assert_array_equal(a.slot_frame, b.slot_frame)
    held = a.slot_frame >= 0  # the checkpoints and rows of slots never written are undefined
    np.testing.assert_array_equal(a.ckpt[held], b.ckpt[held])
    np.testing.assert_array_equal(a.obs_hist[held], b.obs_hist[held])
    np.testing.assert_array_equal(a.state, b.state)
    assert (a.rollbacks, a.resim_steps) == (b.rollbacks, b.resim_steps)


# (node, c, current): clamped to the ring, from frame 0, a second rollback of node 1
# (flushes the first), nothing to re-simulate (c > latest), different first frames
ROLLBACKS = [(0, 5, 11), (1, 9, 12), (2, 0, 3), (1, 10, 12), (3, 13, 13), (4, 11, 12),
             (5, 7, 7)]


@pytest.mark.parametrize("frames", [4, 13])
def test_batched_rollbacks_equal_one_by_one_rollbacks(frames: int) -> None:
    dyn = GeneralAircraft("quadrotor")
    one, batch = _truth(dyn, frames), _truth(dyn, frames)
    assert batch.batched
    rows = np.random.default_rng(3).normal(0.0, 1.0, (len(ROLLBACKS), 4))
    for (i, c, current), row in zip(ROLLBACKS, rows, strict=True):
        assert batch.defer_rollback(i, c, current, row) == one.rollback(i, c, current, row)
    assert batch.pending  # the re-simulation is still owed ...
    assert not np.array_equal(batch.state, one.state)
    done = batch.flush_rollbacks()
    assert not batch.pending and not any(batch.owes(i) for i in range(N))
    # ... the flush re-simulates the nodes pending since node 1's second rollback (13
    # frames), or the one whose c is not past the latest frame (4 frames)
    assert sorted(done.tolist()) == ([1, 4, 5] if frames == 13 else [2])
    _same_truth(batch, one)
    assert batch.flush_rollbacks().size == 0


def test_owed_steps_are_arithmetic() -> None:
    truth = _truth(GeneralAircraft("quadrotor"), 13)  # latest 12, oldest re-simulable 6
    row = np.zeros(4)
    assert truth.defer_rollback(0, 2, 11, row) == 11 - 6 + 1  # clamped to the ring
    assert truth.owes(0) and not truth.owes(1)
    assert truth.defer_rollback(1, 10, 8, row) == 0  # the node is behind c
    assert (truth.rollbacks, truth.resim_steps) == (2, 6)


def test_models_without_step_frames_roll_back_at_once() -> None:
    truth = _truth(PointMass(), 13)
    assert not truth.batched
    ref = _truth(PointMass(), 13)
    row = np.array([1.0, 0.5, 2.0])
    assert truth.defer_rollback(2, 8, 12, row) == ref.rollback(2, 8, 12, row) == 5
    assert not truth.pending
    _same_truth(truth, ref)


def _draws(constant: float | None = None) -> DrawCache:
    def sampler(s: Any, kind: int, index: int, attempt: int) -> Any:
        return np.sin(1.0 + s * 0.37 + kind * 11.3 + index * 0.013 + attempt * 2.9) ** 2 * 1e-3

    return DrawCache(N, sampler, limit=4, constant=constant)


def test_job_costs_equal_job_cost_exactly() -> None:
    costs = JobCosts(_draws(), targets=2)
    ref = _draws()
    slow = [(0.5, 1.0, 3.0), (0.8, 2.0, 1.5)]
    cases = [(i, first, target, resim, now)
             for i in range(N) for first, target in ((3, 3), (2, 5), (6, 5))
             for resim in (0, 1, 7, 19) for now in (0.2, 0.9)]
    cases += [(1, 9, 9, 3, 0.0), (2, 10, 10, 40, 0.0), (0, 9, 9, 30, 0.85)]  # growth, eviction
    for i, first, target, resim, now in cases:
        want = job_cost(ref, slow, i, first, target, resim, now)
        assert costs.cost(slow, i, first, target, resim, now) == want
    const = JobCosts(_draws(0.002))
    assert const.cost([], 0, 1, 3, 5, 0.0) == job_cost(_draws(0.002), [], 0, 1, 3, 5, 0.0)


def test_rolled_back_node_publishes_only_after_its_resimulation(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The loop stops before a pending node's publish (NEED_RESIM); results are the spec's."""
    codes: list[int] = []
    advance = driver.loop.advance

    def counting(S: Any, bound: float, strict: bool) -> int:
        code = int(advance(S, bound, strict))
        codes.append(code)
        return code

    monkeypatch.setattr(driver.loop, "advance", counting)
    sc = load(None, [
        "nodes=40", "hosts=4", "duration=1.0", "warmup=0.3", "fidelity.enabled=false",
        "broker.publish_service=0.0001", "broker.delivery_service=0.00008",
        "bides.theta_warp=1", "bides.hold_down=1",
    ])
    ev, co = run_both(sc, "bides")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["rollbacks"] > 0
    assert L.NEED_ROLLBACK in codes and L.NEED_RESIM in codes
