"""Time-warp rollbacks and their job starts resolved inside the compiled loop.

A rollback the loop meets is deferred in the core's own arrays (node, clamped first
frame, steps owed, the command row) and the job it starts sums its rollback draws from a
table Python fills once per target: the cost is :func:`job_cost`'s float, and the loop
returns to Python only for what needs it (a table row to fill, a second rollback of a
node still owed its re-simulation, dynamics without batched steps).
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any

import numpy as np
import pytest

from sigma_des.events.cohort import make_run
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast import loop
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.jobs import ROLLBACK_DRAW, job_cost
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.test_cohort import run_both

SLOW = [{"kind": "slow", "node": 1, "start": 0.0, "end": 1.0, "factor": 3.0}]
LATEST = 20


def _core(dynamics: str = "quadrotor", **over: Any) -> CompiledCore:
    sc = tiny(dynamics=dynamics, faults=SLOW, **{"bides.theta_warp": 2, **over})
    run, why = make_run(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    assert why == "" and isinstance(run.core, CompiledCore)
    core = run.core
    truth = core.host.truth
    for k in range(LATEST + 1):  # 21 frames issued, under the default command
        truth.step_frame(k, 0.01, core.host.nodes.cmd, None)
    S = core.S
    S[L.INTS][CO.I_LATEST] = truth.latest  # as advance_to hands it over
    nd = S[L.NODE]
    nd[CO.N_FRAME, 1], nd[CO.N_REQ, 1] = 9, 12  # node 1: computed frame 9, asked for 12
    S[L.CMD][1] = 0.1 * (1.0 + np.arange(S[L.CMD].shape[1]))  # its newest command row
    for k in range(10, 13):
        core.tables.fill(0, k)  # the step draws of frames 10..12 (compute: kind 0)
    return core


@pytest.mark.parametrize("step", [0.002, {"dist": "lognormal", "mean": 0.003, "std": 0.002}])
def test_a_rollback_is_deferred_and_its_job_costed_in_the_loop(step: Any) -> None:
    core = _core(**{"compute.step_time": step, "compute.host_share": 0.5})
    S = core.S
    iv, nd = S[L.INTS], S[L.NODE]
    loop.roll_back(S, 1, 4, 9, 0.5)  # a command stamped 4 reached node 1 (at frame 9)
    # deferred: node 1 from frame 4 (the ring holds it), 9 - 4 + 1 = 6 steps owed
    assert iv[CO.I_DEFN] == 1 and S[L.DEF_INT][0].tolist() == [1, 4, 6]
    assert S[L.DEF_ROW][0].tolist() == S[L.CMD][1].tolist()  # a copy of the row
    assert S[L.RESIM_PEND].tolist() == [0, 1, 0, 1]
    # the idle node starts its job at once, but target 12's rollback draws are not in
    # the table yet: Python fills them (NEED_START), then the loop starts the job
    assert (iv[CO.I_PEND], iv[CO.I_PNODE], S[L.FLOATS][CO.F_PT]) == (CO.NEED_START, 1, 0.5)
    assert nd[CO.N_RB, 1] == 6 and not nd[CO.N_BUSY, 1]
    iv[CO.I_PEND] = 0
    S = core.rollbacks.fill(S, 12, 6)
    assert S[L.RB_TAG][12 % 8].tolist() == [12, 6]
    step_time = core.host.nodes.step_time
    for j in range(6):
        assert S[L.RB_VAL][12 % 8, j].tolist() == step_time.vector(ROLLBACK_DRAW, 12, j).tolist()
    loop.start(S, 1, 0.5)
    assert iv[CO.I_PEND] == 0 and nd[CO.N_RB, 1] == 0
    assert (nd[CO.N_BUSY, 1], nd[CO.N_TARGET, 1]) == (1, 12)
    cost = job_cost(step_time, [(0.0, 1.0, 3.0)], 1, 10, 12, 6, 0.5)
    if step == 0.002:  # 3 frames + 6 re-simulated steps of 2 ms, slowed 3x
        hand = 0.0
        for _ in range(9):
            hand += 0.002
        assert cost == hand * 3.0 == pytest.approx(0.054, abs=1e-15)
    # the job took the host's first free core: it ends at 0.5 + cost, bit for bit
    assert S[L.CORES][S[L.HOST_OF][1]].max() == 0.5 + cost
    # the flush re-simulates node 1 from frame 4 as the truth's one-by-one rollback does,
    # counts the rollback and its steps, and unmarks the node
    truth = core.host.truth
    ref = deepcopy(truth)
    assert ref.rollback(1, 4, 9, S[L.CMD][1]) == 6
    assert not np.array_equal(truth.state[1], ref.state[1])  # owed until the flush
    core.S = S
    core.flush_rollbacks()
    assert (truth.rollbacks, truth.resim_steps) == (ref.rollbacks, ref.resim_steps) == (1, 6)
    assert iv[CO.I_DEFN] == 0 and S[L.RESIM_PEND].tolist() == [0, 0, 0, 0]
    np.testing.assert_array_equal(truth.obs_hist[: LATEST + 1], ref.obs_hist[: LATEST + 1])
    np.testing.assert_array_equal(truth.ckpt[: LATEST + 1], ref.ckpt[: LATEST + 1])
    np.testing.assert_array_equal(truth.state, ref.state)


def test_python_gets_a_second_rollback_and_one_past_the_newest_frame() -> None:
    core = _core()
    S = core.S
    iv = S[L.INTS]
    loop.roll_back(S, 1, 4, 9, 0.5)
    iv[CO.I_PEND] = 0
    loop.roll_back(S, 1, 5, 12, 0.6)  # node 1 is still owed its re-simulation
    assert (iv[CO.I_PEND], iv[CO.I_PNODE], iv[CO.I_PA], iv[CO.I_PB]) == (CO.NEED_ROLLBACK, 1, 5, 12)
    iv[CO.I_PEND] = 0
    loop.roll_back(S, 2, LATEST + 1, LATEST + 4, 0.6)  # nothing to re-simulate yet
    assert (iv[CO.I_PEND], iv[CO.I_PNODE]) == (CO.NEED_ROLLBACK, 2)
    assert iv[CO.I_DEFN] == 1 and S[L.NODE][CO.N_RB].tolist() == [0, 6, 0]  # neither deferred


def test_dynamics_without_batched_steps_roll_back_in_python() -> None:
    core = _core("pointmass")
    S = core.S
    loop.roll_back(S, 1, 4, 9, 0.5)
    assert S[L.INTS][CO.I_PEND] == CO.NEED_ROLLBACK and S[L.INTS][CO.I_DEFN] == 0


LOGNORMAL = {"dist": "lognormal", "mean": 0.003, "std": 0.002}


def _held(S: Any) -> dict[int, list[int]]:
    """The table's rows that hold a target: ``{row: [target, draws]}``."""
    tag = S[L.RB_TAG]
    return {r: tag[r].tolist() for r in range(tag.shape[0]) if tag[r, CO.RB_TARGET] != -1}


def _assert_keyed(core: CompiledCore, S: Any) -> None:
    """Every draw a row holds is the rollback draw of its key (``job_cost``'s value)."""
    step_time = core.host.nodes.step_time
    for r, (target, count) in _held(S).items():
        for j in range(count):
            want = step_time.vector(ROLLBACK_DRAW, target, j)
            assert S[L.RB_VAL][r, j].tolist() == want.tolist()


def test_the_table_refills_a_row_for_a_new_target_and_grows() -> None:
    core = _core(**{"compute.step_time": LOGNORMAL})
    rows = core.frame_draws.rows  # blockable draws: a target row per frame of a block
    assert rows == 64
    # no frame block drawn yet: the new target alone, with the table's 8 draws (twice
    # the Θ_warp + 2 = 4 a rollback owes at least)
    S = core.rollbacks.fill(core.S, 12, 3)
    assert _held(S) == {12: [12, 8]} and S[L.RB_VAL].shape == (64, 8, 3)
    assert core.rollbacks.fill(S, 12, 8) is S  # held already
    S = core.rollbacks.fill(S, 12, 9)  # more: twice what the row held, 16, past its 8 rows
    assert _held(S) == {12: [12, 16]} and S[L.RB_VAL].shape == (64, 16, 3)
    S = core.rollbacks.fill(S, 12 + 64, 2)  # the same row, another target: 16 draws
    assert _held(S) == {12: [76, 16]}
    _assert_keyed(core, S)


def test_a_new_target_draws_the_targets_of_the_frame_block_ahead() -> None:
    """A new target's fill also fills the rows of the targets after it up to the end of
    the frame draws' block, with the draws a fill on demand writes."""
    core = _core(**{"compute.step_time": LOGNORMAL})
    core.frame_draws.fill(10)  # the block of frames 10..73
    assert core.frame_draws.end == 74
    S = core.rollbacks.fill(core.S, 12, 3)
    assert _held(S) == {k % 64: [k, 8] for k in range(12, 74)}
    _assert_keyed(core, S)
    assert core.rollbacks.fill(S, 40, 4) is S  # drawn ahead: no return for its job
    # an older target: 64 targets from it (one per row: 73's row now holds 9)
    S = core.rollbacks.fill(S, 9, 2)
    assert _held(S) == {k % 64: [k, 8] for k in range(9, 73)}
    _assert_keyed(core, S)
    # on demand only (no block ahead): every row it fills holds the same draws
    alone = _core(**{"compute.step_time": LOGNORMAL})
    T = alone.rollbacks.fill(alone.S, 40, 4)
    assert _held(T) == {40: [40, 8]}
    np.testing.assert_array_equal(T[L.RB_VAL][40], S[L.RB_VAL][40])
    # a deep need: the table grows, and the draws ahead stop at BLOCK_VALUES values
    deep = _core(**{"compute.step_time": LOGNORMAL})
    deep.frame_draws.fill(10)
    S = deep.rollbacks.fill(deep.S, 12, 30)  # 30 draws x 3 nodes: 4096 // 90 = 45 targets
    assert _held(S) == {k % 64: [k, 30] for k in range(12, 12 + 45)}
    _assert_keyed(deep, S)


def test_a_grid_of_draws_is_the_vectors_of_its_keys() -> None:
    core = _core(**{"compute.step_time": LOGNORMAL})
    step_time = core.host.nodes.step_time
    assert step_time.uniforms is not None  # the one-call path
    got = step_time.grid(ROLLBACK_DRAW, np.array([5, 7, 1000]), np.arange(3))
    assert got.shape == (3, 3, 3)
    for r, k in enumerate((5, 7, 1000)):
        for j in range(3):
            assert got[r, j].tolist() == step_time.vector(ROLLBACK_DRAW, k, j).tolist()


def test_rollbacks_return_to_python_rarely() -> None:
    """A run with many rollbacks: the loop returned for a few of them only (before, each
    rollback was at least one return, its job start often a second)."""
    sc = tiny(**{"nodes": 40, "hosts": 4, "dynamics": "quadrotor", "duration": 1.0,
                 "warmup": 0.3, "fidelity.enabled": False, "commands.enabled": True,
                 "commands.every": 1, "net.server_link.latency": 0.02,
                 "bides.theta_warp": 1})
    run, why = make_run(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc))
    assert why == ""
    m = run.run()["metrics"]
    assert isinstance(run.core, CompiledCore)
    exits = run.core.exit_counts()
    assert m["rollbacks"] > 100
    assert exits["NEED_ROLLBACK"] + exits["NEED_START"] < m["rollbacks"] / 4
    assert exits["NEED_RESIM"] + exits["OK"] > 0


@pytest.mark.parametrize("share", [0.5, 0.0])  # 0: blockable draws, filled ahead
@pytest.mark.parametrize("dynamics", ["pointmass", "quadrotor"])
def test_runs_with_rollbacks_equal_the_specification(dynamics: str, share: float) -> None:
    """Both engines, late commands under a tight warp threshold, drawn step times (tied
    within a host, or independent: blockable, the rollback draws filled ahead), a slow
    fault: every metric identical (point mass: each rollback
    handed to Python, which re-simulates at once; quadrotor: deferred in the loop)."""
    sc = tiny(**{"nodes": 12, "hosts": 2, "dynamics": dynamics, "duration": 1.0,
                 "commands.enabled": True, "commands.behaviour": "follow",
                 "commands.every": 1, "net.host_link.latency": 0.03, "bides.theta_warp": 1,
                 "bides.hold_down": 1, "faults": SLOW, "compute.host_share": share,
                 "compute.step_time": {"dist": "lognormal", "mean": 0.003, "std": 0.002}})
    ev, co = run_both(sc, "bides")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["rollbacks"] > 10 and ev["metrics"]["resim_steps"] > 0
