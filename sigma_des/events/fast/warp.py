"""BiDES time-warp rollbacks in the compiled message core (docs/concepts/engines.md).

A command stamped more than Θ_warp frames behind a node's own frame rolls the node
back (``NodeRules.on_command``): the node owes ``max(0, current − c + 1)`` compute steps,
``c`` clamped to the oldest frame whose previous checkpoint the truth's ring holds, and
the truth re-simulates the node's trajectory from ``c`` with the new command row. The
count and the job start are arithmetic and run here (:func:`rollback`); the physics
re-simulation is deferred: the rollback joins ``def_int``/``def_row`` in arrival order
(node, first frame, steps owed, a copy of the command row) and the node is marked in
``resim_pend``, and Python re-simulates every deferred rollback in one batch
(:meth:`sigma_des.events.truth.SwarmTruth.flush_rollbacks`) before anything reads the
stale rows: before the node's next state publish (the loop returns ``NEED_RESIM``) and
before ``advance_to`` returns.

The loop hands a rollback to Python (``NEED_ROLLBACK``) only where Python must act first:
a second rollback of a node whose re-simulation is still owed (the first is flushed
first), a dynamics model that re-simulates one aircraft at once (no batched steps), and
a first frame past the truth's newest (nothing to re-simulate: the truth's own path).
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    D_FIRST,
    D_NODE,
    D_STEPS,
    I_DEFN,
    I_LATEST,
    I_PA,
    I_PB,
    NEED_ROLLBACK,
    Q_BATCH,
    Q_H,
    Q_M,
    Q_N,
)
from sigma_des.events.fast.job import hand_over, owe
from sigma_des.events.fast.layout import CMD, DEF_INT, DEF_ROW, INTS, IPARAMS, RESIM_PEND
from sigma_des.events.fast.primitives import jit

__all__ = ["defer", "first_resim", "rollback"]


@jit
def first_resim(S, c):  # type: ignore[no-untyped-def]
    """SwarmTruth.first_resim: ``c`` clamped to the oldest frame the ring re-simulates."""
    lo = S[INTS][I_LATEST] - S[IPARAMS][Q_H] + 2
    if lo < 0:
        lo = 0
    return c if c > lo else lo


@jit
def defer(S, i, c, current):  # type: ignore[no-untyped-def]
    """Defer node ``i``'s rollback to (clamped) frame ``c``; the steps its next job owes."""
    iv = S[INTS]
    m = iv[I_DEFN]
    steps = current - c + 1
    if steps < 0:
        steps = 0
    d = S[DEF_INT]
    d[m, D_NODE] = i
    d[m, D_FIRST] = c
    d[m, D_STEPS] = steps
    row = S[DEF_ROW]
    cmd = S[CMD]
    for j in range(S[IPARAMS][Q_M]):
        row[m, j] = cmd[i, j]
    iv[I_DEFN] = m + 1
    rp = S[RESIM_PEND]
    rp[i] = 1
    rp[S[IPARAMS][Q_N]] = 1  # some node is pending
    return steps


@jit
def rollback(S, i, stamp, current, now):  # type: ignore[no-untyped-def]
    """Node ``i`` rolls back to frame ``stamp`` from its frame ``current`` at ``now``."""
    c = first_resim(S, stamp)
    if not S[IPARAMS][Q_BATCH] or S[RESIM_PEND][i] or c > S[INTS][I_LATEST]:
        hand_over(S, NEED_ROLLBACK, i, now)
        iv = S[INTS]
        iv[I_PA] = stamp
        iv[I_PB] = current
        return
    owe(S, i, defer(S, i, c, current), now)
