"""Time-dependent link loss and delay in the compiled core (docs/concepts/model.md, "Network").

:func:`link_loss` is :meth:`sigma_des.net.links.Links._loss_at` in compiled form:
the loss probability of a packet sent at ``t`` on a client's access link —
Gilbert–Elliott's ``loss_bad`` or ``loss_good`` per the chain's state in the
send time's slot, else the Bernoulli ``p`` — then every ``degrade`` window of the
link active at ``t``, in fault order, adds its delay and combines its loss as
``p = 1 - (1 - p)(1 - q)``. :func:`forced_drop` is the ``drop`` faults' lookup.
The chain states, windows and keys are tables Python builds once per run
(:mod:`sigma_des.events.fast.tables`, from the very objects the per-message
engine reads); a send time beyond the chain table sets ``ERR_HORIZON`` (the
driver then runs the whole run per message).
"""

from __future__ import annotations

import numpy as np

from sigma_des.events.fast.codes import I_ERR
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.layout import (
    DEG,
    DEG_PTR,
    DROPS,
    ERR_HORIZON,
    GE_BAD,
    GE_PAR,
    INTS,
    LINK_DYN,
    LINK_OF,
    P_LOSS,
)

__all__ = ["ge_slot", "link_loss", "forced_drop"]


@jit
def ge_slot(t, slot):  # type: ignore[no-untyped-def]
    """The Gilbert–Elliott slot of send time ``t`` (LossProcess.bad_state's floor)."""
    return np.int64(np.floor(t / slot))


@jit
def link_loss(S, client, cls, up, t):  # type: ignore[no-untyped-def]
    """Loss probability and extra delay of a packet ``client`` sends (or receives) at ``t``.

    Args:
        S: the core's state.
        client: the node or server whose access link carries the packet.
        cls: its link class (0 host, 1 server).
        up: 1 on the uplink, 0 on the downlink.
        t: the send time.

    Returns:
        ``(p, extra)``: the loss probability and the extra delay (0.0 when no
        degrade window is active), the per-message engine's arithmetic exactly.
    """
    dyn = S[LINK_DYN]
    p = S[P_LOSS][cls]
    extra = 0.0
    if dyn[cls] == 0 and dyn[2] == 0:
        return p, extra
    link = S[LINK_OF][client]
    if dyn[cls] != 0:
        par = S[GE_PAR]
        bad = S[GE_BAD]
        s = ge_slot(t, par[cls, 0])
        if s >= bad.shape[2]:
            S[INTS][I_ERR] = ERR_HORIZON
        elif bad[up, link, s] != 0:
            p = par[cls, 2]
        else:
            p = par[cls, 1]
    if dyn[2] != 0:
        ptr = S[DEG_PTR]
        w = S[DEG]
        for j in range(ptr[link], ptr[link + 1]):
            if w[j, 0] <= t and t < w[j, 1]:
                extra += w[j, 2]
                p = 1.0 - (1.0 - p) * (1.0 - w[j, 3])
    return p, extra


@jit
def _before(d, m, kind, subj, index):  # type: ignore[no-untyped-def]
    """Whether row ``m`` of the sorted key table comes before ``(kind, subj, index)``."""
    if d[m, 0] != kind:
        return d[m, 0] < kind
    if d[m, 1] != subj:
        return d[m, 1] < subj
    return d[m, 2] < index


@jit
def forced_drop(S, up, kind, subj, index):  # type: ignore[no-untyped-def]
    """Whether a ``drop`` fault loses this first transmission (downlinks only)."""
    if up != 0 or S[LINK_DYN][3] == 0:
        return False
    d = S[DROPS]
    lo = 0
    hi = d.shape[0]
    while lo < hi:  # binary search of the first row not before the key
        mid = (lo + hi) >> 1
        if _before(d, mid, kind, subj, index):
            lo = mid + 1
        else:
            hi = mid
    return lo < d.shape[0] and d[lo, 0] == kind and d[lo, 1] == subj and d[lo, 2] == index
