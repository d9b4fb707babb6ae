"""Replay of logged control signals through the 6-DoF model, one candidate or a population.

The paper's step 2: the logged control signals are fed to the simulator at the
same timestamps (sample-and-hold, the autopilot bypassed: the general
aircraft's open-loop mode), and the simulated state is recorded. The log is cut
into windows of ``tune.segment`` seconds; each window restarts from the logged
state (multiple shooting), because an open-loop quadrotor is unstable and a
long open-loop replay diverges whatever the parameters. Rotor speeds and
surface deflections are not logged: the first window starts with them at
their first commands (steady state), later windows carry them over from the
end of the previous window (the candidate's own actuator lag applied to the
same commands), so a wrong lag is not masked by a reset.

Population vectorisation: a candidate parameter set is one row of a
``(P, PARAM_DIM)`` parameter matrix, and every (candidate, window) pair is one
row of a batched flight, advanced through every window step by one compiled
call. Each row runs the project's own row step (``agents.kernel.step_kernel``
on a one-row view with that candidate's vector), so a batched row is
bit-identical to replaying that candidate alone (:func:`replay_serial`, the
one-by-one path through ``GeneralAircraft.step_open_loop``; tested).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft, observe_state
from sigma_des.agents.kernel import step_kernel
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.wind import WindConfig
from sigma_des.errors import ConfigError
from sigma_des.tuning.flightlog import FlightLog

__all__ = ["Windows", "windows", "param_matrix", "replay_batch", "replay_serial",
           "state_from_obs", "actuator_matrix"]

_NO_CMD = np.zeros((0, 4))


@dataclass(frozen=True)
class Windows:
    """A resampled log cut into replay windows.

    Attributes:
        dt: sample period (s).
        steps: steps per window (M).
        start: ``(S, STATE_DIM)`` logged state at each window start.
        act: ``(S, M, 7)`` actuator commands per window step (ACTUATOR_NAMES order).
        obs: ``(S, M + 1, 12)`` logged observations over each window.
    """

    dt: float
    steps: int
    start: NDArray[np.float64]
    act: NDArray[np.float64]
    obs: NDArray[np.float64]

    @property
    def count(self) -> int:
        """Number of windows S."""
        return int(self.start.shape[0])


def actuator_matrix(log: FlightLog) -> NDArray[np.float64]:
    """``(T, 7)`` kernel actuator commands from the log's control-signal columns."""
    a = np.zeros((log.t.shape[0], 7))
    if log.kind == "quadrotor":
        a[:, 0:4] = log.act
    else:
        a[:, 0] = log.act[:, 0]
        a[:, 4:7] = log.act[:, 1:4]
    return a


def state_from_obs(obs: NDArray[np.float64], t: NDArray[np.float64],
                   act: NDArray[np.float64]) -> NDArray[np.float64]:
    """Full kernel states from logged rows (actuator states taken as their commands).

    Args:
        obs: ``(n, 12)`` logged ``[u v w phi theta psi p q r x y h]``.
        t: ``(n,)`` times.
        act: ``(n, 7)`` actuator commands.
    """
    n = obs.shape[0]
    s = np.zeros((n, L.STATE_DIM))
    s[:, L.U:L.W + 1] = obs[:, 0:3]
    hp, ht, hy = obs[:, 3] / 2, obs[:, 4] / 2, obs[:, 5] / 2
    cp, sp, ct, st, cy, sy = np.cos(hp), np.sin(hp), np.cos(ht), np.sin(ht), np.cos(hy), np.sin(hy)
    s[:, L.Q0] = cp * ct * cy + sp * st * sy
    s[:, L.Q1] = sp * ct * cy - cp * st * sy
    s[:, L.Q2] = cp * st * cy + sp * ct * sy
    s[:, L.Q3] = cp * ct * sy - sp * st * cy
    s[:, L.P:L.R + 1] = obs[:, 6:9]
    s[:, L.XN:L.H + 1] = obs[:, 9:12]
    s[:, L.TIME] = t
    s[:, L.OM0:L.OM0 + 4] = act[:, 0:4]
    s[:, L.DA:L.DR + 1] = act[:, 4:7]
    return s


def windows(log: FlightLog, segment: float) -> Windows:
    """Cut a uniformly sampled log into windows of ``segment`` seconds.

    The tail shorter than one window is not replayed.
    """
    dt = float(log.t[1] - log.t[0])
    m = max(1, int(round(segment / dt)))
    s = (log.t.shape[0] - 1) // m
    if s < 1:
        raise ConfigError("tune.segment", f"{segment} s is longer than the log "
                          f"({log.duration:.3f} s)")
    act = actuator_matrix(log)
    idx = np.arange(s) * m
    start = state_from_obs(log.obs[idx], log.t[idx], act[idx])
    steps = idx[:, None] + np.arange(m)[None, :]
    obs = log.obs[np.concatenate([steps, (idx + m)[:, None]], axis=1)]
    return Windows(dt=dt, steps=m, start=start, act=act[steps], obs=obs)


def param_matrix(params: list[AircraftParams], wind: WindConfig | None = None
                 ) -> NDArray[np.float64]:
    """``(P, PARAM_DIM)`` open-loop kernel vectors of the candidates (wind: still air)."""
    w = wind or WindConfig()
    out = np.empty((len(params), L.PARAM_DIM))
    for i, p in enumerate(params):
        v = p.to_array()
        w.write(v)
        v[L.AP_KIND] = 0.0
        out[i] = v
    return out


@njit(cache=True)
def _replay(start: np.ndarray, act: np.ndarray, dt: float, prms: np.ndarray,
            key: np.uint64, out: np.ndarray) -> None:
    p_n, s_n = prms.shape[0], start.shape[0]
    m = act.shape[1]
    cur = np.empty((1, L.STATE_DIM))
    nxt = np.empty((1, L.STATE_DIM))
    a = np.empty((1, 7))
    node = np.zeros(1, dtype=np.int64)
    for c in range(p_n):
        prm = prms[c]
        for s in range(s_n):
            r = c * s_n + s
            cur[0] = start[s]
            if s > 0:
                # Actuator states are not logged: carry them over from the previous
                # window (the same lag applied to the same commands).
                for j in range(L.OM0, L.DR + 1):
                    cur[0, j] = out[r - 1, m, j]
            out[r, 0] = cur[0]
            for k in range(m):
                a[0] = act[s, k]
                step_kernel(cur, _NO_CMD, a, dt, np.int64(s * m + k + 1), node, prm, key, nxt)
                out[r, k + 1] = nxt[0]
                cur[0] = nxt[0]


def replay_batch(win: Windows, prms: NDArray[np.float64]) -> NDArray[np.float64]:
    """Replay every window with every candidate: ``(P, S, M + 1, 12)`` observations.

    Args:
        win: the windows of the log.
        prms: ``(P, PARAM_DIM)`` from :func:`param_matrix`.
    """
    p_n = prms.shape[0]
    out = np.empty((p_n * win.count, win.steps + 1, L.STATE_DIM))
    _replay(win.start, np.ascontiguousarray(win.act), win.dt,
            np.ascontiguousarray(prms), np.uint64(0), out)
    obs = observe_state(out.reshape(-1, L.STATE_DIM))
    return obs.reshape(p_n, win.count, win.steps + 1, 12)


def replay_serial(win: Windows, params: AircraftParams,
                  wind: WindConfig | None = None) -> NDArray[np.float64]:
    """One candidate, one Python call per step through ``GeneralAircraft.step_open_loop``.

    The reference (and benchmark baseline) of :func:`replay_batch`: returns
    ``(S, M + 1, 12)``, equal to one candidate's slice of the batch bit for bit.
    """
    # Open loop: no autopilot, hence no trim to solve for odd candidates.
    model = GeneralAircraft(dataclasses.replace(params, autopilot="none", gains={}), wind=wind)
    model.key = np.uint64(0)
    node = np.zeros(1, dtype=np.int64)
    out = np.empty((win.count, win.steps + 1, L.STATE_DIM))
    acts = slice(L.OM0, L.DR + 1)
    for s in range(win.count):
        cur = win.start[s:s + 1].copy()
        if s > 0:
            cur[0, acts] = out[s - 1, win.steps, acts]
        out[s, 0] = cur[0]
        for k in range(win.steps):
            cur = model.step_open_loop(cur, win.act[s, k][None, :], win.dt,
                                       s * win.steps + k + 1, node)
            out[s, k + 1] = cur[0]
    return observe_state(out.reshape(-1, L.STATE_DIM)).reshape(out.shape[0], -1, 12)



