"""The server's control events in compiled code: trigger issues and alignment ticks.

With the compiled core (:mod:`~sigma_des.events.fast.loop`) the messages of a run never
reach Python, but its control events — the trigger issue (the swarm's physics step, the
trigger's publication) and the alignment tick (the server's tick burst, BiDES's
Algorithm 1 and rate adaptation or ``none``'s newest states, the command tick) — are
SimPy events whose Python handlers cost several times the messages they cause on a small
swarm (a learning env's scenes). Here the same rules run in one compiled loop
(:func:`run`) that brings the core up to each control event, as
:meth:`~sigma_des.events.engine.MethodRun.advance` does, and handles it: the same
floating point operations in the same order as :mod:`~sigma_des.events.trigger`,
:mod:`~sigma_des.events.server`, the aligners (``bides``, ``none``) and
:meth:`~sigma_des.events.truth.SwarmTruth.step_frame`, so a run is bit-identical to the
SimPy path (tests/events/fast/test_control.py).

A run has at most two control events pending, the next trigger (priority ``TRIGGER``) and
the next alignment tick (``ALIGN``); at equal times the trigger goes first, as the kernel's
priorities order them. :func:`run` returns to Python (:mod:`~.control_run`) for what needs
it: an exit of the core's loop (flushes, growth, a job's rollback draws), deferred
rollbacks to re-simulate, a block of frame draws to sample, room for a trigger's fan-out,
a command tick (the caller decides), the end. The state Python reads (``CI_*``, ``CF_*``)
is in two small arrays; every other array is the run's own, shared in place.
"""

from __future__ import annotations

import math

from sigma_des.core.flags import EXACT, MISSING
from sigma_des.events.align.newest import take_rows
from sigma_des.events.align.ring import align_in
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.handle import deref
from sigma_des.events.fast.loop import advance, owe_steps, publish_trigger, tick
from sigma_des.events.fast.primitives import copy_rows

__all__ = ["CF_FIELDS", "CI_FIELDS", "CODES", "run", "run_held"]

#: int scalars of the control state (``C[0]``), by name
CI_FIELDS = (
    "latest",  # the newest trigger issued (-1 before the first)
    "k0",  # the trigger grid's base frame
    "align_tick",  # index of the next alignment tick
    "hi", "lo",  # BiDES's hold-down / hold-up counters
    "rate_changes",
    "aligned",  # the aligned frame (-1 before any)
    "new_snapshot",
    "trig_on", "align_on",  # a trigger / an alignment tick is scheduled
    "align_direct",  # the scheduled tick waited for the loop thread: it runs unchecked
    "every",  # commands every this many ticks (0: no commands)
    "cpu",  # the network has a CPU stage (server bursts, the loop thread's queue)
    "adapt", "theta_lag", "hole_fill", "lag_high", "lag_low", "hold_down", "hold_up",
    "truth_latest",  # the newest frame the physics truth stepped
    "fd_first", "fd_count",  # the frame draws' block: first frame and frames held
    "need_k",  # the frame whose draws Python must sample (DRAWS)
    "space",  # free event slots and payload rows a trigger's fan-out needs
    "rollbacks", "resim_steps",  # the truth's counts of rollbacks and re-simulated steps
    "rolled",  # rollbacks served here (the core's NEED_ROLLBACK exits)
    "need_node",  # the node whose job start Python must serve (START)
    "method",  # BIDES or NONE
    "dirty",  # none: states newer than the shown ones arrived since the last tick
)
#: float scalars of the control state (``C[1]``), by name
CF_FIELDS = (
    "now", "trig_t", "align_t",  # the clock; the scheduled trigger's and tick's times
    "f_trig", "t0", "base_f",  # the current rate; the grid T_k = t0 + (k - k0) / base_f
    "end",  # the run's duration: nothing happens at or after it
    "phys_t",  # physics time of the newest frame
    "align_phase", "f_align", "f_nominal", "f_min", "rate_down", "rate_up",
    "tick_cost",  # deployment.server_tick (s of the server's loop thread)
    "pt",  # the time of the job start Python must serve (START)
)
CI_LATEST, CI_K0, CI_ALIGN_TICK, CI_HI, CI_LO, CI_RATE_CHANGES = 0, 1, 2, 3, 4, 5
CI_ALIGNED, CI_NEW_SNAPSHOT, CI_TRIG_ON, CI_ALIGN_ON, CI_ALIGN_DIRECT, CI_EVERY = 6, 7, 8, 9, 10, 11
CI_CPU, CI_ADAPT, CI_THETA_LAG, CI_HOLE_FILL, CI_LAG_HIGH, CI_LAG_LOW = 12, 13, 14, 15, 16, 17
CI_HOLD_DOWN, CI_HOLD_UP, CI_TRUTH_LATEST, CI_FD_FIRST, CI_FD_COUNT, CI_NEED_K = (
    18, 19, 20, 21, 22, 23)
CI_SPACE, CI_ROLLBACKS, CI_RESIM_STEPS, CI_ROLLED, CI_NEED_NODE = 24, 25, 26, 27, 28
CI_METHOD, CI_DIRTY = 29, 30
#: the methods the loop runs (``CI_METHOD``)
BIDES, NONE = 0, 1
CF_NOW, CF_TRIG_T, CF_ALIGN_T, CF_F_TRIG, CF_T0, CF_BASE_F, CF_END = 0, 1, 2, 3, 4, 5, 6
CF_PHYS_T, CF_ALIGN_PHASE, CF_F_ALIGN, CF_F_NOMINAL, CF_F_MIN, CF_RATE_DOWN = 7, 8, 9, 10, 11, 12
CF_RATE_UP, CF_TICK_COST, CF_PT = 13, 14, 15
assert CI_DIRTY == len(CI_FIELDS) - 1 and CF_PT == len(CF_FIELDS) - 1

# why run() returned (beyond the core loop's own exit codes, codes.EXIT_CODES)
COMMAND_TICK = 100  # a command tick: the shown snapshot waits for the caller's commands
END = 101  # the next control event is at or after the end: every message before it ran
DEFERRED = 102  # rollbacks deferred by the core: Python re-simulates them
DRAWS = 103  # trigger ``need_k``'s frame draws are not in the block: Python samples them
SPACE = 104  # the trigger's fan-out needs more free event slots than there are
OUT = 105  # deliveries buffered for Python (an aligner without a ring, a recording tap)
START = 106  # a rollback's job start needs rollback draws: Python fills them, starts the job
#: the codes above by name
CODES = {"COMMAND_TICK": COMMAND_TICK, "END": END, "DEFERRED": DEFERRED, "DRAWS": DRAWS,
         "SPACE": SPACE, "OUT": OUT, "START": START}

# the C tuple's arrays
C_INT, C_FLT, C_TRIG_TIME, C_CKPT, C_OBS_HIST, C_SLOT_FRAME, C_FRAME_DT, C_PHYS_HIST = range(8)
C_STATE, C_CMD, C_SHOWN_FRAME, C_SHOWN_GEN, C_SHOWN_OBS, C_SHOWN_FLAG = range(8, 14)
C_FD_VALUES, C_FD_TAGS, C_FD_TABLES, C_FD_WIDTHS, C_FD_BLOCK, C_PHYS = range(14, 20)
C_INITIAL, C_ZERO = 20, 21  # the truth's initial state; a zero row (a slot never written)
C_SCRATCH = 22  # a step's result without checkpoints
C_NEW_FRAME, C_NEW_GEN, C_NEW_OBS = 23, 24, 25  # none: the newest state per node
C_HAS, C_CONSIDERED = 26, 27  # Algorithm 1's per-node scratch rows (bool)


@jit
def _step_truth(C, k, dt, step, observe):  # type: ignore[no-untyped-def]
    """:meth:`SwarmTruth.step_frame` of frame ``k`` (no trajectory log, no held rows):
    the state stepped into its checkpoint slot (or a scratch array without checkpoints),
    observed into the published ring."""
    ci, cf = C[C_INT], C[C_FLT]
    H = C[C_SLOT_FRAME].shape[0]
    slot = k % H
    C[C_FRAME_DT][slot] = dt
    cf[CF_PHYS_T] = cf[CF_PHYS_T] + dt
    C[C_PHYS_HIST][slot] = cf[CF_PHYS_T]
    state = C[C_STATE]
    out = C[C_CKPT][slot] if C[C_CKPT].shape[0] > 0 else C[C_SCRATCH]
    step(state, C[C_CMD], dt, C[C_PHYS], out)
    for r in range(state.shape[0]):
        for c in range(state.shape[1]):
            state[r, c] = out[r, c]
    observe(state, C[C_OBS_HIST][slot])
    C[C_SLOT_FRAME][slot] = k
    ci[CI_TRUTH_LATEST] = k


@jit
def _issue(S, C, step, observe):  # type: ignore[no-untyped-def]
    """The trigger issue at ``now`` (TriggerSource.issue): the frame's draws and room for
    its fan-out first (else a code for Python, nothing changed), then the physics step,
    the publication and the next issue on the grid. Returns 0 or the code."""
    ci, cf = C[C_INT], C[C_FLT]
    t = cf[CF_NOW]
    k = ci[CI_LATEST] + 1
    j = k - ci[CI_FD_FIRST]
    if j < 0 or j >= ci[CI_FD_COUNT]:
        ci[CI_NEED_K] = k
        return DRAWS
    iv = S[L.INTS]
    if iv[CO.I_FREE] < ci[CI_SPACE] or iv[CO.I_PFREE] < ci[CI_SPACE]:
        return SPACE
    ci[CI_TRIG_ON] = 0
    dt = 1.0 / cf[CF_F_TRIG]
    H = C[C_TRIG_TIME].shape[0]
    C[C_TRIG_TIME][k % H] = t
    ci[CI_LATEST] = k
    _step_truth(C, k, dt, step, observe)
    copy_rows(C[C_FD_VALUES], C[C_FD_TAGS], C[C_FD_TABLES], C[C_FD_WIDTHS], C[C_FD_BLOCK], j,
              k % C[C_FD_TAGS].shape[1], k)
    publish_trigger(S, k, t, math.nan, 0)
    if cf[CF_F_TRIG] != cf[CF_BASE_F]:  # the rate changed: count periods from here
        cf[CF_T0] = t
        ci[CI_K0] = k
        cf[CF_BASE_F] = cf[CF_F_TRIG]
    cf[CF_TRIG_T] = cf[CF_T0] + (k + 1 - ci[CI_K0]) / cf[CF_BASE_F]
    ci[CI_TRIG_ON] = 1
    return 0


@jit
def _adapt(C, lag):  # type: ignore[no-untyped-def]
    """BiDES's rate adaptation to the alignment lag (BidesAligner._adapt)."""
    ci, cf = C[C_INT], C[C_FLT]
    if lag > ci[CI_LAG_HIGH]:
        ci[CI_HI] += 1
        ci[CI_LO] = 0
        if ci[CI_HI] >= ci[CI_HOLD_DOWN] and cf[CF_F_TRIG] > cf[CF_F_MIN]:
            cf[CF_F_TRIG] = max(cf[CF_F_MIN], cf[CF_F_TRIG] * cf[CF_RATE_DOWN])
            ci[CI_RATE_CHANGES] += 1
            ci[CI_HI] = 0
    elif lag < ci[CI_LAG_LOW]:
        ci[CI_LO] += 1
        ci[CI_HI] = 0
        if ci[CI_LO] >= ci[CI_HOLD_UP] and cf[CF_F_TRIG] < cf[CF_F_NOMINAL]:
            cf[CF_F_TRIG] = min(cf[CF_F_NOMINAL], cf[CF_F_TRIG] * cf[CF_RATE_UP])
            ci[CI_RATE_CHANGES] += 1
            ci[CI_LO] = 0
    else:
        ci[CI_HI] = 0
        ci[CI_LO] = 0


@jit
def _bides(S, C):  # type: ignore[no-untyped-def]
    """BidesAligner.align: Algorithm 1 into fresh shown rows, then the adaptation."""
    ci = C[C_INT]
    frame, gen, obs, flag = C[C_SHOWN_FRAME], C[C_SHOWN_GEN], C[C_SHOWN_OBS], C[C_SHOWN_FLAG]
    for i in range(frame.shape[0]):  # the rows align() starts from
        frame[i] = -1
        gen[i] = math.nan
        flag[i] = MISSING
        for c in range(obs.shape[1]):
            obs[i, c] = math.nan
    prev = ci[CI_ALIGNED]
    F = align_in(S[L.RING_FRAME], S[L.RING_GEN], S[L.RING_OBS], S[L.RING_LATEST],  # noqa: N806
                 ci[CI_THETA_LAG], ci[CI_HOLE_FILL] != 0, prev, frame, gen, obs, flag,
                 C[C_HAS], C[C_CONSIDERED])
    ci[CI_NEW_SNAPSHOT] = 1 if F > prev else 0
    ci[CI_ALIGNED] = F
    if ci[CI_ADAPT] and F >= 0:
        _adapt(C, ci[CI_LATEST] - F)


@jit
def _none(C):  # type: ignore[no-untyped-def]
    """NoneAligner.align: the newest states shown, if any arrived since the last tick."""
    ci = C[C_INT]
    ci[CI_NEW_SNAPSHOT] = ci[CI_DIRTY]
    if not ci[CI_DIRTY]:
        return
    nf, ng, no = C[C_NEW_FRAME], C[C_NEW_GEN], C[C_NEW_OBS]
    frame, gen, obs, flag = C[C_SHOWN_FRAME], C[C_SHOWN_GEN], C[C_SHOWN_OBS], C[C_SHOWN_FLAG]
    top = nf[0]
    for i in range(nf.shape[0]):
        frame[i] = nf[i]
        gen[i] = ng[i]
        for c in range(obs.shape[1]):
            obs[i, c] = no[i, c]
        flag[i] = EXACT if nf[i] >= 0 else MISSING
        top = max(top, nf[i])
    ci[CI_ALIGNED] = top
    ci[CI_DIRTY] = 0


@jit
def _take_out(S, C):  # type: ignore[no-untyped-def]
    """none: the deliveries the core buffered (``S.out_*``), taken by NoneAligner.on_states's
    rule, :func:`~sigma_des.events.align.newest.take_rows` itself (a row replaces its
    node's entry when its frame is greater), in arrival order."""
    iv = S[L.INTS]
    o = iv[CO.I_OUT]
    oi, of = S[L.OUT_INT], S[L.OUT_FLOAT]
    no = C[C_NEW_OBS]
    changed = C[C_HAS]  # a per-node scratch row (Algorithm 1's, unused by none)
    for i in range(changed.shape[0]):
        changed[i] = False
    take_rows(C[C_NEW_FRAME], C[C_NEW_GEN], no, oi[:o, 0], oi[:o, 1], of[:o, 1],
              of[:o, 3:3 + no.shape[1]], changed)
    for i in range(changed.shape[0]):
        if changed[i]:
            C[C_INT][CI_DIRTY] = 1
    iv[CO.I_OUT] = 0


@jit
def _align(S, C):  # type: ignore[no-untyped-def]
    """The alignment tick at ``now`` (AlignmentServer._align with the method's ``align``):
    the server's tick burst, the snapshot (and BiDES's adaptation), the command tick, the
    next tick. Returns COMMAND_TICK when the caller's commands are due, else 0."""
    ci, cf = C[C_INT], C[C_FLT]
    t = cf[CF_NOW]
    if cf[CF_TICK_COST] > 0.0 and ci[CI_CPU]:
        tick(S, CO.P_SERVER, cf[CF_TICK_COST], t)  # before the tick's commands
    if ci[CI_METHOD] == BIDES:
        _bides(S, C)
    else:
        _none(C)
    gen = C[C_SHOWN_GEN]
    due = False
    if ci[CI_EVERY] > 0 and ci[CI_ALIGN_TICK] % ci[CI_EVERY] == 0:
        for i in range(gen.shape[0]):  # commands only on a view with a valid row
            if not math.isnan(gen[i]):
                due = True
                break
    ci[CI_ALIGN_TICK] += 1
    nxt = (ci[CI_ALIGN_TICK] + cf[CF_ALIGN_PHASE]) / cf[CF_F_ALIGN]
    cf[CF_ALIGN_T] = nxt if nxt > t else t
    ci[CI_ALIGN_ON] = 1
    return COMMAND_TICK if due else 0


@jit
def _tick(S, C):  # type: ignore[no-untyped-def]
    """An alignment tick's event: it waits for the server's loop thread (_once_free),
    then runs unless the run is over. Returns what :func:`_align` returns (or 0)."""
    ci, cf = C[C_INT], C[C_FLT]
    t = cf[CF_NOW]
    ci[CI_ALIGN_ON] = 0
    if not ci[CI_ALIGN_DIRECT] and ci[CI_CPU]:
        free = S[L.CPU_FREE][CO.P_SERVER]
        if free > t:  # the tick runs once the loop thread is free
            cf[CF_ALIGN_T] = free
            ci[CI_ALIGN_ON] = 1
            ci[CI_ALIGN_DIRECT] = 1
            return 0
    ci[CI_ALIGN_DIRECT] = 0
    if t >= cf[CF_END]:
        return 0
    return _align(S, C)


@jit
def _roll_back(S, C, resim):  # type: ignore[no-untyped-def]
    """The rollback the core handed over (``NEED_ROLLBACK``), as CompiledCore._rollback
    and SwarmTruth.rollback serve it for a model whose rollbacks are not deferred: the
    node re-simulated from its checkpoint, then the steps its next job owes. Returns
    False, with nothing changed, when Python must serve it (the node still owes an
    earlier re-simulation, or the event table is short of room); else 0 or START."""
    ci, cf = C[C_INT], C[C_FLT]
    iv = S[L.INTS]
    i = iv[CO.I_PNODE]
    if S[L.RESIM_PEND][i] or iv[CO.I_FREE] < ci[CI_SPACE] or iv[CO.I_PFREE] < ci[CI_SPACE]:
        return -1
    now = S[L.FLOATS][CO.F_PT]
    latest = ci[CI_TRUTH_LATEST]
    slot_frame = C[C_SLOT_FRAME]
    H = slot_frame.shape[0]
    c = max(iv[CO.I_PA], max(0, latest - H + 2))  # SwarmTruth.first_resim
    if c == 0:
        prev = C[C_INITIAL][i]
    elif slot_frame[(c - 1) % H] < 0:
        prev = C[C_ZERO]
    else:
        prev = C[C_CKPT][(c - 1) % H, i]
    if c <= latest:
        resim(prev, C[C_CMD][i], C[C_FRAME_DT], c, latest, C[C_PHYS], i, C[C_CKPT],
              C[C_OBS_HIST], C[C_STATE])
    else:  # nothing to re-simulate: the node's state is its checkpoint before c
        for x in range(prev.shape[0]):
            C[C_STATE][i, x] = prev[x]
    steps = max(0, iv[CO.I_PB] - c + 1)
    ci[CI_ROLLBACKS] += 1
    ci[CI_RESIM_STEPS] += steps
    ci[CI_ROLLED] += 1
    owe_steps(S, i, steps, now)
    if iv[CO.I_PEND] == CO.NEED_START:  # the job start it made needs rollback draws
        iv[CO.I_PEND] = 0
        ci[CI_NEED_NODE] = i
        cf[CF_PT] = now
        return START
    return 0


@jit
def run(S, C, step, observe, resim):  # type: ignore[no-untyped-def]
    """Run the control events and the messages before each (messages first at equal
    times) until Python is needed; return why (the core's exit code, or :data:`CODES`).

    ``step``, ``observe`` and ``resim`` are the dynamics' compiled kernels (its
    ``compiled_physics``: the same bits as its ``step``, ``observe`` and
    ``resimulate_into``)."""
    ci, cf = C[C_INT], C[C_FLT]
    iv = S[L.INTS]
    while True:
        trig = ci[CI_TRIG_ON] != 0
        if trig and (not ci[CI_ALIGN_ON] or cf[CF_TRIG_T] <= cf[CF_ALIGN_T]):
            tc = cf[CF_TRIG_T]
        elif ci[CI_ALIGN_ON]:
            tc = cf[CF_ALIGN_T]
            trig = False
        else:
            tc = math.inf
        last = tc >= cf[CF_END]
        iv[CO.I_LATEST] = ci[CI_TRUTH_LATEST]  # rollbacks clamp to the ring
        code = advance(S, cf[CF_END] if last else tc, last)
        if code == CO.NEED_ROLLBACK:
            code = _roll_back(S, C, resim)
            if code < 0:
                return CO.NEED_ROLLBACK
            if code != 0:
                return code
            continue
        if code != CO.OK:
            return code
        if iv[CO.I_DEFN]:
            return DEFERRED
        if iv[CO.I_OUT]:
            if ci[CI_METHOD] != NONE:
                return OUT
            _take_out(S, C)
        if last:
            return END
        cf[CF_NOW] = tc
        if trig:
            code = _issue(S, C, step, observe)
        else:
            code = _tick(S, C)
        if code != 0:
            return code


@jit
def run_held(H, C, step, observe, resim):  # type: ignore[no-untyped-def]
    """:func:`run` on the state a :class:`~sigma_des.events.fast.handle.Handle` holds
    (the core's state unboxed once, not at every call)."""
    return run(deref(H), C, step, observe, resim)
