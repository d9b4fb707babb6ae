"""The compiled step of the general aircraft: blocks of rows, fixed sub-steps (numba).

Rows are advanced in blocks of :data:`LANES` aircraft. A block is copied into a
column-wise scratch (``w[c * LANES + k]`` = column ``c`` of the block's row ``k``)
and each part of a sub-step is one loop over the block's lanes calling a pure
function of scalars (rigid_body.py, forces.py, aero.py, autopilot.py); with the
columns a fixed stride apart the compiler runs several aircraft per SIMD
instruction. SIMD lanes are IEEE operations on separate aircraft (no fused
multiply-add, no ``fastmath``, no cross-lane reduction), so every row gets exactly
the bits the scalar code gives it and the result of row ``i`` does not depend on
the batch it is in or on its position in a block.

Per frame step (held over its sub-steps, one row at a time: these need libm):
air density and gravity at the row's altitude, the Dryden turbulence update (at
its own, lower rate, keyed by node and update index; see wind.py), the wind
vector, the slow autopilot parts. Per sub-step, lane loops: rotation matrix and
autopilot inner loops; first-order actuator lags (exact exponential
discretisation); aerodynamic then per-rotor forces; rigid-body integration.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.aero import aero_forces, bluff_body_forces
from sigma_des.agents.approx import atan2_fast, sqrt
from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar
from sigma_des.agents.autopilot import (
    fixedwing_autopilot,
    fixedwing_prepare,
    multirotor_autopilot,
    multirotor_prepare,
)
from sigma_des.agents.forces import rotor_contribution, rotor_geometry
from sigma_des.agents.rigid_body import rigid_body_update, rotmat_q, to_body, to_ned
from sigma_des.agents.wind import mean_wind, turbulence_update

__all__ = ["LANES", "step_kernel"]

#: Aircraft per block (the scratch is ``NCOL * LANES`` doubles, ~17 kB: in L1).
LANES = 32
# Scratch columns after the state's: rotation matrix (9), NED ground velocity (3),
# NED wind (3, held over the frame), body-axis wind (3), density, gravity, actuator
# commands (7), autopilot set-points (8), body force and moment (6), one rotor speed,
# heading cosine and sine (2).
RM = L.STATE_DIM
VEL = RM + 9
WND = VEL + 3
BW = WND + 3
RHO = BW + 3
GRAV = RHO + 1
ACT = GRAV + 1
PRE = ACT + 7
FRC = PRE + 8
OMI = FRC + 6               # the speed of the rotor being summed (a copy)
HDG = OMI + 1               # heading (cos, sin), per frame
NCOL = HDG + 2


@njit(cache=True)
def step_kernel(state: np.ndarray, command: np.ndarray, act_cmd: np.ndarray, dt: float,
                frame: np.int64, nodes: np.ndarray, prm: np.ndarray, key: np.uint64,
                out: np.ndarray) -> None:
    """Advance every row of ``state`` by ``dt`` into ``out`` (see module docstring).

    Args:
        state: ``(n, STATE_DIM)`` input states (not modified).
        command: ``(n, 4)`` guidance commands (autopilot modes).
        act_cmd: ``(n, 7)`` actuator commands (open-loop mode, ``AP_KIND == 0``).
        dt: frame step (s).
        frame: frame index the step leads to (keys the turbulence draws).
        nodes: ``(n,)`` global node ids (key the turbulence draws).
        prm: aircraft parameter vector.
        key: turbulence stream key (``RandomStreams(seed).stream(...).key``).
        out: ``(n, STATE_DIM)`` output array.
    """
    n = state.shape[0]
    nsub = max(1, int(math.ceil(dt / prm[L.ENV_SUBSTEP] - 1e-9)))
    h = dt / nsub
    am = 1.0 - math.exp(-h / prm[L.TAU_MOTOR])
    asv = 1.0 - math.exp(-h / prm[L.TAU_SERVO])
    x = np.zeros(L.STATE_DIM)
    pre = np.zeros(8)
    memo = np.full(3, np.nan)
    w = np.empty(NCOL * LANES)
    tan_tilt = math.tan(prm[L.GAIN_BASE + 10])
    for b0 in range(0, n, LANES):
        nb = min(LANES, n - b0)
        for k in range(nb):
            for j in range(L.STATE_DIM):
                w[j * LANES + k] = state[b0 + k, j]
        frame_lanes(w, nb)
        for k in range(nb):
            frame_row(w, k, b0 + k, command, act_cmd, dt, nodes, prm, key, tan_tilt, x, pre,
                      memo)
        for _ in range(nsub):
            substep(w, nb, prm, h, am, asv)
        for k in range(nb):
            for j in range(L.STATE_DIM):
                out[b0 + k, j] = w[j * LANES + k]


@njit(cache=True, inline="always")
def _turbulence_periods(memo: np.ndarray, t: float, dt: float, tp: float) -> tuple:
    """Turbulence update indices ``floor(t / tp)``, ``floor((t + dt) / tp)`` (+ 1e-6).

    Rows of a swarm share their time, so the last row's values are reused when ``t``
    is the same (``memo = [t, e0, e1]``; NaN at first: never equal).
    """
    if t != memo[0]:
        memo[0] = t
        memo[1] = math.floor(t / tp + 1e-6)
        memo[2] = math.floor((t + dt) / tp + 1e-6)
    return memo[1], memo[2]


@njit(cache=True, inline="always")
def _store_kinematics(w: np.ndarray, k: int) -> tuple:
    """Store lane ``k``'s rotation matrix and NED ground velocity; returns the matrix."""
    rm = rotmat_q(w[L.Q0 * LANES + k], w[L.Q1 * LANES + k], w[L.Q2 * LANES + k],
                  w[L.Q3 * LANES + k])
    _put3(w, RM, k, rm[0], rm[1], rm[2])
    _put3(w, RM + 3, k, rm[3], rm[4], rm[5])
    _put3(w, RM + 6, k, rm[6], rm[7], rm[8])
    vn, ve, vd = to_ned(rm, w[L.U * LANES + k], w[L.V * LANES + k], w[L.W * LANES + k])
    _put3(w, VEL, k, vn, ve, vd)
    return rm


@njit(cache=True, error_model="numpy")
def frame_lanes(w: np.ndarray, nb: int) -> None:
    """The per-frame kinematics of every lane: rotation matrix, NED velocity, heading."""
    for k in range(nb):
        rm = _store_kinematics(w, k)
        # Heading (cos, sin): turns the turbulence to NED and the roll override.
        hn = sqrt(rm[0] * rm[0] + rm[3] * rm[3])
        ok = hn > 1e-9
        w[HDG * LANES + k] = rm[0] / hn if ok else 1.0
        w[(HDG + 1) * LANES + k] = rm[3] / hn if ok else 0.0


@njit(cache=True)
def frame_row(w: np.ndarray, k: int, i: int, command: np.ndarray, act_cmd: np.ndarray,
              dt: float, nodes: np.ndarray, prm: np.ndarray, key: np.uint64, tan_tilt: float,
              x: np.ndarray, pre: np.ndarray, memo: np.ndarray) -> None:
    """The per-frame part of row ``i``, whose state is lane ``k`` of ``w`` (updated there).

    Reads the kinematics of :func:`frame_lanes`; ``tan_tilt`` is the multirotor's
    ``tan`` of its tilt limit (a per-call constant); ``x`` (a state row), ``pre``
    (set-points) and ``memo`` are scratch.
    """
    kind = int(prm[L.AP_KIND])
    tp = prm[L.ENV_TURB_ON]
    hgt, t = w[L.H * LANES + k], w[L.TIME * LANES + k]
    rm = _rm(w, k)
    vn, ve, vd = w[VEL * LANES + k], w[(VEL + 1) * LANES + k], w[(VEL + 2) * LANES + k]
    heading = (w[HDG * LANES + k], w[(HDG + 1) * LANES + k])
    _, _, rho = isa_scalar(hgt)
    # Wind: mean (at this step's time and altitude) + turbulence in heading axes.
    wn, we, wd = mean_wind(prm, t, hgt)
    if tp > 0.0:
        # Update at the turbulence rate (wind.py): when this frame crosses one or
        # more multiples of the period tp, over exactly the periods crossed.
        e0, e1 = _turbulence_periods(memo, t, dt, tp)
        if e1 > e0:
            spd = sqrt((vn - wn) ** 2 + (ve - we) ** 2 + (vd - wd) ** 2)
            x[L.H] = hgt
            x[L.TU], x[L.TV], x[L.TW] = (w[L.TU * LANES + k], w[L.TV * LANES + k],
                                         w[L.TW * LANES + k])
            turbulence_update(x, prm, key, nodes[i], np.int64(e1), (e1 - e0) * tp, spd)
            _put3(w, L.TU, k, x[L.TU], x[L.TV], x[L.TW])
        ch, sh = heading
        tu, tv = w[L.TU * LANES + k], w[L.TV * LANES + k]
        wn += ch * tu - sh * tv
        we += sh * tu + ch * tv
        wd += w[L.TW * LANES + k]
    if kind != 0:
        # NaN in v / chi / h = keep the current value (resolved per step).
        c0, c1, c2 = command[i, 0], command[i, 1], command[i, 2]
        cmd = (c0 if c0 == c0 else sqrt(vn * vn + ve * ve),
               c1 if c1 == c1 else atan2_fast(rm[3], rm[0]),
               c2 if c2 == c2 else hgt, command[i, 3])
        if kind == 1:
            multirotor_prepare(prm, cmd, rm, heading, tan_tilt, pre)
        else:
            fixedwing_prepare(prm, cmd, vn, ve, pre)
    else:
        for j in range(7):
            w[(ACT + j) * LANES + k] = act_cmd[i, j]
    for j in range(8):
        w[(PRE + j) * LANES + k] = pre[j]
    _put3(w, WND, k, wn, we, wd)
    w[RHO * LANES + k] = rho
    w[GRAV * LANES + k] = gravity_scalar(hgt)


@njit(cache=True, error_model="numpy")
def substep(w: np.ndarray, nb: int, prm: np.ndarray, h: float, am: float, asv: float) -> None:
    """One sub-step of the ``nb`` lanes of block ``w``: a sequence of lane loops."""
    kind = int(prm[L.AP_KIND])
    kinematics_lanes(w, nb)
    if kind == 1:
        multirotor_lanes(w, nb, prm, h)
    elif kind == 2:
        fixedwing_lanes(w, nb, prm, h)
    nrot = int(prm[L.NROT])
    for j in range(nrot):
        _lag_lanes(_column(w, L.OM0 + j), _column(w, ACT + j), nb, am)
    _lag_lanes(_column(w, L.DA), _column(w, ACT + 4), nb, asv)
    _lag_lanes(_column(w, L.DE), _column(w, ACT + 5), nb, asv)
    _lag_lanes(_column(w, L.DR), _column(w, ACT + 6), nb, asv)
    aero_lanes(w, nb, prm)
    if nrot == 4:
        four_rotor_lanes(w, nb, prm)
    else:
        for j in range(nrot):
            rotor_lanes(w, nb, prm, j)
    rigid_body_lanes(w, nb, prm, h)


@njit(cache=True, inline="always")
def _column(w: np.ndarray, c: int) -> np.ndarray:
    """Column ``c`` of block ``w`` as a view (lane ``k`` is element ``k``)."""
    return w[c * LANES:(c + 1) * LANES]


@njit(cache=True, error_model="numpy")
def _lag_lanes(x: np.ndarray, u: np.ndarray, nb: int, gain: float) -> None:
    """First-order lag of lanes ``x`` towards ``u`` (gain ``1 - exp(-h / tau)``)."""
    for k in range(nb):
        x[k] += gain * (u[k] - x[k])


@njit(cache=True, inline="always")
def _put3(w: np.ndarray, c: int, k: int, a: float, b: float, d: float) -> None:
    """Store ``a, b, d`` in columns ``c, c + 1, c + 2`` of lane ``k``."""
    w[c * LANES + k] = a
    w[(c + 1) * LANES + k] = b
    w[(c + 2) * LANES + k] = d


@njit(cache=True, inline="always")
def _rm(w: np.ndarray, k: int) -> tuple:
    """The rotation matrix of lane ``k`` (stored by :func:`kinematics_lanes`)."""
    return (w[RM * LANES + k], w[(RM + 1) * LANES + k], w[(RM + 2) * LANES + k],
            w[(RM + 3) * LANES + k], w[(RM + 4) * LANES + k], w[(RM + 5) * LANES + k],
            w[(RM + 6) * LANES + k], w[(RM + 7) * LANES + k], w[(RM + 8) * LANES + k])


@njit(cache=True, inline="always")
def _pre(w: np.ndarray, k: int) -> tuple:
    """The autopilot set-points of lane ``k`` (stored by :func:`frame_row`)."""
    return (w[PRE * LANES + k], w[(PRE + 1) * LANES + k], w[(PRE + 2) * LANES + k],
            w[(PRE + 3) * LANES + k], w[(PRE + 4) * LANES + k], w[(PRE + 5) * LANES + k],
            w[(PRE + 6) * LANES + k], w[(PRE + 7) * LANES + k])


@njit(cache=True, error_model="numpy")
def kinematics_lanes(w: np.ndarray, nb: int) -> None:
    """Rotation matrix, NED ground velocity and body-axis wind of every lane."""
    for k in range(nb):
        rm = _store_kinematics(w, k)
        bx, by, bz = to_body(rm, w[WND * LANES + k], w[(WND + 1) * LANES + k],
                             w[(WND + 2) * LANES + k])
        _put3(w, BW, k, bx, by, bz)


@njit(cache=True, error_model="numpy")
def multirotor_lanes(w: np.ndarray, nb: int, prm: np.ndarray, h: float) -> None:
    """The multirotor cascade of every lane: integrators and actuator commands."""
    for k in range(nb):
        res = multirotor_autopilot(
            prm, _pre(w, k), _rm(w, k), w[VEL * LANES + k], w[(VEL + 1) * LANES + k],
            w[(VEL + 2) * LANES + k], w[GRAV * LANES + k], h, w[L.H * LANES + k],
            w[L.P * LANES + k], w[L.Q * LANES + k], w[L.R * LANES + k],
            w[L.I0 * LANES + k], w[L.I1 * LANES + k], w[L.I2 * LANES + k])
        _store_autopilot(w, k, res)


@njit(cache=True, error_model="numpy")
def fixedwing_lanes(w: np.ndarray, nb: int, prm: np.ndarray, h: float) -> None:
    """The fixed-wing autopilot of every lane: integrators and actuator commands."""
    for k in range(nb):
        ur = w[L.U * LANES + k] - w[BW * LANES + k]
        vr = w[L.V * LANES + k] - w[(BW + 1) * LANES + k]
        wr = w[L.W * LANES + k] - w[(BW + 2) * LANES + k]
        va = sqrt(ur * ur + vr * vr + wr * wr)
        res = fixedwing_autopilot(
            prm, _pre(w, k), _rm(w, k), va, w[GRAV * LANES + k], h, w[L.H * LANES + k],
            w[L.P * LANES + k], w[L.Q * LANES + k], w[L.R * LANES + k],
            w[L.I0 * LANES + k], w[L.I1 * LANES + k], w[L.I2 * LANES + k])
        _store_autopilot(w, k, res)


@njit(cache=True, inline="always")
def _store_autopilot(w: np.ndarray, k: int, res: tuple) -> None:
    _put3(w, L.I0, k, res[0], res[1], res[2])
    _put3(w, ACT, k, res[3], res[4], res[5])
    _put3(w, ACT + 3, k, res[6], res[7], res[8])
    w[(ACT + 6) * LANES + k] = res[9]


@njit(cache=True, error_model="numpy")
def aero_lanes(w: np.ndarray, nb: int, prm: np.ndarray) -> None:
    """Aerodynamic force and moment of every lane, into the force columns.

    The bluff-body / wing choice is made once for the block, outside the lane loop
    (inside it the vectoriser would evaluate both and select).
    """
    if prm[L.AERO_B] == 0.0:
        for k in range(nb):
            f = bluff_body_forces(prm, w[L.U * LANES + k] - w[BW * LANES + k],
                                  w[L.V * LANES + k] - w[(BW + 1) * LANES + k],
                                  w[L.W * LANES + k] - w[(BW + 2) * LANES + k],
                                  w[RHO * LANES + k])
            _put3(w, FRC, k, f[0], f[1], f[2])
            _put3(w, FRC + 3, k, f[3], f[4], f[5])
        return
    for k in range(nb):
        f = aero_forces(prm, w[L.U * LANES + k] - w[BW * LANES + k],
                        w[L.V * LANES + k] - w[(BW + 1) * LANES + k],
                        w[L.W * LANES + k] - w[(BW + 2) * LANES + k],
                        w[L.P * LANES + k], w[L.Q * LANES + k], w[L.R * LANES + k],
                        w[L.DA * LANES + k], w[L.DE * LANES + k], w[L.DR * LANES + k],
                        w[RHO * LANES + k])
        _put3(w, FRC, k, f[0], f[1], f[2])
        _put3(w, FRC + 3, k, f[3], f[4], f[5])


@njit(cache=True, error_model="numpy")
def rotor_lanes(w: np.ndarray, nb: int, prm: np.ndarray, i: int) -> None:
    """Add rotor ``i``'s force and moment to every lane's force columns."""
    geo = rotor_geometry(prm, i)
    # Copy the rotor's speeds to a fixed column: an offset known at compile time keeps
    # the loop below free of run-time alias checks (which a view into w would fail).
    om = (L.OM0 + i) * LANES
    for k in range(nb):
        w[OMI * LANES + k] = w[om + k]
    for k in range(nb):
        ur = w[L.U * LANES + k] - w[BW * LANES + k]
        vr = w[L.V * LANES + k] - w[(BW + 1) * LANES + k]
        wr = w[L.W * LANES + k] - w[(BW + 2) * LANES + k]
        f = rotor_contribution(prm, geo, ur, vr, wr, ur * ur + vr * vr + wr * wr,
                               w[OMI * LANES + k], w[RHO * LANES + k])
        fx, fy, fz = w[FRC * LANES + k], w[(FRC + 1) * LANES + k], w[(FRC + 2) * LANES + k]
        _put3(w, FRC, k, fx + f[0], fy + f[1], fz + f[2])
        lm, mm, nm = (w[(FRC + 3) * LANES + k], w[(FRC + 4) * LANES + k],
                      w[(FRC + 5) * LANES + k])
        _put3(w, FRC + 3, k, lm + f[3], mm + f[4], nm + f[5])


@njit(cache=True, inline="always")
def _add6(a: tuple, b: tuple) -> tuple:
    return a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5]


@njit(cache=True, error_model="numpy")
def four_rotor_lanes(w: np.ndarray, nb: int, prm: np.ndarray) -> None:
    """:func:`rotor_lanes` of rotors 0..3 in one pass (force columns read and written once;
    the sums are taken in the same order, so the bits are the same)."""
    g0, g1 = rotor_geometry(prm, 0), rotor_geometry(prm, 1)
    g2, g3 = rotor_geometry(prm, 2), rotor_geometry(prm, 3)
    for k in range(nb):
        ur = w[L.U * LANES + k] - w[BW * LANES + k]
        vr = w[L.V * LANES + k] - w[(BW + 1) * LANES + k]
        wr = w[L.W * LANES + k] - w[(BW + 2) * LANES + k]
        v2 = ur * ur + vr * vr + wr * wr
        rho = w[RHO * LANES + k]
        f = (w[FRC * LANES + k], w[(FRC + 1) * LANES + k], w[(FRC + 2) * LANES + k],
             w[(FRC + 3) * LANES + k], w[(FRC + 4) * LANES + k], w[(FRC + 5) * LANES + k])
        f = _add6(f, rotor_contribution(prm, g0, ur, vr, wr, v2, w[L.OM0 * LANES + k], rho))
        f = _add6(f, rotor_contribution(prm, g1, ur, vr, wr, v2, w[L.OM1 * LANES + k], rho))
        f = _add6(f, rotor_contribution(prm, g2, ur, vr, wr, v2, w[L.OM2 * LANES + k], rho))
        f = _add6(f, rotor_contribution(prm, g3, ur, vr, wr, v2, w[L.OM3 * LANES + k], rho))
        _put3(w, FRC, k, f[0], f[1], f[2])
        _put3(w, FRC + 3, k, f[3], f[4], f[5])


@njit(cache=True, error_model="numpy")
def rigid_body_lanes(w: np.ndarray, nb: int, prm: np.ndarray, h: float) -> None:
    """Integrate every lane's rigid body over the sub-step ``h``."""
    for k in range(nb):
        f = FRC * LANES + k
        res = rigid_body_update(
            prm, _rm(w, k), w[L.U * LANES + k], w[L.V * LANES + k], w[L.W * LANES + k],
            w[L.P * LANES + k], w[L.Q * LANES + k], w[L.R * LANES + k],
            w[L.Q0 * LANES + k], w[L.Q1 * LANES + k], w[L.Q2 * LANES + k],
            w[L.Q3 * LANES + k], w[f], w[f + LANES], w[f + 2 * LANES], w[f + 3 * LANES],
            w[f + 4 * LANES], w[f + 5 * LANES], w[GRAV * LANES + k], h)
        w[L.U * LANES + k], w[L.V * LANES + k], w[L.W * LANES + k] = res[0], res[1], res[2]
        w[L.P * LANES + k], w[L.Q * LANES + k], w[L.R * LANES + k] = res[3], res[4], res[5]
        w[L.Q0 * LANES + k], w[L.Q1 * LANES + k] = res[6], res[7]
        w[L.Q2 * LANES + k], w[L.Q3 * LANES + k] = res[8], res[9]
        w[L.XN * LANES + k] += res[10]
        w[L.YE * LANES + k] += res[11]
        w[L.H * LANES + k] -= res[12]
        w[L.TIME * LANES + k] += h
