"""The compiled step of the general aircraft: one loop over rows, fixed sub-steps (numba).

Each row is copied into a scratch vector, advanced through ``ceil(dt / h_max)``
equal sub-steps and written to the output array, so rows never interact and the
result of row ``i`` does not depend on the batch it is in (the same scalar code
runs for every row; no BLAS, no cross-row reductions, no ``fastmath``).

Per frame step (held over its sub-steps): air density and gravity at the row's
altitude, the Dryden turbulence update for (node, frame), the wind vector. Per
sub-step: Euler angles, autopilot, first-order actuator lags (exact exponential
discretisation), forces, rigid-body integration.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L
from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar
from sigma_des.agents.autopilot import fixedwing_autopilot, multirotor_autopilot
from sigma_des.agents.forces import forces_moments
from sigma_des.agents.rigid_body import euler_of, rigid_body_substep, rotate_to_body, rotate_to_ned
from sigma_des.agents.wind import mean_wind, turbulence_update, wind_ned

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
    turb = prm[L.ENV_TURB_ON] > 0.0
    x = np.empty(L.STATE_DIM)
    act = np.zeros(7)
    cmd = np.empty(4)
    for i in range(n):
        for j in range(L.STATE_DIM):
            x[j] = state[i, j]
        phi, theta, psi = euler_of(x)
        vn, ve, vd = rotate_to_ned(x, x[L.U], x[L.V], x[L.W])
        _, _, rho = isa_scalar(x[L.H])
        g = gravity_scalar(x[L.H])
        if kind != 0:
            # NaN in v / chi / h = keep the current value (resolved per step).
            cmd[0] = command[i, 0] if command[i, 0] == command[i, 0] else math.hypot(vn, ve)
            cmd[1] = command[i, 1] if command[i, 1] == command[i, 1] else psi
            cmd[2] = command[i, 2] if command[i, 2] == command[i, 2] else x[L.H]
            cmd[3] = command[i, 3]
        if turb:
            mn, me, md = mean_wind(prm, x[L.TIME], x[L.H])
            spd = math.sqrt((vn - mn) ** 2 + (ve - me) ** 2 + (vd - md) ** 2)
            turbulence_update(x, prm, key, nodes[i], frame, dt, spd)
        wn, we, wd = wind_ned(x, prm, psi)
        for s in range(nsub):
            if s > 0:
                phi, theta, psi = euler_of(x)
                vn, ve, vd = rotate_to_ned(x, x[L.U], x[L.V], x[L.W])
            if kind == 1:
                multirotor_autopilot(x, prm, cmd, phi, theta, psi, vn, ve, vd, g, h, act)
            elif kind == 2:
                bx, by, bz = rotate_to_body(x, wn, we, wd)
                ur, vr, wr = x[L.U] - bx, x[L.V] - by, x[L.W] - bz
                va = math.sqrt(ur * ur + vr * vr + wr * wr)
                fixedwing_autopilot(x, prm, cmd, phi, theta, vn, ve, va, g, h, act)
            else:
                for j in range(7):
                    act[j] = act_cmd[i, j]
            for j in range(nrot):
                x[L.OM0 + j] += am * (act[j] - x[L.OM0 + j])
            x[L.DA] += asv * (act[4] - x[L.DA])
            x[L.DE] += asv * (act[5] - x[L.DE])
            x[L.DR] += asv * (act[6] - x[L.DR])
            fx, fy, fz, lm, mm, nm = forces_moments(x, prm, wn, we, wd, rho)
            rigid_body_substep(x, prm, fx, fy, fz, lm, mm, nm, g, h)
        for j in range(L.STATE_DIM):
            out[i, j] = x[j]
