"""Python's part of the compiled core's time-warp rollbacks (docs/concepts/engines.md).

The loop resolves a rollback and the job start it causes itself
(:mod:`~sigma_des.events.fast.warp`, :mod:`~sigma_des.events.fast.job`); Python keeps
what needs it:

* **the rollback draws**: a job owing ``rb`` re-simulated steps to ``target`` sums the
  draws ``(ROLLBACK_DRAW, node, target, j)``, ``j < rb``. They sit in a table of
  ``rb_t`` target rows (row ``target % rb_t``, tagged with its target and how many
  draws it holds), each draw ``j`` a vector over every node, sampled from the very
  :class:`~sigma_des.core.draws.DrawCache` the per-message engine reads (the
  ``host_share`` copula included), so the loop's sum is :func:`~sigma_des.events.jobs.job_cost`'s
  float. A row is filled on the loop's first ``NEED_START`` for its target (to twice the
  draws it held, at least what the job needs: few returns per target), and the table
  grows when a job owes more draws than its rows hold. A new target's fill also draws
  ahead the rows of the later targets up to the end of the frame draws' block (the
  frames already issued or about to be; at most :data:`~sigma_des.core.draws.BLOCK_VALUES`
  values, one sampler call): the jobs of the next rollbacks find their draws without a
  return. Draws are a pure function of their key, so a row drawn ahead holds what a fill
  on demand would write, and a row overwritten before its job starts costs a return;
* **the re-simulation** of the deferred rollbacks: :meth:`Rollbacks.flush` hands the
  loop's pending rows (``def_int``, ``def_row``, arrival order) to
  :meth:`~sigma_des.events.truth.SwarmTruth.flush_rollbacks` and unmarks their nodes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import BLOCK_VALUES, DrawCache
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.frame_draws import FrameDraws
from sigma_des.events.jobs import ROLLBACK_DRAW
from sigma_des.events.truth import SwarmTruth

__all__ = ["TARGETS", "Rollbacks"]

#: Target rows of the rollback-draw table (targets whose rollback jobs may be in
#: flight at once: consecutive trigger frames).
TARGETS = 8

State = tuple[NDArray[Any], ...]


class Rollbacks:
    """The rollback-draw table and the flush of deferred re-simulations of one run.

    Args:
        truth: the run's physics truth (it re-simulates the deferred rollbacks).
        step_time: the compute stream's draws (the per-message engine's cache).
        n: number of nodes.
        warp: BiDES time warp is on (else the table is one empty row).
        theta: the warp threshold Θ_warp (a rollback owes at least Θ_warp + 2 steps
            unless clamped to the ring: the table's first size is twice that).
        frames: the run's frame draws: a new target's fill draws ahead the targets up to
            the end of their block (the table then has a row for each of the block's
            frames, when the draws are blockable).
    """

    def __init__(self, truth: SwarmTruth, step_time: DrawCache, n: int, warp: bool,
                 theta: int, frames: FrameDraws | None = None) -> None:
        self.truth = truth
        self.step_time = step_time
        self.n = n
        # room for twice the least a rollback owes: a late state owes more (Θ_warp = 10
        # and 200 ms links: 12-19 steps), and a table that grows mid-run costs the run a
        # return per target and a new state tuple
        self._rows = max(1, 2 * (theta + 2)) if warp else 1
        self.frames = frames
        ahead = frames.rows if frames is not None and step_time.blockable else 1
        self._targets = max(TARGETS, ahead) if warp else 1

    def dims(self) -> dict[str, int]:
        """The table's dimensions (``rb_t`` targets of ``rb_j`` draws)."""
        return {"rb_t": self._targets, "rb_j": self._rows}

    def given(self) -> dict[str, NDArray[Any]]:
        """The table's arrays, empty (``np.zeros``: pages untouched until filled)."""
        tag = np.zeros((self._targets, 2), dtype=np.int64)
        tag[:, CO.RB_TARGET] = -1
        return {"rb_val": np.zeros((self._targets, self._rows, self.n)), "rb_tag": tag}

    def fill(self, S: State, target: int, need: int) -> State:
        """Make the table hold at least ``need`` rollback draws of ``target``.

        Returns:
            The state, with a larger ``rb_val`` if the table had to grow.
        """
        tag = S[L.RB_TAG]
        row = target % tag.shape[0]
        if tag[row, CO.RB_TARGET] != target:
            if self.step_time.blockable:
                return self._fill_ahead(S, target, need)
            tag[row] = (target, 0)
        have = int(tag[row, CO.RB_ROWS])
        if have >= need:
            return S
        want = max(need, 2 * have)
        S = _room(S, want)
        val = S[L.RB_VAL]
        if self.step_time.blockable:  # every missing draw in one sampler call
            val[row, have:want] = self.step_time.block(ROLLBACK_DRAW, target,
                                                       np.arange(have, want))
        else:
            for j in range(have, want):
                val[row, j] = self.step_time.vector(ROLLBACK_DRAW, target, j)
        tag[row, CO.RB_ROWS] = want
        return S

    def _fill_ahead(self, S: State, target: int, need: int) -> State:
        """Fill the row of a new ``target`` and the rows of the targets after it up to
        the end of the frame draws' block (at most one per table row and
        :data:`BLOCK_VALUES` values), each with as many draws as the table's rows hold
        (``need`` at least)."""
        S = _room(S, need)
        val = S[L.RB_VAL]
        t, depth, n = val.shape
        end = self.frames.end if self.frames is not None else 0
        count = max(1, min(end - target, t, BLOCK_VALUES // max(1, depth * n)))
        targets = np.arange(target, target + count, dtype=np.int64)
        rows = targets % t
        val[rows] = self.step_time.grid(ROLLBACK_DRAW, targets, np.arange(depth))
        tag = S[L.RB_TAG]
        tag[rows, CO.RB_TARGET] = targets
        tag[rows, CO.RB_ROWS] = depth
        return S

    def flush(self, S: State) -> None:
        """Re-simulate every deferred rollback (one batched call) and unmark their nodes."""
        iv = S[L.INTS]
        m = int(iv[CO.I_DEFN])
        if m == 0:
            return
        d = S[L.DEF_INT][:m]
        nodes = self.truth.flush_rollbacks(d[:, CO.D_NODE].copy(), d[:, CO.D_FIRST].copy(),
                                           S[L.DEF_ROW][:m].copy(), d[:, CO.D_STEPS].copy())
        iv[CO.I_DEFN] = 0
        pend = S[L.RESIM_PEND]
        pend[nodes] = 0
        pend[self.n] = 0  # the flush re-simulated every pending node


def _room(S: State, want: int) -> State:
    """The state with a table of ``want`` draws per row at least (grown to twice its
    rows or ``want``, the draws held kept)."""
    val = S[L.RB_VAL]
    if want <= val.shape[1]:
        return S
    big = np.zeros((val.shape[0], max(want, 2 * val.shape[1]), val.shape[2]))
    big[:, : val.shape[1]] = val
    return L.replaced(S, {"rb_val": big})
