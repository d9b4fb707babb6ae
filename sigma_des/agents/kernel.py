"""The compiled step of the general aircraft: one loop over rows, fixed sub-steps (numba).

Each row is copied into a scratch vector, advanced through ``ceil(dt / h_max)``
equal sub-steps and written to the output array, so rows never interact and the
result of row ``i`` does not depend on the batch it is in (the same scalar code
runs for every row; no BLAS, no cross-row reductions, no ``fastmath``).

Per frame step (held over its sub-steps): air density and gravity at the row's
altitude, the Dryden turbulence update (at its own, lower rate, keyed by node and
update index; see wind.py), the wind vector, the
slow autopilot parts. Per sub-step: rotation matrix, autopilot inner loops,
first-order actuator lags (exact exponential discretisation), forces,
rigid-body integration.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.approx import atan2_fast
from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar
from sigma_des.agents.autopilot import (
    fixedwing_autopilot,
    fixedwing_prepare,
    multirotor_autopilot,
    multirotor_prepare,
)
from sigma_des.agents.forces import forces_moments
from sigma_des.agents.rigid_body import rigid_body_substep, rotmat, to_body, to_ned
from sigma_des.agents.wind import mean_wind, turbulence_update

__all__ = ["step_kernel"]


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
    kind = int(prm[L.AP_KIND])
    nrot = int(prm[L.NROT])
    tp = prm[L.ENV_TURB_ON]
    turb = tp > 0.0
    x = np.empty(L.STATE_DIM)
    act = np.zeros(7)
    cmd = np.empty(4)
    pre = np.zeros(8)
    for i in range(n):
        for j in range(L.STATE_DIM):
            x[j] = state[i, j]
        rm = rotmat(x)
        vn, ve, vd = to_ned(rm, x[L.U], x[L.V], x[L.W])
        _, _, rho = isa_scalar(x[L.H])
        g = gravity_scalar(x[L.H])
        # Wind: mean (at this step's time and altitude) + turbulence in heading axes.
        wn, we, wd = mean_wind(prm, x[L.TIME], x[L.H])
        if turb:
            # Update at the turbulence rate (wind.py): when this frame crosses one or
            # more multiples of the period tp, over exactly the periods crossed.
            e0 = math.floor(x[L.TIME] / tp + 1e-6)
            e1 = math.floor((x[L.TIME] + dt) / tp + 1e-6)
            if e1 > e0:
                spd = math.sqrt((vn - wn) ** 2 + (ve - we) ** 2 + (vd - wd) ** 2)
                turbulence_update(x, prm, key, nodes[i], np.int64(e1), (e1 - e0) * tp, spd)
            hn = math.sqrt(rm[0] * rm[0] + rm[3] * rm[3])
            ch, sh = (rm[0] / hn, rm[3] / hn) if hn > 1e-9 else (1.0, 0.0)
            wn += ch * x[L.TU] - sh * x[L.TV]
            we += sh * x[L.TU] + ch * x[L.TV]
            wd += x[L.TW]
        if kind != 0:
            # NaN in v / chi / h = keep the current value (resolved per step).
            c0, c1, c2 = command[i, 0], command[i, 1], command[i, 2]
            cmd[0] = c0 if c0 == c0 else math.sqrt(vn * vn + ve * ve)
            cmd[1] = c1 if c1 == c1 else atan2_fast(rm[3], rm[0])
            cmd[2] = c2 if c2 == c2 else x[L.H]
            cmd[3] = command[i, 3]
            if kind == 1:
                multirotor_prepare(prm, cmd, rm, pre)
            else:
                fixedwing_prepare(prm, cmd, vn, ve, pre)
        for s in range(nsub):
            if s > 0:
                rm = rotmat(x)
                vn, ve, vd = to_ned(rm, x[L.U], x[L.V], x[L.W])
            bx, by, bz = to_body(rm, wn, we, wd)
            if kind == 1:
                multirotor_autopilot(x, prm, pre, rm, vn, ve, vd, g, h, act)
            elif kind == 2:
                ur, vr, wr = x[L.U] - bx, x[L.V] - by, x[L.W] - bz
                va = math.sqrt(ur * ur + vr * vr + wr * wr)
                fixedwing_autopilot(x, prm, pre, rm, va, g, h, act)
            else:
                for j in range(7):
                    act[j] = act_cmd[i, j]
            for j in range(nrot):
                x[L.OM0 + j] += am * (act[j] - x[L.OM0 + j])
            x[L.DA] += asv * (act[4] - x[L.DA])
            x[L.DE] += asv * (act[5] - x[L.DE])
            x[L.DR] += asv * (act[6] - x[L.DR])
            fx, fy, fz, lm, mm, nm = forces_moments(x, prm, bx, by, bz, rho)
            rigid_body_substep(x, prm, rm, fx, fy, fz, lm, mm, nm, g, h)
        for j in range(L.STATE_DIM):
            out[i, j] = x[j]
