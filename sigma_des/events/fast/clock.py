"""Node local clocks in the compiled core (docs/concepts/model.md, Clocks).

:func:`local_time` is :meth:`sigma_des.net.clocks.NodeClocks.local_time` for one
node and time, the same floating point operations in the same order: without NTP
``t + offset + drift * t``; with NTP, after the last sync ``j >= 1`` at or before
``t``, ``t + e_ij + drift * (t - j * period)``, where the residuals ``e_ij`` are a
table Python fills once per run from the very same stream
(:func:`sigma_des.events.fast.tables.clock_tables`). A time beyond the table sets
``ERR_HORIZON`` (the driver then runs the whole run per message).
"""

from __future__ import annotations

import numpy as np

from sigma_des.events.fast.codes import I_ERR
from sigma_des.events.fast.compiler import jit
from sigma_des.events.fast.layout import (
    CLOCK_DRIFT,
    CLOCK_OFF,
    ERR_HORIZON,
    INTS,
    NTP_PERIOD,
    NTP_RES,
)

__all__ = ["local_time", "sync_index"]


@jit
def sync_index(t, period):  # type: ignore[no-untyped-def]
    """Index ``j`` of the last NTP sync at or before ``t`` (0: none yet), exactly
    ``max{j : j * period <= t}`` despite the rounding of ``t / period``."""
    j = np.int64(np.floor(t / period))
    if j * period > t:
        j -= 1
    if (j + 1) * period <= t:
        j += 1
    return j if j > 0 else np.int64(0)


@jit
def local_time(S, i, t):  # type: ignore[no-untyped-def]
    """Node ``i``'s clock reading at true time ``t``."""
    drift = S[CLOCK_DRIFT][i]
    period = S[NTP_PERIOD][0]
    if period > 0.0:
        j = sync_index(t, period)
        if j >= 1:
            res = S[NTP_RES]
            if j >= res.shape[1]:
                S[INTS][I_ERR] = ERR_HORIZON
                return t
            return t + res[i, j] + drift * (t - j * period)
    return t + S[CLOCK_OFF][i] + drift * t
