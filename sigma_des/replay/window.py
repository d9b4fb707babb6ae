"""The dynamic sampling window of the reference paper's eq. (15), and our reading of it.

Eq. (15): ``W = w · (ω · δ_max / ‖δ‖₂ · (|Δθ|_max + π) / π)``, with ``δ_i = v_i − v_{i−1}``.
The paper leaves ``w``, ``ω``, ``δ_max`` and ``‖δ‖₂`` undefined. We read, per knot ``j``
(sample index):

* the **default window** is the ``2w + 1`` samples ``j − w … j + w`` (clipped at the ends);
* ``δ_max`` is the largest ``‖δ_i‖`` in the default window and ``‖δ‖₂`` the root mean
  square of ``‖δ_i‖`` over the whole log, so ``m_v = δ_max / ‖δ‖₂`` says how much more
  abruptly the velocity changes here than on average (≈ 1 in steady flight);
* ``|Δθ|_max`` is the largest change of an Euler angle between consecutive samples in the
  default window (wrapped to [0, π]), so ``m_θ = (|Δθ|_max + π) / π`` lies in [1, 2];
* the product ``ω · m_v · m_θ`` is a *manoeuvre index*. Read literally, W grows with it
  (``direction = "literal"``). We use it the other way round (``direction = "shrink"``,
  the default): ``W_j = w / (ω · m_v · m_θ)``, rounded and clamped to ``0 … w`` — wide
  windows (strong averaging of the tangent) in steady flight, narrow ones where the
  aircraft manoeuvres, where a wide window would smear the turn.

``W_j`` is the half-width (in samples) of the window over which the Hermite tangent at
knot ``j`` is fitted (:mod:`sigma_des.replay.interpolate`). The ablation in
``experiments/interpolation.py`` compares ``fixed`` (W = w everywhere), ``velocity``
(``m_θ = 1``), ``attitude`` (``m_v = 1``), ``both`` and ``literal``; ``none`` is W = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["RULES", "WindowRule", "window_sizes"]

#: Window-rule variants of the ablation.
RULES: tuple[str, ...] = ("none", "fixed", "velocity", "attitude", "both", "literal")


@dataclass(frozen=True)
class WindowRule:
    """Parameters of the dynamic window.

    Attributes:
        rule: one of :data:`RULES` (``both`` is eq. (15) in our reading).
        w: default window half-width, samples (>= 0).
        omega: the scaling constant ω (> 0).
    """

    rule: str = "both"
    w: int = 1
    omega: float = 1.0

    def __post_init__(self) -> None:
        if self.rule not in RULES:
            raise ValueError(f"window rule must be one of {RULES}, got {self.rule!r}")
        if self.w < 0:
            raise ValueError(f"window w must be >= 0 samples, got {self.w}")
        if not (self.omega > 0 and math.isfinite(self.omega)):
            raise ValueError(f"window omega must be > 0, got {self.omega}")


def _window_max(x: NDArray[np.float64], w: int) -> NDArray[np.float64]:
    """``max(x[j-w : j+w+1])`` for every ``j`` (clipped at the ends)."""
    m = x.size
    pad = np.concatenate([np.full(w, -np.inf), x, np.full(w, -np.inf)])
    view = np.lib.stride_tricks.sliding_window_view(pad, 2 * w + 1)
    return np.asarray(view.max(axis=1)[:m])


def window_sizes(
    rule: WindowRule, vel: NDArray[np.float64], att: NDArray[np.float64] | None
) -> NDArray[np.int64]:
    """Tangent-window half-width ``W_j`` (samples) of every knot.

    Args:
        rule: the window rule.
        vel: ``(m, d)`` logged velocities.
        att: ``(m, 3)`` logged Euler angles (rad), or None (attitude term = 1).
    """
    m = vel.shape[0]
    w = rule.w
    if rule.rule == "none" or w == 0 or m < 2:
        return np.zeros(m, dtype=np.int64)
    if rule.rule == "fixed":
        return np.full(m, w, dtype=np.int64)
    d = np.linalg.norm(np.diff(vel, axis=0), axis=1)  # ‖δ_i‖, i = 1..m-1
    d = np.concatenate([[d[0]], d])  # δ_0 := δ_1 (no sample before the first)
    ref = math.sqrt(float(np.mean(d**2)))
    m_v = _window_max(d, w) / ref if ref > 0 else np.ones(m)
    if att is not None and att.shape[0] == m:
        da = np.abs((np.diff(att, axis=0) + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        da = np.concatenate([[da[0]], da])
        m_t = (_window_max(da, w) + np.pi) / np.pi
    else:
        m_t = np.ones(m)
    if rule.rule == "velocity":
        m_t = np.ones(m)
    elif rule.rule == "attitude":
        m_v = np.ones(m)
    index = rule.omega * m_v * m_t
    if rule.rule == "literal":
        raw = w * index
    else:
        with np.errstate(divide="ignore"):
            raw = np.where(index > 0, w / np.maximum(index, 1e-300), w)
    return np.clip(np.rint(raw), 0, w).astype(np.int64)
