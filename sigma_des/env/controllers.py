"""Hand-written controllers of the ``tight`` task: baselines for the learners.

Both act on the ``tight`` observation (:class:`~sigma_des.env.tasks.TightTask`) and
command ``v = v_leader + k e`` (m/s; the leader's velocity plus a proportional
correction of the slot error ``e``), clipped to the action box, and an altitude
change of the altitude error:

* :func:`naive` uses the shown slot error as if it were current;
* :func:`extrapolating` first moves the shown states forward: the slot by the
  leader's shown velocity over the leader's age plus ``lead``, the agent by its own
  shown velocity over its own age plus ``lead``, where ``lead`` (the time until the
  command acts) is taken as the agent's own age (the command crosses the same kind
  of links as the state did) — a constant-velocity predictor that ignores turns.

With ages 0 (perfect information) the two are the same controller.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.env.tasks import AGE_REF, TightTask

__all__ = ["naive", "extrapolating"]

Array = NDArray[np.float64]


def _act(obs: NDArray[np.float32], task: TightTask, k: float, predict: bool) -> Array:
    o = obs.astype(np.float64)
    e = o[..., 0:2] * task.d
    v_own, age_own = o[..., 3:5] * task.v_ref, o[..., 5:6] * AGE_REF
    v_lead, age_lead = o[..., 6:8] * task.v_ref, o[..., 8:9] * AGE_REF
    if predict:
        lead = age_own
        e = e + v_lead * (age_lead + lead) - v_own * (age_own + lead)
    v = (v_lead + k * e) / task.v_max
    dh = o[..., 2:3] * 10.0 / task.dh_max
    return np.clip(np.concatenate([v, dh], axis=-1), -1.0, 1.0)


def naive(obs: NDArray[np.float32], task: TightTask, k: float = 1.0) -> Array:
    """Actions ``(..., 3)`` steering to the shown slot (see module docstring)."""
    return _act(obs, task, k, predict=False)


def extrapolating(obs: NDArray[np.float32], task: TightTask, k: float = 1.0) -> Array:
    """Actions ``(..., 3)`` steering to the extrapolated slot (see module docstring)."""
    return _act(obs, task, k, predict=True)
