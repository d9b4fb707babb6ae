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
from sigma_des.agents.rotor import rotor_thrust_torque

__all__ = ["forces_moments"]


@njit(cache=True, inline="always")
def forces_moments(x: np.ndarray, prm: np.ndarray, bx: float, by: float, bz: float,
                   rho: float) -> tuple[float, float, float, float, float, float]:
    """Body force (N) and moment (N m) of rotors and aerodynamics for state row ``x``.

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
        k = L.ROTOR_BASE + L.ROTOR_STRIDE * i
        px, py, pz = prm[k], prm[k + 1], prm[k + 2]
        ex, ey, ez = prm[k + 3], prm[k + 4], prm[k + 5]
        spin = prm[k + 6]
        va = ur * ex + vr * ey + wr * ez
        vt2 = v2 - va * va
        if vt2 < 0.0:
            vt2 = 0.0
        thrust, torque = rotor_thrust_torque(prm, va, vt2, x[L.OM0 + i], rho)
        tx, ty, tz = thrust * ex, thrust * ey, thrust * ez
        fx += tx
        fy += ty
        fz += tz
        # Moment of the thrust about the CG plus the shaft reaction torque, which
        # opposes the rotor's spin vector (spin * axis).
        lm += py * tz - pz * ty - spin * torque * ex
        mm += pz * tx - px * tz - spin * torque * ey
        nm += px * ty - py * tx - spin * torque * ez
    return fx, fy, fz, lm, mm, nm
