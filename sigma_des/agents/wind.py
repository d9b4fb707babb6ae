"""Wind at each aircraft: a decaying mean wind with shear plus seeded Dryden turbulence.

Mean wind (NED, m/s) = ``w0 * exp(-t / tau) * (h / h_ref) ** shear`` — the
"decaying mean wind" of the paper, with an optional power-law shear profile
(``shear = 1/7`` is the classic neutral-atmosphere exponent; 0 disables it).

Turbulence follows the MIL-F-8785C low-altitude Dryden model: scale lengths
``L_w = h``, ``L_u = L_v = h / (0.177 + 0.000823 h)^1.2`` and intensities
``sigma_w = 0.1 W20``, ``sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4``
(h and L in feet, clipped to 10..1000 ft), ``W20`` the wind speed at 20 ft. Each
component is realised as a first-order Gauss–Markov process with the Dryden
correlation time ``L / V`` (exact for ``u``, a first-order approximation of the
second-order ``v``/``w`` filters), discretised exactly over the frame step::

    x_{k+1} = a x_k + sigma sqrt(1 - a^2) eta_k,   a = exp(-V dt / L)

so its variance is ``sigma^2`` whatever ``dt`` is. The filters are updated at
``turb_rate`` (default 20 Hz) over the whole elapsed number of periods exactly: the
correlation times are seconds, so a 20 Hz sample-and-hold is more than ten samples per
correlation time, at a fifth of a per-frame update's cost. ``eta`` are counter-based
normals keyed by (node id, update index, component) — the update index is ``floor(t *
turb_rate)`` of the row's own time — so rolling a node back and re-running reproduces
the same gusts, and the gusts do not depend on the frame rate (an adaptive ``f_trig``
sees the same turbulence). The filter states are state columns, held constant over the
kernel's sub-steps. Components are in along-heading / cross / down axes and rotated to
NED with the aircraft's heading."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.core.counter_rng import absorb, normal_at
from sigma_des.errors import ConfigError

__all__ = ["WindConfig", "mean_wind", "dryden_scales", "turbulence_update"]

_FT = 0.3048


@dataclass(frozen=True)
class WindConfig:
    """Wind field parameters (all zero = still air).

    Attributes:
        mean_ned: initial mean wind (north, east, down), m/s.
        decay_tau: e-folding time of the mean wind (s); ``inf`` keeps it constant.
        shear: power-law shear exponent (0 = uniform with height).
        h_ref: reference height of ``mean_ned`` for the shear profile (m).
        w20: Dryden turbulence reference wind at 20 ft (m/s); 0 disables
            turbulence (MIL-F-8785C: 7.7 m/s light, 15.4 moderate, 23.1 severe).
        turb_rate: update rate of the turbulence filters (Hz), see the module doc.
    """

    mean_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)
    decay_tau: float = math.inf
    shear: float = 0.0
    h_ref: float = 10.0
    w20: float = 0.0
    turb_rate: float = 20.0

    def __post_init__(self) -> None:
        if not (self.turb_rate > 0 and math.isfinite(self.turb_rate)):
            raise ConfigError("wind.turb_rate", f"must be a finite rate > 0 Hz, got "
                              f"{self.turb_rate}")
        if len(self.mean_ned) != 3 or not all(math.isfinite(c) for c in self.mean_ned):
            raise ConfigError("wind.mean_ned", f"must be 3 finite numbers, got {self.mean_ned}")
        if not self.decay_tau > 0:
            raise ConfigError("wind.decay_tau",
                              f"must be > 0 (inf = no decay), got {self.decay_tau}")
        if not 0 <= self.shear < 1:
            raise ConfigError("wind.shear", f"must be in [0, 1), got {self.shear}")
        if not self.h_ref > 0:
            raise ConfigError("wind.h_ref", f"must be > 0, got {self.h_ref}")
        if not 0 <= self.w20 < 50:
            raise ConfigError("wind.w20", f"must be in [0, 50) m/s, got {self.w20}")

    def write(self, prm: np.ndarray) -> None:
        """Store these values in an aircraft parameter vector."""
        prm[L.ENV_WN], prm[L.ENV_WE], prm[L.ENV_WD] = self.mean_ned
        prm[L.ENV_TAU] = self.decay_tau if math.isfinite(self.decay_tau) else 0.0
        prm[L.ENV_SHEAR] = self.shear
        prm[L.ENV_HREF] = self.h_ref
        prm[L.ENV_W20] = self.w20
        # ENV_TURB_ON holds the update period (s); 0 = no turbulence.
        prm[L.ENV_TURB_ON] = 1.0 / self.turb_rate if self.w20 > 0 else 0.0


@njit(cache=True)
def mean_wind(prm: np.ndarray, t: float, h: float) -> tuple[float, float, float]:
    """Mean wind NED (m/s) at time ``t`` and altitude ``h`` (``ENV_TAU == 0``: no decay)."""
    k = 1.0
    tau = prm[L.ENV_TAU]
    if tau > 0.0:
        k = math.exp(-t / tau)
    sh = prm[L.ENV_SHEAR]
    if sh > 0.0:
        k *= (max(h, 0.5) / prm[L.ENV_HREF]) ** sh
    return prm[L.ENV_WN] * k, prm[L.ENV_WE] * k, prm[L.ENV_WD] * k


@njit(cache=True)
def dryden_scales(h: float, w20: float) -> tuple[float, float, float, float]:
    """MIL-F-8785C low-altitude Dryden ``(L_uv, L_w, sigma_uv, sigma_w)`` in m, m/s."""
    hf = min(max(h / _FT, 10.0), 1000.0)
    den = 0.177 + 0.000823 * hf
    lw = hf * _FT
    sw = 0.1 * w20
    d04 = den ** 0.4                      # one pow: den^1.2 = (den^0.4)^3
    return hf / (d04 * d04 * d04) * _FT, lw, sw / d04, sw


@njit(cache=True, inline="always")
def turbulence_update(x: np.ndarray, prm: np.ndarray, key: np.uint64, node: np.int64,
                      frame: np.int64, dt: float, speed: float) -> None:
    """Advance the turbulence filter states of row ``x`` by ``dt`` (draws keyed by
    ``(node, frame)``; the kernel passes the update index as ``frame``)."""
    luv, lw, suv, sw = dryden_scales(x[L.H], prm[L.ENV_W20])
    spd = max(speed, 1.0)
    auv = math.exp(-spd * dt / luv)
    aw = math.exp(-spd * dt / lw)
    h2 = absorb(absorb(key, node), frame)
    e0, e1, e2 = normal_at(h2, 0), normal_at(h2, 1), normal_at(h2, 2)  # type: ignore[arg-type]
    kuv = suv * math.sqrt(1.0 - auv * auv)
    x[L.TU] = auv * x[L.TU] + kuv * e0
    x[L.TV] = auv * x[L.TV] + kuv * e1
    x[L.TW] = aw * x[L.TW] + sw * math.sqrt(1.0 - aw * aw) * e2
