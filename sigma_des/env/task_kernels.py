"""Compiled observation and reward of the formation tasks over a leading scene axis.

``SwarmVec`` builds every scene's observation and reward at each step; on a small
swarm the numpy expressions of :mod:`sigma_des.env.tasks` cost tens of calls on tiny
arrays each, which at a few scenes is most of a step. These kernels do the very
floating-point operations of those expressions (``FormationTask.columns_many`` and
``TightTask.columns_many`` with ``Task.observe_many``'s masking and clipping;
``Task.reward_many`` on the formation targets; ``Task.commands_many``'s guidance and
velocity commands around its numpy trigonometry), in the same order, element by element
(``tests/env/test_task_kernels.py`` checks them bit for bit against the numpy path).
As in :mod:`sigma_des.agents.rule_kernels`, the transcendental functions stay numpy or
``math`` calls made by the callers (numpy's SIMD ``cos`` may differ from the C
library's in the last bit), and so do the slot offsets
(:func:`~sigma_des.env.scene_axis.slot_offsets`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["agent_guidance", "formation_observe", "formation_reward", "tight_observe",
           "velocity_commands"]

#: ``np.nan_to_num``'s stand-in for an infinity
_BIG = float(np.finfo(np.float64).max)


@njit(cache=True)
def _finite(x: float, nan: float) -> float:
    """``np.nan_to_num(x, nan=nan)``: NaN -> ``nan``, +-inf -> the largest float."""
    if math.isnan(x):
        return nan
    if math.isinf(x):
        return _BIG if x > 0 else -_BIG
    return x


@njit(cache=True)
def _dist(pos: np.ndarray, i: int, j: int) -> float:
    """The distance from row ``i`` of ``pos`` to row ``j`` (``inf`` to itself), as
    ``nearest_many``: ``sqrt((d0^2 + d1^2) + d2^2)``, numpy's order on that layout."""
    if i == j:
        return math.inf
    acc = 0.0
    for c in range(pos.shape[1]):
        dd = pos[j, c] - pos[i, c]
        acc = dd * dd if c == 0 else acc + dd * dd
    return math.sqrt(acc)


@njit(cache=True)
def _nearest(pos: np.ndarray, i: int) -> int:
    """``np.argmin`` over ``j`` of :func:`_dist` from row ``i`` (the first minimum; a NaN
    distance is the minimum, as numpy's)."""
    best, best_d = 0, _dist(pos, i, 0)
    for j in range(1, pos.shape[0]):
        if math.isnan(best_d):
            break
        dist = _dist(pos, i, j)
        if math.isnan(dist) or dist < best_d:
            best, best_d = j, dist
    return best


@njit(cache=True)
def _targets(obs: np.ndarray, s: int, lc: float, ls: float, dx: np.ndarray, dy: np.ndarray,
             tgt: np.ndarray) -> None:
    """``formation_targets_many`` of scene ``s`` into ``tgt`` (``(n, 3)``)."""
    for i in range(obs.shape[1]):
        tgt[i, 0] = (obs[s, 0, 9] + lc * dx[i]) - ls * dy[i]
        tgt[i, 1] = (obs[s, 0, 10] + ls * dx[i]) + lc * dy[i]
        tgt[i, 2] = obs[s, 0, 11]


@njit(cache=True)
def _put(out: np.ndarray, s: int, k: int, c: int, x: float, lim: float) -> None:
    """``np.clip(np.nan_to_num(x, nan=0.0), -lim, lim)`` as float32 into ``out[s, k, c]``."""
    if math.isnan(x):
        x = 0.0
    if x < -lim:
        x = -lim
    elif x > lim:
        x = lim
    out[s, k, c] = np.float32(x)


@njit(cache=True)
def _slot_error(out: np.ndarray, s: int, k: int, g: int, obs: np.ndarray, tgt: np.ndarray,
                d: float, lim: float) -> None:
    """Columns 0-2 of agent ``k`` (node ``g``): its slot error north and east ``/ d`` and
    its altitude error ``/ 10 m``."""
    _put(out, s, k, 0, (tgt[g, 0] - obs[s, g, 9]) / d, lim)
    _put(out, s, k, 1, (tgt[g, 1] - obs[s, g, 10]) / d, lim)
    _put(out, s, k, 2, (tgt[g, 2] - obs[s, g, 11]) / 10.0, lim)


@njit(cache=True)
def _scene_rows(obs: np.ndarray, s: int, cos5: np.ndarray, sin5: np.ndarray, v_ref: float,
                pos: np.ndarray, vel: np.ndarray) -> None:
    """Scene ``s``'s positions (``nan_to_num(nan=1e9)``, north and east) and velocities
    (``velocity_many / v_ref``)."""
    for i in range(obs.shape[1]):
        pos[i, 0] = _finite(obs[s, i, 9], 1e9)
        pos[i, 1] = _finite(obs[s, i, 10], 1e9)
        vel[i, 0] = obs[s, i, 0] * cos5[s, i] / v_ref
        vel[i, 1] = obs[s, i, 0] * sin5[s, i] / v_ref


@njit(cache=True)
def formation_observe(obs: np.ndarray, valid: np.ndarray, cos5: np.ndarray,
                      sin5: np.ndarray, lead_vel: np.ndarray, lc: np.ndarray, ls: np.ndarray,
                      dx: np.ndarray, dy: np.ndarray, agents: np.ndarray, d: float,
                      v_ref: float, lim: float) -> np.ndarray:
    """``FormationTask.observe_many``: ``(S, A, 9)`` float32 (``lead_vel`` ``(S, 2)`` is
    ``velocity_many(obs[:, :1]) / v_ref``, ``lc``/``ls`` the leader headings' cos/sin)."""
    S, n = obs.shape[0], obs.shape[1]
    A = agents.shape[0]
    out = np.zeros((S, A, 9), dtype=np.float32)
    pos, vel, tgt = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 3))
    for s in range(S):
        _scene_rows(obs, s, cos5, sin5, v_ref, pos, vel)
        _targets(obs, s, lc[s], ls[s], dx, dy, tgt)
        for k in range(A):
            g = agents[k]
            if not valid[s, g]:
                continue
            j = _nearest(pos, g)
            _slot_error(out, s, k, g, obs, tgt, d, lim)
            _put(out, s, k, 3, lead_vel[s, 0], lim)
            _put(out, s, k, 4, lead_vel[s, 1], lim)
            _put(out, s, k, 5, vel[g, 0], lim)
            _put(out, s, k, 6, vel[g, 1], lim)
            _put(out, s, k, 7, (pos[j, 0] - pos[g, 0]) / d, lim)
            _put(out, s, k, 8, (pos[j, 1] - pos[g, 1]) / d, lim)
    return out


@njit(cache=True)
def tight_observe(obs: np.ndarray, valid: np.ndarray, age: np.ndarray, cos5: np.ndarray,
                  sin5: np.ndarray, lc: np.ndarray, ls: np.ndarray, dx: np.ndarray,
                  dy: np.ndarray, agents: np.ndarray, d: float, v_ref: float, age_ref: float,
                  lim: float) -> np.ndarray:
    """``TightTask.observe_many``: ``(S, A, 14)`` float32 (``age`` as given to it, NaN
    where no state is shown)."""
    S, n = obs.shape[0], obs.shape[1]
    A = agents.shape[0]
    out = np.zeros((S, A, 14), dtype=np.float32)
    pos, vel, tgt = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 3))
    a = np.empty(n)
    for s in range(S):
        _scene_rows(obs, s, cos5, sin5, v_ref, pos, vel)
        _targets(obs, s, lc[s], ls[s], dx, dy, tgt)
        for i in range(n):
            a[i] = _finite(age[s, i], 0.0) / age_ref
        for k in range(A):
            g = agents[k]
            if not valid[s, g]:
                continue
            j = _nearest(pos, g)
            _slot_error(out, s, k, g, obs, tgt, d, lim)
            _put(out, s, k, 3, vel[g, 0], lim)
            _put(out, s, k, 4, vel[g, 1], lim)
            _put(out, s, k, 5, a[g], lim)
            _put(out, s, k, 6, vel[0, 0], lim)
            _put(out, s, k, 7, vel[0, 1], lim)
            _put(out, s, k, 8, a[0], lim)
            _put(out, s, k, 9, (pos[j, 0] - pos[g, 0]) / d, lim)
            _put(out, s, k, 10, (pos[j, 1] - pos[g, 1]) / d, lim)
            _put(out, s, k, 11, vel[j, 0], lim)
            _put(out, s, k, 12, vel[j, 1], lim)
            _put(out, s, k, 13, a[j], lim)
    return out


@njit(cache=True)
def formation_reward(truth: np.ndarray, lc: np.ndarray, ls: np.ndarray, dx: np.ndarray,
                     dy: np.ndarray, agents: np.ndarray, actions: np.ndarray, L: float,
                     lim: float, w_sep: float, r_safe: float, w_u: float, r_col: float,
                     penalty: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Task.reward_many`` on the formation targets: rewards, failures and true errors,
    ``(S, A)`` each (``actions`` ``(S, A, 3)`` float64)."""
    S, n = truth.shape[0], truth.shape[1]
    A = agents.shape[0]
    r, e = np.empty((S, A)), np.empty((S, A))
    fail = np.empty((S, A), dtype=np.bool_)
    tgt, pos = np.empty((n, 3)), np.empty((n, 3))
    for s in range(S):
        _targets(truth, s, lc[s], ls[s], dx, dy, tgt)
        for i in range(n):
            for c in range(3):
                pos[i, c] = truth[s, i, 9 + c]
        for k in range(A):
            g = agents[k]
            ex, ey, ez = tgt[g, 0] - pos[g, 0], tgt[g, 1] - pos[g, 1], tgt[g, 2] - pos[g, 2]
            err = math.sqrt((ex * ex + ey * ey) + ez * ez)
            dmin = _dist(pos, g, _nearest(pos, g))
            m = err if (math.isnan(err) or err < lim) else lim
            x = m / L
            rk = -(x * x)
            y = 1.0 - dmin / r_safe
            y = y if (math.isnan(y) or y > 0.0) else 0.0
            rk = rk - w_sep * (y * y)
            a0, a1, a2 = actions[s, k, 0], actions[s, k, 1], actions[s, k, 2]
            rk = rk - w_u * ((a0 * a0 + a1 * a1) + a2 * a2) / 3.0
            f = dmin < r_col or err > lim or not math.isfinite(err)
            r[s, k] = rk - penalty if f else rk
            fail[s, k] = f
            e[s, k] = err
    return r, fail, e


@njit(cache=True)
def agent_guidance(g: np.ndarray, speed: np.ndarray, course: np.ndarray, actions: np.ndarray,
                   obs: np.ndarray, valid: np.ndarray, agents: np.ndarray, dh_max: float,
                   send: np.ndarray) -> None:
    """``Task.commands_many``'s guidance of the agents into ``g`` (``(S, n, 4)``, the
    scripted rows there already): speed, course and the altitude
    ``obs[..., 11] + actions[..., 2] * dh_max``; ``send`` (``(S, n)``) the rows whose
    speed and altitude are known, of nodes with a shown state."""
    S, n = g.shape[0], g.shape[1]
    for s in range(S):
        for k in range(agents.shape[0]):
            i = agents[k]
            g[s, i, 0] = speed[s, k]
            g[s, i, 1] = course[s, k]
            g[s, i, 2] = obs[s, i, 11] + actions[s, k, 2] * dh_max
        for i in range(n):
            send[s, i] = (not math.isnan(g[s, i, 0])) and (not math.isnan(g[s, i, 2])) \
                and valid[s, i]


@njit(cache=True)
def velocity_commands(rows: np.ndarray, cos1: np.ndarray, sin1: np.ndarray,
                      obs: np.ndarray, send: np.ndarray, cmds: np.ndarray) -> None:
    """``to_command`` of guidance ``rows`` (``(m, 4)``, the sent rows of ``send`` in
    order; ``cos1``/``sin1`` the cos/sin of their course; ``obs`` the ``(S, n, 12)``
    shown states) as ``vn, ve, vh`` into the sent rows of ``cmds`` (``(S, n, 3)``):
    ``v cos chi``, ``v sin chi`` and ``np.clip(0.5 (h - h_shown), -3, 3)``."""
    r = 0
    for s in range(send.shape[0]):
        for i in range(send.shape[1]):
            if not send[s, i]:
                continue
            v = rows[r, 0]
            cmds[s, i, 0] = v * cos1[r]
            cmds[s, i, 1] = v * sin1[r]
            x = 0.5 * (rows[r, 2] - obs[s, i, 11])
            if not math.isnan(x):  # np.clip: NaN passes; else max(x, -3), then min(., 3)
                x = x if x > -3.0 else -3.0
                x = x if x < 3.0 else 3.0
            cmds[s, i, 2] = x
            r += 1
