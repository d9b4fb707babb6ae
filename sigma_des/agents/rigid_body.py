"""6-DoF rigid-body equations of motion and attitude kinematics (numba).

Body axes x forward, y right, z down; the attitude is a unit quaternion (scalar
first) rotating body vectors into NED. Translational equations are written for the
body-axis ground velocity (Beard & McLain 2012, eqs. 3.14–3.17, with the
``Ixz`` product of inertia via their Gamma constants). One integrator serves every
aircraft type: a semi-implicit step (velocities and rates by explicit Euler from
the forces at the start of the sub-step, position and attitude with the average of
old and new velocities), which is exact for constant accelerations (free fall)
and needs one force evaluation per sub-step — the kernel's main cost. The
quaternion is renormalised after every sub-step, so it stays unit-norm to
rounding error indefinitely.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.approx import sqrt

__all__ = ["euler_of", "rotmat_q", "rotmat", "to_ned", "to_body", "rigid_body_update",
           "rigid_body_substep"]


@njit(cache=True, inline="always")
def euler_of(x: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad, ZYX convention) of the quaternion in state row ``x``."""
    q0, q1, q2, q3 = x[L.Q0], x[L.Q1], x[L.Q2], x[L.Q3]
    phi = math.atan2(2.0 * (q0 * q1 + q2 * q3), 1.0 - 2.0 * (q1 * q1 + q2 * q2))
    s = min(max(2.0 * (q0 * q2 - q3 * q1), -1.0), 1.0)
    theta = math.asin(s)
    psi = math.atan2(2.0 * (q0 * q3 + q1 * q2), 1.0 - 2.0 * (q2 * q2 + q3 * q3))
    return phi, theta, psi


@njit(cache=True, inline="always")
def rotmat_q(q0: float, q1: float, q2: float, q3: float
             ) -> tuple[float, float, float, float, float, float, float, float, float]:
    """Body->NED rotation matrix of quaternion ``(q0, q1, q2, q3)``, row-major."""
    return (1.0 - 2.0 * (q2 * q2 + q3 * q3), 2.0 * (q1 * q2 - q0 * q3), 2.0 * (q1 * q3 + q0 * q2),
            2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q1 * q1 + q3 * q3), 2.0 * (q2 * q3 - q0 * q1),
            2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1), 1.0 - 2.0 * (q1 * q1 + q2 * q2))


@njit(cache=True, inline="always")
def rotmat(x: np.ndarray) -> tuple[float, float, float, float, float, float, float, float, float]:
    """Body->NED rotation matrix of row ``x``, row-major ``(r00, r01, ..., r22)``."""
    return rotmat_q(x[L.Q0], x[L.Q1], x[L.Q2], x[L.Q3])


@njit(cache=True, inline="always")
def to_ned(rm: tuple, a: float, b: float, c: float) -> tuple[float, float, float]:
    """Rotate body vector ``(a, b, c)`` to NED with matrix ``rm`` (from :func:`rotmat`)."""
    return (rm[0] * a + rm[1] * b + rm[2] * c, rm[3] * a + rm[4] * b + rm[5] * c,
            rm[6] * a + rm[7] * b + rm[8] * c)


@njit(cache=True, inline="always")
def to_body(rm: tuple, n: float, e: float, d: float) -> tuple[float, float, float]:
    """Rotate NED vector ``(n, e, d)`` to body axes (transpose of ``rm``)."""
    return (rm[0] * n + rm[3] * e + rm[6] * d, rm[1] * n + rm[4] * e + rm[7] * d,
            rm[2] * n + rm[5] * e + rm[8] * d)


@njit(cache=True, inline="always")
def rigid_body_update(prm: np.ndarray, rm: tuple, u: float, v: float, w: float, p: float,
                      q: float, r: float, q0: float, q1: float, q2: float, q3: float,
                      fx: float, fy: float, fz: float, lm: float, mm: float, nm: float,
                      g: float, h: float) -> tuple[float, float, float, float, float, float,
                                                   float, float, float, float, float, float,
                                                   float]:
    """One sub-step of the rigid body as a pure function of scalars (see module doc).

    The kernel calls it on a block of aircraft held column-wise, so the compiler can
    run several aircraft per instruction; :func:`rigid_body_substep` is the same step
    on one state row.

    Args:
        prm: aircraft parameter vector (mass and inertia are read).
        rm: rotation matrix at the start of the sub-step (:func:`rotmat`).
        u, v, w: body ground velocity (m/s).
        p, q, r: body rates (rad/s).
        q0, q1, q2, q3: attitude quaternion.
        fx, fy, fz: non-gravitational body force (N).
        lm, mm, nm: body moment about the centre of gravity (N m).
        g: gravitational acceleration (m/s^2).
        h: sub-step (s).

    Returns:
        New ``(u, v, w, p, q, r, q0, q1, q2, q3)`` and the NED displacement over the
        sub-step ``(h dn, h de, h dd)`` (down positive; altitude decreases by it).
    """
    m = prm[L.MASS]
    ixx, iyy, izz, ixz = prm[L.IXX], prm[L.IYY], prm[L.IZZ], prm[L.IXZ]
    # Gravity in body axes: third row of the body->NED rotation times g.
    gx, gy, gz = rm[6] * g, rm[7] * g, rm[8] * g
    du = r * v - q * w + fx / m + gx
    dv = p * w - r * u + fy / m + gy
    dw = q * u - p * v + fz / m + gz
    if ixz == 0.0:
        # Principal axes: the exact textbook form, so a pure roll moment gives
        # dp/dt = L / Ixx to the last bit.
        dp = ((iyy - izz) * q * r + lm) / ixx
        dq = ((izz - ixx) * p * r + mm) / iyy
        dr = ((ixx - iyy) * p * q + nm) / izz
    else:
        gam = ixx * izz - ixz * ixz
        g1 = ixz * (ixx - iyy + izz) / gam
        g2 = (izz * (izz - iyy) + ixz * ixz) / gam
        g7 = ((ixx - iyy) * ixx + ixz * ixz) / gam
        dp = g1 * p * q - g2 * q * r + (izz * lm + ixz * nm) / gam
        dq = (izz - ixx) / iyy * p * r - ixz / iyy * (p * p - r * r) + mm / iyy
        dr = g7 * p * q - g1 * q * r + (ixz * lm + ixx * nm) / gam
    un, vn_, wn = u + h * du, v + h * dv, w + h * dw
    pn, qn, rn = p + h * dp, q + h * dq, r + h * dr
    # Position with the average body velocity, rotated by the start attitude.
    ua, va, wa = 0.5 * (u + un), 0.5 * (v + vn_), 0.5 * (w + wn)
    dn, de, dd = to_ned(rm, ua, va, wa)
    # Quaternion kinematics with the average rate, then renormalise.
    pa, qa, ra = 0.5 * (p + pn) * 0.5 * h, 0.5 * (q + qn) * 0.5 * h, 0.5 * (r + rn) * 0.5 * h
    n0 = q0 - q1 * pa - q2 * qa - q3 * ra
    n1 = q1 + q0 * pa + q2 * ra - q3 * qa
    n2 = q2 + q0 * qa - q1 * ra + q3 * pa
    n3 = q3 + q0 * ra + q1 * qa - q2 * pa
    inv = 1.0 / sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)
    return (un, vn_, wn, pn, qn, rn, n0 * inv, n1 * inv, n2 * inv, n3 * inv,
            h * dn, h * de, h * dd)


@njit(cache=True, inline="always")
def rigid_body_substep(x: np.ndarray, prm: np.ndarray, rm: tuple, fx: float, fy: float,
                       fz: float, lm: float, mm: float, nm: float, g: float, h: float) -> None:
    """Advance row ``x`` in place by ``h`` seconds under body force/moment and gravity.

    Args:
        x: one state row (modified in place: velocities, rates, quaternion,
            position, time).
        prm: aircraft parameter vector.
        rm: rotation matrix of ``x`` at the start of the sub-step (:func:`rotmat`).
        fx, fy, fz: non-gravitational body force (N).
        lm, mm, nm: body moment about the centre of gravity (N m).
        g: gravitational acceleration (m/s^2).
        h: sub-step (s).
    """
    (x[L.U], x[L.V], x[L.W], x[L.P], x[L.Q], x[L.R], x[L.Q0], x[L.Q1], x[L.Q2], x[L.Q3],
     dn, de, dd) = rigid_body_update(prm, rm, x[L.U], x[L.V], x[L.W], x[L.P], x[L.Q], x[L.R],
                                     x[L.Q0], x[L.Q1], x[L.Q2], x[L.Q3], fx, fy, fz, lm, mm,
                                     nm, g, h)
    x[L.XN] += dn
    x[L.YE] += de
    x[L.H] -= dd
    x[L.TIME] += h
