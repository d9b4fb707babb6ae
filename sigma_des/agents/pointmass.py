"""A 2nd-order point-mass aircraft: the stand-in dynamics of the core simulator.

State ``[x, y, h, vn, ve, vh]``; command = desired ``[vn, ve, vh]`` velocity,
tracked with a first-order lag of time constant ``tau``. The swarm starts on a
grid with a common cruise velocity. Cheap, exact and row-independent, so it is
the reference dynamics for hand-computed engine tests.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["PointMass"]


@njit(cache=True)
def _step_frames(s0: np.ndarray, cmd: np.ndarray, dts: np.ndarray, gains: np.ndarray,
                 out: np.ndarray) -> None:
    """One row through consecutive frames: :meth:`PointMass.step`'s operations, in its
    order, per column (``gains[j]`` its ``1 - exp(-dt / tau)`` of ``dts[j]``)."""
    s = s0.copy()
    for j in range(dts.shape[0]):
        a = gains[j]
        dt = dts[j]
        for c in range(3):
            v0 = s[3 + c]
            v1 = v0 + a * (cmd[c] - v0)
            s[c] = s[c] + 0.5 * (v0 + v1) * dt
            s[3 + c] = v1
        out[j] = s


@njit(cache=True)
def _step_rows(state: np.ndarray, cmd: np.ndarray, dt: float, a: float,
               out: np.ndarray) -> None:
    """:meth:`PointMass.step`'s array operations row by row, in its order (gain ``a``)."""
    for r in range(state.shape[0]):
        for c in range(3):
            v0 = state[r, 3 + c]
            v1 = v0 + a * (cmd[r, c] - v0)
            out[r, c] = state[r, c] + 0.5 * (v0 + v1) * dt
            out[r, 3 + c] = v1


@njit(cache=True)
def _step_gain(state: np.ndarray, cmd: np.ndarray, dt: float, p: np.ndarray,
               out: np.ndarray) -> None:
    """:meth:`PointMass.step` into ``out`` with ``p[0]`` its ``tau``: the gain
    ``1 - exp(-dt / tau)`` (the same libm ``exp`` as Python's ``math.exp``), then
    :func:`_step_rows`."""
    a = 1.0 - math.exp(-dt / p[0])
    _step_rows(state, cmd, dt, a, out)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _resim_gain(prev: np.ndarray, cmd: np.ndarray, frame_dt: np.ndarray, first: int,
                latest: int, p: np.ndarray, i: int, ckpt: np.ndarray, obs_hist: np.ndarray,
                state: np.ndarray) -> None:
    """:meth:`PointMass.resimulate_into` with ``p[0]`` its ``tau``."""
    s = state[i]  # the working row: rows are independent, prev is another slot's
    for c in range(s.shape[0]):
        s[c] = prev[c]
    _resimulate_in(s, cmd, frame_dt, first, latest, p[0], i, ckpt, obs_hist)


@njit(cache=True)
def _observe_rows(state: np.ndarray, out: np.ndarray) -> None:
    """:meth:`PointMass.observe` of each row of ``state`` written into ``out``'s rows
    (:func:`_observe_row`)."""
    for r in range(state.shape[0]):
        _observe_row(state[r], out[r])


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _observe_row(s: np.ndarray, o: np.ndarray) -> None:
    """:meth:`PointMass.observe` of state row ``s`` written into ``o``: the C library's
    ``hypot`` and ``atan2`` (Python's ``math``), the other columns zero. Every path
    observes through this kernel: numpy's float64 ufuncs are SIMD code on AVX-512
    machines and differ from the C library's in the last bit there."""
    vn, ve, vh = s[3], s[4], s[5]
    for c in range(o.shape[0]):
        o[c] = 0.0
    o[0] = math.hypot(vn, ve)
    o[2] = -vh
    o[5] = math.atan2(ve, vn)
    o[9] = s[0]
    o[10] = s[1]
    o[11] = s[2]


@njit(cache=True)
def _resimulate(prev: np.ndarray, cmd: np.ndarray, frame_dt: np.ndarray, first: int,
                latest: int, tau: float, i: int, ckpt: np.ndarray, obs_hist: np.ndarray,
                state: np.ndarray) -> None:
    """Row ``i`` re-simulated from ``prev`` through frames ``first..latest`` with ``cmd``
    into its ring slots (``f % H``; ``frame_dt`` the ring's steps) and ``state``:
    :meth:`PointMass.step_frames` (its gain, :meth:`PointMass.step`'s operations) and
    :func:`_observe_rows`, in one call."""
    s = prev.copy()
    _resimulate_in(s, cmd, frame_dt, first, latest, tau, i, ckpt, obs_hist)
    state[i] = s


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _resimulate_in(s: np.ndarray, cmd: np.ndarray, frame_dt: np.ndarray, first: int,
                   latest: int, tau: float, i: int, ckpt: np.ndarray,
                   obs_hist: np.ndarray) -> None:
    """:func:`_resimulate`'s frames, stepping row ``s`` in place (it ends as the newest
    state; nothing is allocated, so a loop compiled without reference counting may call
    it)."""
    H = frame_dt.shape[0]
    for f in range(first, latest + 1):
        slot = f % H
        dt = frame_dt[slot]
        a = 1.0 - math.exp(-dt / tau)
        for c in range(3):
            v0 = s[3 + c]
            v1 = v0 + a * (cmd[c] - v0)
            s[c] = s[c] + 0.5 * (v0 + v1) * dt
            s[3 + c] = v1
        for c in range(6):
            ckpt[slot, i, c] = s[c]
        _observe_row(s, obs_hist[slot, i])


class PointMass:
    """Point mass with velocity-command tracking (see module docstring)."""

    name = "pointmass"
    state_dim = 6
    command_dim = 3
    #: a rollback re-simulates at once through :meth:`step_frames` (one compiled call),
    #: cheaper than deferring it to a batched step per frame in Python
    defer_rollbacks = False
    #: :meth:`step` reads neither the frame index nor the node ids: rows of different
    #: frames (scenes of a learning env) may share one call
    frame_free = True
    #: :meth:`observe` maps each row alone, by elementwise numpy calls on its columns
    #: (the same operations whichever rows share the call): the states of many swarms
    #: may be observed in one call (a learning env's scenes)
    observe_rows = True

    def __init__(self, spacing: float = 10.0, cruise: float = 10.0, altitude: float = 100.0,
                 tau: float = 0.5) -> None:
        if tau <= 0:
            raise ValueError(f"pointmass.tau must be > 0, got {tau}")
        self.spacing = spacing
        self.cruise = cruise
        self.altitude = altitude
        self.tau = tau

    def initial_state(self, n: int) -> NDArray[np.float64]:
        side = max(1, math.ceil(math.sqrt(n)))
        i = np.arange(n)
        s = np.zeros((n, 6))
        s[:, 0] = (i // side) * self.spacing
        s[:, 1] = (i % side) * self.spacing
        s[:, 2] = self.altitude
        s[:, 3] = self.cruise
        return s

    def default_command(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.tile(np.array([self.cruise, 0.0, 0.0]), (state.shape[0], 1))

    def step(self, state: NDArray[np.float64], command: NDArray[np.float64], dt: float,
             frame: int, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        a = (1.0 - math.exp(-dt / self.tau))
        if (state.dtype == np.float64 and command.dtype == np.float64 and state.ndim == 2
                and state.shape[1] == 6 and command.shape == (state.shape[0], 3)):
            out = np.empty(state.shape)
            _step_rows(state, command, float(dt), a, out)  # compiled: the same operations
            return out
        v0 = state[:, 3:6]
        v1 = v0 + a * (command - v0)
        out = np.empty_like(state)
        out[:, 0:3] = state[:, 0:3] + 0.5 * (v0 + v1) * dt
        out[:, 3:6] = v1
        return out

    def step_frames(self, state: NDArray[np.float64], command: NDArray[np.float64],
                    dts: NDArray[np.float64], first_frame: int, node: int
                    ) -> NDArray[np.float64]:
        """One aircraft through consecutive frames (a time-warp re-simulation).

        Row ``j`` of the result is :meth:`step` of row ``j-1`` (``state`` for j = 0) by
        ``dts[j]``: the same operations on the same floats, compiled, without a Python
        call per frame (the gain ``1 - exp(-dt / tau)`` is Python's, as in :meth:`step`).

        Args:
            state: ``(6,)`` start state.
            command: ``(3,)`` command held over all frames.
            dts: ``(m,)`` frame steps.
            first_frame: frame the first step leads to (the model does not depend on it).
            node: the aircraft's node id (likewise).
        """
        d = np.array(dts, dtype=np.float64).reshape(-1)
        m = d.size
        if m and d.min() == d.max():  # one rate throughout (the usual case): one gain
            gains = np.full(m, 1.0 - math.exp(-float(d[0]) / self.tau))
        else:
            gains = np.array([1.0 - math.exp(-x / self.tau) for x in d.tolist()])
        out = np.empty((m, 6))
        _step_frames(np.ascontiguousarray(state, dtype=np.float64).reshape(6),
                     np.ascontiguousarray(command, dtype=np.float64).reshape(3),
                     d, gains, out)
        return out

    def resimulate_into(self, prev: NDArray[np.float64], row: NDArray[np.float64],
                        frame_dt: NDArray[np.float64], first: int, latest: int, i: int,
                        ckpt: NDArray[np.float64], obs_hist: NDArray[np.float64],
                        state: NDArray[np.float64]) -> None:
        """A time-warp re-simulation of row ``i`` written into a physics ring in one call.

        Frames ``first..latest`` (at least one) from ``prev`` with ``row`` held, each
        ``f`` by ``frame_dt[f % H]``: its state into ``ckpt[f % H, i]``, its
        :meth:`observe` row into ``obs_hist[f % H, i]``, the last state into
        ``state[i]`` -- :meth:`step_frames` then :meth:`observe`, the same floats.
        """
        _resimulate(np.ascontiguousarray(prev, dtype=np.float64).reshape(6),
                    np.ascontiguousarray(row, dtype=np.float64).reshape(3), frame_dt,
                    int(first), int(latest), float(self.tau), int(i), ckpt, obs_hist, state)

    def compiled_physics(self) -> tuple[Any, Any, Any, NDArray[np.float64]]:
        """The compiled kernels a compiled control loop steps, observes and re-simulates
        the swarm with (:mod:`sigma_des.events.fast.control`): ``step(state, cmd, dt,
        params, out)``, ``observe(state, out)``, ``resimulate(prev, row, frame_dt, first,
        latest, params, i, ckpt, obs_hist, state)`` and ``params``: the same bits as
        :meth:`step`, :meth:`observe` and :meth:`resimulate_into`."""
        return _step_gain, _observe_rows, _resim_gain, np.array([float(self.tau)])

    def observe_into(self, state: NDArray[np.float64], out: NDArray[np.float64]) -> None:
        """:meth:`observe` written into ``out`` (``(n, 12)`` float64), compiled."""
        _observe_rows(state, out)

    def observe(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """``[speed, 0, -vh, 0, 0, psi, 0, 0, 0, x, y, h]`` of each row: ``speed =
        hypot(vn, ve)``, ``psi = atan2(ve, vn)`` (the compiled kernel every path uses,
        :func:`_observe_row`)."""
        obs = np.empty((state.shape[0], 12))
        _observe_rows(np.ascontiguousarray(state, dtype=np.float64), obs)
        return obs
