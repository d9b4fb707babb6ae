"""The CPU stage in the compiled message core (docs/concepts/deployment.md).

Every process (the broker, the server, each physics host's client process) is one
thread on a machine's cores; a burst is placed at its arrival —
:mod:`sigma_des.net.cpu` (``Process.acquire``, ``hold``, ``burst``, ``Machine.place``,
``reserve``) with the same floating point operations in the same order: ready at ``r
= a if a > thread_free else thread_free``, length ``L = demand * scale``, the earliest
start ``s >= r`` at which a core has ``[s, s + L)`` free of its reservations (lowest
index on ties), at most ``RESERVATIONS`` a core (beyond: the two earliest merge).
Process ``p`` is the spec's ``Cpu.processes[p]`` (broker, server, hosts); its
counters (CPU seconds and longest wait in the metrics window, bursts) are handed
back at the end of the run.
A zero demand is no burst: callers never call :func:`burst` for it.
Run-queue waits (``deployment.*_runq``, ``runq_growth``, ``broker_runq_growth``,
``server_runq_growth``) are ``Process.run_wait`` and ``Machine.load_wait``, and a
wake-up's part on the other thread (``*_wake_side``) is ``Process.beside``, and a
process's network thread (``*_net_msg``, ``*_net_wake``) ``Process.net_span``, the same
operations in the same order.
"""

from __future__ import annotations

import math

from sigma_des.events.fast.codes import (
    CA_BUSY,
    CA_QUEUED,
    CA_WAIT,
    G_END,
    G_WARMUP,
    ML_BG,
    ML_BUSY,
    ML_END,
    ML_GROW,
    ML_Q,
)
from sigma_des.events.fast.layout import (
    CPU_ACC,
    CPU_BURSTS,
    CPU_FREE,
    CPU_GROW,
    CPU_IV,
    CPU_LOAD,
    CPU_MACH,
    CPU_NET,
    CPU_NFREE,
    CPU_NIV,
    CPU_RUNQ,
    CPU_SCALE,
    CPU_SIDE,
    CPU_SWITCH,
    CPU_WAKE,
    FPARAMS,
)
from sigma_des.events.fast.primitives import jit
from sigma_des.events.fast.stateref import ref
from sigma_des.net.cpu import LOAD_WINDOW, RESERVATIONS
from sigma_des.net.cpu import queue_wait as net_queue_wait

__all__ = ["acquire", "burst", "hold", "net_span", "queue_wait", "run_wait", "span",
           "threaded", "tick"]


#: net.cpu.queue_wait compiled as it is (Erlang C's mean wait over mean service)
queue_wait = jit(net_queue_wait)


@jit
def _load_wait(S, m, a):  # type: ignore[no-untyped-def]
    """Machine.load_wait: the run-queue wait per CPU second of machine ``m`` at ``a``."""
    ld = S[CPU_LOAD][m]
    if ld[ML_GROW] == 0.0:
        return 0.0
    if a >= ld[ML_END]:
        n = S[CPU_NIV][m].shape[0]
        busy = ld[ML_BUSY] if a < ld[ML_END] + LOAD_WINDOW else 0.0
        ld[ML_Q] = queue_wait(n, (busy / LOAD_WINDOW + ld[ML_BG]) / n)
        ld[ML_END] += LOAD_WINDOW * (1.0 + math.floor((a - ld[ML_END]) / LOAD_WINDOW))
        ld[ML_BUSY] = 0.0
    return ld[ML_Q]


@jit
def run_wait(S, p, a, cpu, length):  # type: ignore[no-untyped-def]
    """Process.run_wait: the run-queue wait of a burst of ``cpu`` CPU seconds (``length``
    on a core) of process ``p`` arriving at ``a``; its CPU counts in the load window."""
    m = S[CPU_MACH][p]
    ld = S[CPU_LOAD][m]
    rq = S[CPU_RUNQ][p]
    if not (ld[ML_GROW] != 0.0 or rq > 0.0):
        return 0.0
    q = _load_wait(S, m, a)  # also closes the load window: every burst's arrival does
    wait = (rq + q if S[CPU_GROW][p] != 0.0 else rq) * length
    ld[ML_BUSY] += cpu
    g = S[FPARAMS]
    if g[G_WARMUP] <= a and a < g[G_END]:
        S[CPU_ACC][p, CA_QUEUED] += wait
    return wait


@jit
def acquire(S, p, a, length, wait):  # type: ignore[no-untyped-def]
    """Process.acquire: start time and core of a burst of ``length`` of process ``p``
    arriving at ``a`` that waits ``wait`` on the run queue once its thread is free
    (ended reservations dropped, nothing held)."""
    tf = S[CPU_FREE][p]
    r = a if a > tf else tf
    nf = S[CPU_NFREE][p]
    sw = S[CPU_SWITCH][p]
    if sw > 0.0 and nf > r:  # the network thread holds the interpreter lock
        lock = r + sw
        r = nf if nf < lock else lock
    if wait > 0.0:
        r += wait
    return _place(S, S[CPU_MACH][p], a, r, length)


@jit
def _place(S, m, a, r, length):  # type: ignore[no-untyped-def]
    """Machine.place: the earliest start ``s >= r`` on machine ``m`` of a burst of
    ``length`` arriving at ``a``, and its core (ended reservations dropped)."""
    iv = S[CPU_IV][m]
    niv = S[CPU_NIV][m]
    best = -1.0
    core = 0
    for c in range(niv.shape[0]):
        k = 0
        while k < niv[c] and iv[c, k, 1] <= a:  # ended by now
            k += 1
        if k:
            nk = niv[c] - k
            for j in range(nk):
                iv[c, j, 0] = iv[c, j + k, 0]
                iv[c, j, 1] = iv[c, j + k, 1]
            niv[c] = nk
        s = r
        for j in range(niv[c]):
            st = iv[c, j, 0]
            en = iv[c, j, 1]
            if en <= s:
                continue
            if s + length <= st:  # fits in the gap before this reservation
                break
            s = en
        if c == 0 or s < best:
            best = s
            core = c
    return best, core


@jit
def _reserve(S, m, c, s, end):  # type: ignore[no-untyped-def]
    """Machine.reserve: core ``c`` of machine ``m`` holds ``[s, end)``."""
    iv = S[CPU_IV][m]
    niv = S[CPU_NIV][m]
    n = niv[c]
    i = n
    while i > 0 and iv[c, i - 1, 0] > s:
        i -= 1
    j = n
    while j > i:
        iv[c, j, 0] = iv[c, j - 1, 0]
        iv[c, j, 1] = iv[c, j - 1, 1]
        j -= 1
    iv[c, i, 0] = s
    iv[c, i, 1] = end
    n += 1
    if n > RESERVATIONS:  # the two earliest merge (a row of room for the insert)
        iv[c, 0, 1] = iv[c, 1, 1]
        for j in range(1, n - 1):
            iv[c, j, 0] = iv[c, j + 1, 0]
            iv[c, j, 1] = iv[c, j + 1, 1]
        n -= 1
    niv[c] = n


@jit
def hold(S, p, a, s, c, end):  # type: ignore[no-untyped-def]
    """Process.hold: the burst arrived at ``a``, started at ``s`` on core ``c``, ends at ``end``."""
    S[CPU_FREE][p] = end
    _reserve(S, S[CPU_MACH][p], c, s, end)
    g = S[FPARAMS]
    acc = S[CPU_ACC]
    if g[G_WARMUP] <= a and a < g[G_END]:
        S[CPU_BURSTS][p] += 1
        w = s - a
        if w > acc[p, CA_WAIT]:
            acc[p, CA_WAIT] = w
    _count(S, p, s, end)


@jit
def _count(S, p, s, end):  # type: ignore[no-untyped-def]
    """Process._count: the part of ``[s, end)`` inside the metrics window is busy."""
    g = S[FPARAMS]
    lo = s if s > g[G_WARMUP] else g[G_WARMUP]
    hi = end if end < g[G_END] else g[G_END]
    if hi > lo:
        S[CPU_ACC][p, CA_BUSY] += hi - lo


@jit
def _beside(S, p, a, length):  # type: ignore[no-untyped-def]
    """Process.beside: a wake-up's part on the other thread, from ``a`` on a core."""
    m = S[CPU_MACH][p]
    s, c = _place(S, m, a, a, length)
    _reserve(S, m, c, s, s + length)
    _count(S, p, s, s + length)


@jit
def span(S, p, demand, a):  # type: ignore[no-untyped-def]
    """Process.span: a burst of ``demand`` (> 0) CPU seconds of process ``p`` arriving at
    ``a`` (plus the process's wake-up cost if its thread is idle then); its start and end."""
    w = S[CPU_WAKE][p]
    idle = w > 0.0 and a > S[CPU_FREE][p]
    cpu = demand + w if idle else demand
    sc = S[CPU_SCALE][p]
    length = cpu * sc
    side = S[CPU_SIDE][p] if idle and not threaded(S, p) else 0.0
    if side > 0.0:
        side_len = side * sc
        wait = run_wait(S, p, a, cpu + side, length)
        _beside(S, p, a, side_len)
    else:
        wait = run_wait(S, p, a, cpu, length)
    s, c = acquire(S, p, a, length, wait)
    end = s + length
    hold(S, p, a, s, c, end)
    return s, end


@jit
def threaded(S, p):  # type: ignore[no-untyped-def]
    """Process.threaded: process ``p`` has a network thread."""
    return S[CPU_NET][p, 0] > 0.0 or S[CPU_NET][p, 1] > 0.0


@jit
def net_span(S, p, a, gil):  # type: ignore[no-untyped-def]
    """Process.net_span: a burst on process ``p``'s network thread arriving at ``a``
    (with ``gil``, a received copy that waits for the interpreter lock while the loop
    thread is busy, at most the switch, and wakes after it); its start and end."""
    nf = S[CPU_NFREE]
    idle = a > nf[p]
    r = a if idle else nf[p]
    free = S[CPU_FREE][p]
    sw = S[CPU_SWITCH][p]
    if gil and sw > 0.0 and free > r:
        idle = True
        lock = r + sw
        r = free if free < lock else lock
    net = S[CPU_NET]
    cpu = net[p, 0] + net[p, 1] if idle else net[p, 0]
    sc = S[CPU_SCALE][p]
    length = cpu * sc
    side = S[CPU_SIDE][p] if idle else 0.0
    wait = run_wait(S, p, a, cpu + side, length)
    if side > 0.0:
        _beside(S, p, a, side * sc)
    m = S[CPU_MACH][p]
    s, c = _place(S, m, a, r + wait, length)
    end = s + length
    _reserve(S, m, c, s, end)
    nf[p] = end
    _count(S, p, s, end)
    return s, end


@jit
def burst(S, p, demand, a):  # type: ignore[no-untyped-def]
    """Process.burst: a burst's end (:func:`span`)."""
    return span(S, p, demand, a)[1]


@jit
def tick(S, p, demand, t):  # type: ignore[no-untyped-def]
    """A burst called from Python (the server's alignment tick); its end."""
    return burst(ref(S), p, demand, t)
