"""Fixed-wing aerodynamic forces and moments, ``1/2 rho V^2 S C`` (numba).

Coefficient models are the linear stability-derivative form of Beard & McLain,
*Small Unmanned Aircraft* (2012), ch. 4: lift, drag and side force and the roll,
pitch and yaw moments are linear in angle of attack ``alpha``, sideslip ``beta``,
the non-dimensional rates ``p b/2V``, ``q c/2V``, ``r b/2V`` and the aileron,
elevator and rudder deflections. Lift is clipped at ``+-CLmax`` (a crude stall),
drag is the parabolic polar ``CD0 + k CL^2 + CDde |de|``.

Drag acts against the air-relative velocity vector and lift perpendicular to it
in the body x-z plane, so the model stays meaningful at any flow direction; that
is what lets a multirotor use the same code as a pure bluff body: a preset with
zero span (``AERO_B == 0``) gets drag only, with no alpha/beta trigonometry.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.approx import asin_fast, atan2_fast, sqrt

__all__ = ["bluff_body_forces", "aero_forces"]


@njit(cache=True, inline="always")
def _drag_only(qs: float, cd0: float, vt: float, ur: float, vr: float, wr: float
               ) -> tuple[float, float, float, float, float, float]:
    f = -qs * cd0 / vt
    return f * ur, f * vr, f * wr, 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def bluff_body_forces(prm: np.ndarray, ur: float, vr: float, wr: float, rho: float
                      ) -> tuple[float, float, float, float, float, float]:
    """:func:`aero_forces` of a preset with zero span (``AERO_B == 0``): drag only, along -V."""
    area, cd0 = prm[L.AERO_S], prm[L.CD0]
    v2 = ur * ur + vr * vr + wr * wr
    if v2 < 1e-4:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return _drag_only(0.5 * rho * v2 * area, cd0, sqrt(v2), ur, vr, wr)


@njit(cache=True, inline="always")
def aero_forces(prm: np.ndarray, ur: float, vr: float, wr: float, p: float, q: float,
                r: float, da: float, de: float, dr: float, rho: float
                ) -> tuple[float, float, float, float, float, float]:
    """Body-axis aerodynamic force (N) and moment (N m) about the centre of gravity.

    Args:
        prm: aircraft parameter vector (layout.py).
        ur, vr, wr: air-relative body velocity (m/s).
        p, q, r: body rates (rad/s).
        da, de, dr: aileron, elevator, rudder deflections (rad).
        rho: air density (kg/m^3).

    Returns:
        ``(Fx, Fy, Fz, L, M, N)``.
    """
    # Every parameter is read before the first branch, so the vectorised kernel
    # (kernel.py) holds no array reference across the branches.
    area, b, c = prm[L.AERO_S], prm[L.AERO_B], prm[L.AERO_C]
    cl0, cla, clq, clde, clmax = prm[L.CL0], prm[L.CLA], prm[L.CLQ], prm[L.CLDE], prm[L.CLMAX]
    cd0, cdk, cdde = prm[L.CD0], prm[L.CDK], prm[L.CDDE]
    cyb, cyp, cyr, cyda, cydr = prm[L.CYB], prm[L.CYP], prm[L.CYR], prm[L.CYDA], prm[L.CYDR]
    clb, clp, clr, clda, cldr = prm[L.CLB], prm[L.CLP], prm[L.CLR], prm[L.CLDA], prm[L.CLDR]
    cm0, cma, cmq, cmde = prm[L.CM0], prm[L.CMA], prm[L.CMQ], prm[L.CMDE]
    cnb, cnp, cnr, cnda, cndr = prm[L.CNB], prm[L.CNP], prm[L.CNR], prm[L.CNDA], prm[L.CNDR]
    v2 = ur * ur + vr * vr + wr * wr
    if v2 < 1e-4:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    vt = sqrt(v2)
    qs = 0.5 * rho * v2 * area
    if b == 0.0:
        return _drag_only(qs, cd0, vt, ur, vr, wr)
    # Polynomial atan2/asin (approx.py, 1e-5 rad): two libm calls per sub-step saved;
    # 1e-5 rad of alpha is 6e-5 in CL, far below the model's own accuracy.
    alpha = atan2_fast(wr, ur)
    beta = asin_fast(vr / vt)
    pn = p * b / (2.0 * vt)
    qn = q * c / (2.0 * vt)
    rn = r * b / (2.0 * vt)
    cl = cl0 + cla * alpha + clq * qn + clde * de
    if cl > clmax:
        cl = clmax
    elif cl < -clmax:
        cl = -clmax
    cd = cd0 + cdk * cl * cl + cdde * abs(de)
    cy = cyb * beta + cyp * pn + cyr * rn + cyda * da + cydr * dr
    # Lift direction: perpendicular to V in the x-z plane, (sin a, 0, -cos a).
    vxz = sqrt(ur * ur + wr * wr)
    if vxz > 1e-6:
        sa = wr / vxz
        ca = ur / vxz
    else:
        sa = 0.0
        ca = 1.0
    fd = -qs * cd / vt
    fx = fd * ur + qs * cl * sa
    fy = fd * vr + qs * cy
    fz = fd * wr - qs * cl * ca
    lm = qs * b * (clb * beta + clp * pn + clr * rn + clda * da + cldr * dr)
    mm = qs * c * (cm0 + cma * alpha + cmq * qn + cmde * de)
    nm = qs * b * (cnb * beta + cnp * pn + cnr * rn + cnda * da + cndr * dr)
    return fx, fy, fz, lm, mm, nm
