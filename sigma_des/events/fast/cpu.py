"""The CPU stage in the compiled message core (docs/MODEL.md, "Deployment and CPU").

Every process (the broker, the server, each physics host's client process) is one
thread on a machine's cores; a burst is allocated at its arrival, first come first
served — :mod:`sigma_des.net.cpu` (``Process.acquire``, ``hold``, ``burst``) with the
same floating point operations in the same order: the lowest-index core with the
smallest free time, ``s = a if a > thread_free else thread_free; s = s if s >
core_free else core_free``, ``end = s + demand * scale``. Process ``p`` is the
spec's ``Cpu.processes[p]`` (broker, server, hosts); its counters (CPU seconds and
longest wait in the metrics window, bursts) are handed back at the end of the run.
A zero demand is no burst: callers never call :func:`burst` for it.
"""

from __future__ import annotations

from sigma_des.events.fast.layout import (
    CA_BUSY,
    CA_WAIT,
    CPU_ACC,
    CPU_BURSTS,
    CPU_CORE,
    CPU_FREE,
    CPU_MACH,
    CPU_SCALE,
    FPARAMS,
    G_END,
    G_WARMUP,
)
from sigma_des.events.fast.primitives import jit
from sigma_des.events.fast.stateref import ref

__all__ = ["acquire", "burst", "hold", "tick"]


@jit
def acquire(S, p, a):  # type: ignore[no-untyped-def]
    """Process.acquire: start time and core of a burst of process ``p`` arriving at ``a``."""
    row = S[CPU_CORE][S[CPU_MACH][p]]
    c = 0
    for j in range(1, row.shape[0]):  # free.index(min(free)): the first smallest
        if row[j] < row[c]:
            c = j
    tf = S[CPU_FREE][p]
    cf = row[c]
    s = a if a > tf else tf
    s = s if s > cf else cf
    return s, c


@jit
def hold(S, p, a, s, c, end):  # type: ignore[no-untyped-def]
    """Process.hold: the burst arrived at ``a``, started at ``s`` on core ``c``, ends at ``end``."""
    S[CPU_FREE][p] = end
    S[CPU_CORE][S[CPU_MACH][p], c] = end
    g = S[FPARAMS]
    acc = S[CPU_ACC]
    if g[G_WARMUP] <= a and a < g[G_END]:
        S[CPU_BURSTS][p] += 1
        w = s - a
        if w > acc[p, CA_WAIT]:
            acc[p, CA_WAIT] = w
    lo = s if s > g[G_WARMUP] else g[G_WARMUP]
    hi = end if end < g[G_END] else g[G_END]
    if hi > lo:
        acc[p, CA_BUSY] += hi - lo


@jit
def burst(S, p, demand, a):  # type: ignore[no-untyped-def]
    """Process.burst: a burst of ``demand`` (> 0) CPU seconds of process ``p`` arriving at
    ``a``; its end."""
    s, c = acquire(S, p, a)
    end = s + demand * S[CPU_SCALE][p]
    hold(S, p, a, s, c, end)
    return end


@jit
def tick(S, p, demand, t):  # type: ignore[no-untyped-def]
    """A burst called from Python (the server's alignment tick); its end."""
    return burst(ref(S), p, demand, t)
