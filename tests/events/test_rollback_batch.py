"""Batched time-warp rollbacks equal the one-by-one spec, exactly.

The compiled core defers a rollback's physics re-simulation (in its own arrays,
:mod:`sigma_des.events.fast.warp`) and the truth re-simulates every pending aircraft in
one step call per frame (:meth:`SwarmTruth.flush_rollbacks`). It must give the bits
of the per-message engine's one-by-one path (:meth:`SwarmTruth.rollback`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import sigma_des.events.fast.driver as driver
from sigma_des import load
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.pointmass import PointMass
from sigma_des.events.fast import codes as CO
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


# (node, c, current), one rollback per node: clamped to the ring, from frame 0, nothing
# owed (the node is behind c), different first frames (arrival order kept on ties)
ROLLBACKS = [(0, 5, 11), (1, 9, 12), (2, 0, 3), (3, 7, 6), (4, 11, 12), (5, 7, 7)]


def _deferred(truth: SwarmTruth, cases: list[tuple[int, int, int]], rows: Any) -> tuple[Any, ...]:
    """The compiled core's deferral of ``cases`` (sigma_des.events.fast.warp), as arrays."""
    nodes = np.array([i for i, _c, _cur in cases], dtype=np.int64)
    first = np.array([truth.first_resim(c) for _i, c, _cur in cases], dtype=np.int64)
    steps = np.array([max(0, cur - f + 1) for (_i, _c, cur), f in zip(cases, first, strict=True)],
                     dtype=np.int64)
    return nodes, first, np.asarray(rows, dtype=np.float64), steps


def test_batched_rollbacks_equal_one_by_one_rollbacks() -> None:
    dyn = GeneralAircraft("quadrotor")
    one, batch = _truth(dyn, 13), _truth(dyn, 13)  # latest 12, oldest re-simulable 6
    assert batch.batched
    rows = np.random.default_rng(3).normal(0.0, 1.0, (len(ROLLBACKS), 4))
    nodes, first, rows_, steps = _deferred(batch, ROLLBACKS, rows)
    assert first.tolist() == [6, 9, 6, 7, 11, 7] and steps.tolist() == [6, 4, 0, 0, 2, 1]
    for (i, c, current), row, owed in zip(ROLLBACKS, rows, steps, strict=True):
        assert one.rollback(i, c, current, row) == owed
    assert not np.array_equal(batch.state, one.state)  # the re-simulation is still owed
    done = batch.flush_rollbacks(nodes, first, rows_, steps)
    assert done.tolist() == [0, 2, 3, 5, 1, 4]  # by first frame, arrival order on ties
    _same_truth(batch, one)
    assert batch.flush_rollbacks(nodes[:0], first[:0], rows_[:0], steps[:0]).size == 0


def test_batched_rollbacks_from_frame_zero_start_at_the_initial_state() -> None:
    # a young ring (latest 4): rollbacks from frame 0 (the initial state), 1 and 4
    dyn = GeneralAircraft("quadrotor")
    one, batch = _truth(dyn, 5), _truth(dyn, 5)
    cases = [(3, 0, 4), (0, 1, 4), (5, 4, 4), (1, 0, 2)]
    rows = np.random.default_rng(5).normal(0.0, 1.0, (len(cases), 4))
    nodes, first, rows_, steps = _deferred(batch, cases, rows)
    assert first.tolist() == [0, 1, 4, 0]
    for (i, c, current), row in zip(cases, rows, strict=True):
        one.rollback(i, c, current, row)
    assert batch.flush_rollbacks(nodes, first, rows_, steps).tolist() == [3, 1, 0, 5]
    _same_truth(batch, one)


def test_first_frames_clamp_to_the_ring() -> None:
    truth = _truth(GeneralAircraft("quadrotor"), 13)  # latest 12, oldest re-simulable 6
    assert [truth.first_resim(c) for c in (0, 5, 6, 7, 14)] == [6, 6, 6, 7, 14]
    young = _truth(GeneralAircraft("quadrotor"), 4)  # latest 3: the whole past is held
    assert [young.first_resim(c) for c in (0, 2)] == [0, 2]


@pytest.mark.parametrize("bad", ["twice", "past", "old"])
def test_a_flush_refuses_what_the_core_never_defers(bad: str) -> None:
    truth = _truth(GeneralAircraft("quadrotor"), 13)
    cases = {"twice": [(1, 7, 9), (1, 8, 9)], "past": [(1, 13, 13)], "old": [(1, 6, 9)]}[bad]
    nodes, first, rows, steps = _deferred(truth, cases, np.zeros((len(cases), 4)))
    if bad == "old":
        first[0] = 5  # not clamped
    with pytest.raises(ValueError, match="one per node"):
        truth.flush_rollbacks(nodes, first, rows, steps)
    assert truth.rollbacks == 0


def test_models_without_step_frames_roll_back_at_once() -> None:
    truth = _truth(PointMass(), 13)
    assert not truth.batched
    ref = _truth(PointMass(), 13)
    row = np.array([1.0, 0.5, 2.0])
    assert truth.rollback(2, 8, 12, row) == ref.rollback(2, 8, 12, row) == 5
    _same_truth(truth, ref)
    with pytest.raises(ValueError, match="batched dynamics"):
        truth.flush_rollbacks(*_deferred(truth, [(1, 8, 12)], row[None, :]))


def test_rolled_back_node_publishes_only_after_its_resimulation(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The loop stops before a pending node's publish (NEED_RESIM); results are the spec's.
    Rollbacks are resolved in the loop: few return to Python (a second rollback of a node
    still owed its re-simulation, a target's first rollback job: its draws)."""
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
    rollbacks = ev["metrics"]["rollbacks"]
    assert rollbacks > 0
    assert CO.NEED_RESIM in codes
    assert codes.count(CO.NEED_ROLLBACK) + codes.count(CO.NEED_START) < rollbacks / 4
