"""Force and moment assembly of the general aircraft: rotors + aerodynamics (numba).

Every preset is the same model with different parameters: ``NROT`` rotors (each
with a position, a thrust axis and a spin sign) plus one aerodynamic body. The
air-relative velocity (ground velocity minus wind) feeds both, so wind and
turbulence act on multirotors and fixed wings alike. Gravity is added by the
rigid-body step. Rotor-disc rotational velocity (``omega x r``) is neglected.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.aero import aero_forces
from sigma_des.agents.rotor import rotor_constants, rotor_thrust_torque

__all__ = ["rotor_geometry", "rotor_contribution", "forces_moments"]


@njit(cache=True, inline="always")
def rotor_geometry(prm: np.ndarray, i: int) -> tuple[float, float, float, float, float, float,
                                                      float]:
    """Rotor ``i``'s position (m), thrust axis and spin sign ``(px, py, pz, ex, ey, ez, spin)``."""
    k = L.ROTOR_BASE + L.ROTOR_STRIDE * i
    return prm[k], prm[k + 1], prm[k + 2], prm[k + 3], prm[k + 4], prm[k + 5], prm[k + 6]


@njit(cache=True, inline="always")
def rotor_contribution(prm: np.ndarray, geo: tuple, ur: float, vr: float, wr: float, v2: float,
                       omega: float, rho: float
                       ) -> tuple[float, float, float, float, float, float]:
    """Body force (N) and moment (N m) of one rotor alone (a pure function of scalars).

    Args:
        prm: aircraft parameter vector (the common rotor constants are read).
        geo: the rotor's :func:`rotor_geometry`.
        ur, vr, wr: air-relative body velocity (m/s); ``v2`` its squared norm.
        omega: the rotor's speed (rad/s).
        rho: air density (kg/m^3).
    """
    rc = rotor_constants(prm)
    px, py, pz, ex, ey, ez, spin = geo
    va = ur * ex + vr * ey + wr * ez
    vt2 = v2 - va * va
    if vt2 < 0.0:
        vt2 = 0.0
    thrust, torque = rotor_thrust_torque(rc, va, vt2, omega, rho)
    tx, ty, tz = thrust * ex, thrust * ey, thrust * ez
    # Moment of the thrust about the CG plus the shaft reaction torque, which
    # opposes the rotor's spin vector (spin * axis).
    return (tx, ty, tz, py * tz - pz * ty - spin * torque * ex,
            pz * tx - px * tz - spin * torque * ey, px * ty - py * tx - spin * torque * ez)


@njit(cache=True, inline="always")
def forces_moments(x: np.ndarray, prm: np.ndarray, bx: float, by: float, bz: float,
                   rho: float) -> tuple[float, float, float, float, float, float]:
    """Body force (N) and moment (N m) of rotors and aerodynamics for state row ``x``.

    The rotors' contributions are added to the aerodynamic ones in rotor order (the
    kernel sums them in the same order, so both give the same bits).

    Args:
        x: one state row (layout.py); rotor speeds and surfaces are read from it.
        prm: aircraft parameter vector.
        bx, by, bz: wind at the aircraft in body axes (m/s).
        rho: air density (kg/m^3).
    """
    ur, vr, wr = x[L.U] - bx, x[L.V] - by, x[L.W] - bz
    fx, fy, fz, lm, mm, nm = aero_forces(prm, ur, vr, wr, x[L.P], x[L.Q], x[L.R],
                                         x[L.DA], x[L.DE], x[L.DR], rho)
    v2 = ur * ur + vr * vr + wr * wr
    for i in range(int(prm[L.NROT])):
        tx, ty, tz, dl, dm, dn = rotor_contribution(prm, rotor_geometry(prm, i), ur, vr, wr, v2,
                                                 x[L.OM0 + i], rho)
        fx += tx
        fy += ty
        fz += tz
        lm += dl
        mm += dm
        nm += dn
    return fx, fy, fz, lm, mm, nm
