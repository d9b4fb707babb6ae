"""A node's compute job in the compiled message core (docs/concepts/model.md, "Physics nodes").

A job steps node ``i`` from its newest computed frame to its newest request: its cost
is :func:`sigma_des.events.jobs.job_cost` — the step draws ``(STEP_DRAW, i, f, 0)`` of
every frame, then the rollback draws ``(ROLLBACK_DRAW, i, target, j)`` of the steps a
time-warp rollback owes, then every slow factor active at the start — summed here in
that order from the draw tables, so the float is the specification's. A target's
rollback draws are a table row Python fills on demand (``rb_val``, ``rb_tag``:
:class:`~sigma_des.events.fast.rollbacks.Rollbacks`); a start that finds them missing
stops the loop (``NEED_START``) and Python fills the row and starts the job
(:func:`start_job` again). The job takes its host's earliest-free core
(:func:`reserve`) and completes as an ``EV_DONE`` event.
"""

from __future__ import annotations

from sigma_des.events.fast.codes import (
    EV_DONE,
    F_PT,
    I_PEND,
    I_PNODE,
    N_BUSY,
    N_FRAME,
    N_RB,
    N_REQ,
    N_TARGET,
    NEED_START,
    RB_ROWS,
    RB_TARGET,
    STEP,
)
from sigma_des.events.fast.layout import (
    CORES,
    FLOATS,
    HOST_OF,
    INTS,
    NODE,
    RB_TAG,
    RB_VAL,
    SLOW,
    SLOW_PTR,
)
from sigma_des.events.fast.primitives import address, alloc, draw, jit, push
from sigma_des.events.fast.stateref import ref

__all__ = ["hand_over", "owe", "reserve", "start_job"]


@jit
def hand_over(S, code, i, now):  # type: ignore[no-untyped-def]
    """Stop the loop after this event: Python must act (``code``) for node ``i``."""
    iv = S[INTS]
    iv[I_PEND] = code
    iv[I_PNODE] = i
    S[FLOATS][F_PT] = now


@jit
def reserve(S, i, target, cost, now):  # type: ignore[no-untyped-def]
    """Take the host's earliest-free core for ``cost`` seconds; schedule completion."""
    S = ref(S)  # one pointer to the state for every call below
    row = S[CORES][S[HOST_OF][i]]
    m = 0
    for j in range(1, row.shape[0]):
        if row[j] < row[m]:
            m = j
    free = row[m]
    start = now if now > free else free
    row[m] = start + cost
    nd = S[NODE]
    nd[N_BUSY, i] = 1
    nd[N_TARGET, i] = target
    slot = alloc(S)
    address(S, slot, EV_DONE, i, 0, i, target)
    push(S, start + cost, slot)


@jit
def start_job(S, i, now):  # type: ignore[no-untyped-def]
    """NodeRules.start_job: node ``i``'s job to its newest request, starting at ``now``
    (``NEED_START`` if the rollback draws it owes are not in the table yet)."""
    nd = S[NODE]
    target = nd[N_REQ, i]
    rb = nd[N_RB, i]
    row = 0
    if rb != 0:
        tag = S[RB_TAG]
        row = target % tag.shape[0]
        if tag[row, RB_TARGET] != target or tag[row, RB_ROWS] < rb:
            hand_over(S, NEED_START, i, now)
            return
    cost = 0.0
    for f in range(nd[N_FRAME, i] + 1, target + 1):
        cost += draw(S, STEP, 0, i, f)
    if rb != 0:
        val = S[RB_VAL]
        for j in range(rb):
            cost += val[row, j, i]
        nd[N_RB, i] = 0
    ptr = S[SLOW_PTR]
    slow = S[SLOW]
    for j in range(ptr[i], ptr[i + 1]):
        if slow[j, 0] <= now and now < slow[j, 1]:
            cost *= slow[j, 2]
    reserve(S, i, target, cost, now)


@jit
def owe(S, i, steps, now):  # type: ignore[no-untyped-def]
    """Node ``i`` owes ``steps`` more re-simulated steps (a rollback); start it if idle."""
    nd = S[NODE]
    nd[N_RB, i] += steps
    if not nd[N_BUSY, i]:
        start_job(S, i, now)
