"""Rotor / propeller thrust and torque from blade-element momentum theory (numba).

For rotor speed ``omega`` (rad/s), radius ``R``, solidity ``sigma`` (blade area /
disc area), lift-curve slope ``a`` and collective pitch at 3/4 radius ``theta``::

    CT = (sigma a / 2) (theta / 3 (1 + 3/2 mu^2) - lambda / 2)        (pitch, advance ratio)
    CQ = sigma cd0 / 8 (1 + 4.65 mu^2) + lambda CT                     (profile + induced/climb)
    T  = CT rho (pi R^2) (omega R)^2,   Q = CQ rho (pi R^2) (omega R)^2 R

(Leishman, *Principles of Helicopter Aerodynamics*, 2nd ed., eqs. 3.46 and 3.95
and §5.4). The inflow ratio ``lambda = lambda_c + lambda_i`` adds the axial
(climb / flight-speed) inflow ``lambda_c = V_axial / (omega R)`` to the induced
inflow from Glauert's formula evaluated with the hover thrust coefficient,
``lambda_i = lambda_h^2 / sqrt(mu^2 + (lambda_c + lambda_h)^2)``; this closed form
avoids a per-step fixed-point iteration and reduces exactly to momentum theory in
hover. ``mu`` is the in-plane (edgewise) advance ratio. The denominator is floored
at ``lambda_h`` so descent through the vortex-ring state stays bounded.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.approx import sqrt

__all__ = ["rotor_constants", "rotor_thrust_torque", "hover_inflow", "static_ct"]


@njit(cache=True, inline="always")
def rotor_constants(prm: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """The rotor constants ``(R, lambda_h, sigma, a, theta, cd0)`` of parameter vector ``prm``."""
    return (prm[L.ROT_R], prm[L.ROT_LAMBDA_H], prm[L.ROT_SIGMA], prm[L.ROT_A],
            prm[L.ROT_THETA], prm[L.ROT_CD0])


@njit(cache=True, inline="always")
def rotor_thrust_torque(rc: tuple, va: float, vt2: float, omega: float,
                        rho: float) -> tuple[float, float]:
    """Thrust (N, along the rotor axis) and shaft torque (N m) of one rotor.

    Args:
        rc: the :func:`rotor_constants`.
        va: air-relative velocity component along the thrust axis (m/s; > 0 when
            the rotor moves in the direction it pushes, i.e. climb / forward flight).
        vt2: squared in-plane air-relative velocity (m^2/s^2).
        omega: rotor speed (rad/s).
        rho: air density (kg/m^3).
    """
    rad, lam_h, sig, a, theta, cd0 = rc
    tip = omega * rad
    if tip < 1e-3:
        return 0.0, 0.0
    lam_c = va / tip
    mu2 = vt2 / (tip * tip)
    den = sqrt(mu2 + (lam_c + lam_h) * (lam_c + lam_h))
    if den < lam_h:
        den = lam_h
    lam = lam_c + lam_h * lam_h / den
    ct = 0.5 * sig * a * (theta / 3.0 * (1.0 + 1.5 * mu2) - 0.5 * lam)
    if ct < 0.0:
        ct = 0.0            # no reverse thrust: a windmilling prop is not modelled
    cq = sig * cd0 / 8.0 * (1.0 + 4.65 * mu2) + lam * ct
    qdyn = rho * math.pi * rad * rad * tip * tip
    return ct * qdyn, cq * qdyn * rad


def hover_inflow(sigma: float, a: float, theta: float) -> tuple[float, float]:
    """Static (hover) inflow ratio and thrust coefficient, solving CT = 2 lambda^2.

    Returns:
        ``(lambda_h, CT_static)``.
    """
    # CT = k (theta/3 - lam/2) with k = sigma a / 2 and CT = 2 lam^2:
    # 2 lam^2 + k lam / 2 - k theta / 3 = 0  ->  positive root.
    k = 0.5 * sigma * a
    lam = (-k / 2 + math.sqrt(k * k / 4 + 8 * k * theta / 3)) / 4
    return lam, 2 * lam * lam


def static_ct(sigma: float, a: float, theta: float) -> float:
    """Static thrust coefficient (rotor convention T / (rho pi R^2 (omega R)^2))."""
    return hover_inflow(sigma, a, theta)[1]
