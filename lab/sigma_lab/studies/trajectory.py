"""Trajectory metrics of a formation flight: distance to slot, convergence, turn window.

Pure functions of logged positions (no engine, no aircraft model): the formation
study (``experiments/formation.py``) feeds them the true positions of a run and the
slot geometry of its behaviour (a callable, so this module knows no behaviour).

* :func:`slot_distances` — every node's horizontal distance to its slot and vertical
  distance to the leader's altitude, and the leader's course over ground;
* :func:`window_end` — where the convergence window ends: the leader's first turn;
* :func:`convergence_time` — the first time after which a distance stays below a
  threshold up to the window's end.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["SlotsAt", "convergence_time", "slot_distances", "window_end"]

Array = NDArray[np.float64]
#: ``slots_at(positions (n, 3), leader course (rad))`` → ``(n, 2)`` north/east slots.
SlotsAt = Callable[[Array, float], Array]


def slot_distances(
    t: Array, pos: Array, leader: int, slots_at: SlotsAt
) -> tuple[Array, Array, Array]:
    """Horizontal and vertical distance of every node to its slot, and the leader course.

    Args:
        t: ``(T,)`` sample times.
        pos: ``(T, n, 3)`` true positions (north, east, altitude).
        leader: the leader's node index.
        slots_at: the formation's slots given the positions and the leader's course.

    Returns:
        ``(dh (T, n), dv (T, n), course (T,))``; the leader's entries are 0.
    """
    lead = pos[:, leader, :2]
    vel = np.gradient(lead, t, axis=0) if len(t) > 1 else np.zeros_like(lead)
    course = np.arctan2(vel[:, 1], vel[:, 0])
    dh = np.empty(pos.shape[:2])
    for k in range(len(t)):
        slots = slots_at(pos[k], float(course[k]))
        dh[k] = np.hypot(pos[k, :, 0] - slots[:, 0], pos[k, :, 1] - slots[:, 1])
    dv = np.abs(pos[:, :, 2] - pos[:, leader, 2][:, None])
    return dh, dv, course


def window_end(t: Array, course: Array, turn_deg: float, turn_start_deg: float) -> float:
    """End of the convergence window: the leader's first turn, or the end of the flight.

    A turn is a course more than ``turn_deg`` off the initial one (after 1 s); the
    window ends where that turn began, the last sample within ``turn_start_deg`` of
    the initial course (the slots start to swing as soon as the leader banks).
    """
    if len(t) < 2:
        return float(t[-1]) if len(t) else 0.0
    c0 = course[min(len(course) - 1, 3)]  # initial course (skip edge samples)
    dev = np.abs((course - c0 + np.pi) % (2 * np.pi) - np.pi)
    off = np.nonzero((dev > math.radians(turn_deg)) & (t > 1.0))[0]
    if not off.size:
        return float(t[-1])
    calm = np.nonzero(dev[: off[0]] <= math.radians(turn_start_deg))[0]
    return float(t[calm[-1]]) if calm.size else float(t[off[0]])


def convergence_time(t: Array, d: Array, threshold: float, t_end: float) -> float:
    """First time after which ``d`` stays below ``threshold`` up to ``t_end`` (NaN: never)."""
    inside = t <= t_end + 1e-9
    tt, dd = t[inside], d[inside]
    if tt.size == 0 or dd[-1] >= threshold:
        return math.nan
    above = np.nonzero(dd >= threshold)[0]
    return float(tt[0]) if above.size == 0 else float(tt[above[-1] + 1])
