"""A rollback whose re-simulation would change no bit skips its physics, and gives the same bits.

The truth tracks the command row each node's frames were stepped with and since which
frame (:mod:`sigma_des.events.held`); a rollback re-stepping frames with that very row
from the same checkpoint is skipped. The results must be those of re-simulating anyway.
"""

from __future__ import annotations

import numpy as np

from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.events.held import NEVER, HeldCommands
from sigma_des.events.truth import SwarmTruth

N, H = 5, 16


def test_held_commands_by_hand() -> None:
    held = HeldCommands(3, 2)
    assert (held.since == NEVER).all()
    cmd = np.array([[1.0, 2.0], [3.0, np.nan], [0.0, 5.0]])
    held.stepped(0, cmd)
    assert held.since.tolist() == [0, 0, 0]
    cmd2 = cmd.copy()
    cmd2[1, 0] = 4.0
    held.stepped(1, cmd2)
    held.stepped(2, cmd2)
    assert held.since.tolist() == [0, 1, 0]
    nodes, first = np.array([0, 1, 1, 2]), np.array([0, 0, 1, 1])
    rows = np.array([[1.0, 2.0], [4.0, np.nan], [4.0, np.nan], [-0.0, 5.0]])
    # node 1 held (4, NaN) only since frame 1; -0.0 is not 0.0 by its bits
    assert held.redundant(nodes, first, rows).tolist() == [True, False, True, False]
    held.resimulated(np.array([2]), np.array([1]), rows[3:])
    assert held.since.tolist() == [0, 1, 1]
    assert held.redundant(np.array([2, 2]), np.array([1, 0]), rows[[3, 3]]).tolist() == [
        True, False]


def _truths() -> tuple[SwarmTruth, SwarmTruth, np.ndarray]:
    """Two truths stepped alike to frame 11 (node 1's command changes at frame 6); the
    second never skips (its tracking off: what re-simulating every rollback gives)."""
    dyn = GeneralAircraft("quadrotor", seed=2)
    a = SwarmTruth(dyn, N, H, 10.0, True)
    b = SwarmTruth(dyn, N, H, 10.0, True)
    b.stepped_rows = None
    cmd = dyn.default_command(a.state)
    cmd[:, 0] = 3.0
    for k in range(12):
        if k == 6:
            cmd = cmd.copy()
            cmd[1, 1] += 0.5
        for t in (a, b):
            t.step_frame(k, 0.01 + 0.002 * (k % 2), cmd, None)
    return a, b, cmd


def _same(a: SwarmTruth, b: SwarmTruth) -> None:
    np.testing.assert_array_equal(a.ckpt[: a.latest + 1], b.ckpt[: b.latest + 1])  # written
    np.testing.assert_array_equal(a.obs_hist[: a.latest + 1], b.obs_hist[: b.latest + 1])
    np.testing.assert_array_equal(a.state, b.state)
    assert (a.rollbacks, a.resim_steps) == (b.rollbacks, b.resim_steps)


def test_rollbacks_skipped_exactly_when_nothing_would_change() -> None:
    a, b, cmd = _truths()
    before = a.ckpt.copy()
    turned = cmd[2].copy()
    turned[1] += 1.0
    # (node, c, row, skipped?): node 0 held its row throughout; node 1 only since 6;
    # node 2 with a new row, then that row again from a later frame, then an earlier one
    cases = [(0, 3, cmd[0], True), (1, 3, cmd[1], False), (1, 7, cmd[1], True),
             (2, 4, turned, False), (2, 8, turned, True), (2, 2, turned, False)]
    for i, c, row, skipped in cases:
        was = a.resim_skipped
        assert a.rollback(i, c, 11, row) == b.rollback(i, c, 11, row) == 12 - c
        assert a.resim_skipped - was == int(skipped)
        _same(a, b)
    assert a.resim_skipped == 3
    assert not np.array_equal(a.ckpt[3:12, 1], before[3:12, 1])  # re-simulations did change


def test_deferred_rollbacks_skip_the_same_ones() -> None:
    a, b, cmd = _truths()
    turned = cmd[3].copy()
    turned[2] += 4.0
    nodes = np.array([3, 0, 1], dtype=np.int64)
    first = np.array([5, 2, 4], dtype=np.int64)
    rows = np.array([turned, cmd[0], cmd[1]])
    steps = np.array([7, 10, 8], dtype=np.int64)
    got = a.flush_rollbacks(nodes, first, rows, steps)
    assert got.tolist() == [0, 1, 3]  # every node rolled back, by first frame
    assert a.resim_skipped == 1  # node 0 only: node 1's frames 4, 5 held its old row
    for i, c, row in zip(nodes, first, rows, strict=True):
        b.rollback(int(i), int(c), int(c) + int(steps[list(nodes).index(i)]) - 1, row)
    _same(a, b)
    # a second flush of the same rows: now every one is redundant
    a.flush_rollbacks(nodes, first, rows, steps)
    assert a.resim_skipped == 4
    for i, c, row in zip(nodes, first, rows, strict=True):
        b.rollback(int(i), int(c), int(c) + int(steps[list(nodes).index(i)]) - 1, row)
    _same(a, b)
