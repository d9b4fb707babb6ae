"""The ideal run: closed loop with zero latency and perfect alignment (docs/concepts/metrics.md).

Every frame the behaviour sees the true current state of every node (the view a
perfect alignment method would deliver with no delay), its commands take effect
at the next step, and positions are logged at ``log_rate`` Hz by linear
interpolation between frames — the reference trajectories for DTW fidelity.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import Behaviour, DynamicsModel, SwarmView

__all__ = ["closed_loop", "fly"]


def closed_loop(dynamics: DynamicsModel, behaviour: Behaviour | None, n: int, frames: int,
                dt: float, state: NDArray[np.float64] | None = None,
                ) -> Iterator[NDArray[np.float64]]:
    """The ideal closed loop, frame by frame: the observations at frame 0, then after
    each of ``frames`` steps of ``dt``.

    Before step ``k`` the behaviour sees every node's true observation of frame ``k``;
    its commands (an all-NaN row: keep the command in force) drive step ``k + 1``.
    The arrays yielded are read-only use (the behaviour's next view).

    Args:
        dynamics: the model.
        behaviour: the behaviour (None: the model's default command throughout).
        n: number of aircraft (node ids ``0..n-1``).
        frames: number of steps.
        dt: physics step (s).
        state: initial state (default ``dynamics.initial_state(n)``).
    """
    nodes = np.arange(n, dtype=np.int64)
    s = dynamics.initial_state(n) if state is None else np.array(state, dtype=np.float64)
    cmd = dynamics.default_command(s)
    obs = dynamics.observe(s)
    yield obs
    valid = np.ones(n, dtype=bool)
    for k in range(frames):
        if behaviour is not None:
            view = SwarmView(obs=obs, frame=np.full(n, k, dtype=np.int64), valid=valid,
                             aligned_frame=k)
            new = behaviour.commands(view, dynamics)
            rows = ~np.all(np.isnan(new), axis=1)
            cmd[rows] = new[rows]
        s = dynamics.step(s, cmd, dt, k + 1, nodes)
        obs = dynamics.observe(s)
        yield obs


def fly(dynamics: DynamicsModel, behaviour: Behaviour | None, n: int, duration: float,
        dt: float, log_rate: float = 30.0, state: NDArray[np.float64] | None = None,
        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run the ideal closed loop (:func:`closed_loop`), logging positions.

    Args:
        dynamics: the model.
        behaviour: the behaviour (None: the model's default command throughout).
        n: number of aircraft (node ids ``0..n-1``).
        duration: simulated time (s).
        dt: physics step (s).
        log_rate: trajectory sampling rate (Hz); the paper samples at 30 Hz.
        state: initial state (default ``dynamics.initial_state(n)``).

    Returns:
        ``(times (T,), positions (T, n, 3))`` with columns north, east, altitude.
    """
    if dt <= 0 or duration <= 0 or log_rate <= 0:
        raise ValueError("fly: dt, duration and log_rate must be > 0")
    frames = int(round(duration / dt))
    times = np.arange(int(np.floor(duration * log_rate + 1e-9)) + 1) / log_rate
    out = np.empty((len(times), n, 3))
    loop = closed_loop(dynamics, behaviour, n, frames, dt, state)
    obs = next(loop)
    prev_pos, prev_t, j = obs[:, 9:12].copy(), 0.0, 0
    while j < len(times) and times[j] <= 0.0:
        out[j] = prev_pos
        j += 1
    for k, obs in enumerate(loop):
        pos, t = obs[:, 9:12], (k + 1) * dt
        while j < len(times) and times[j] <= t + 1e-12:
            w = (times[j] - prev_t) / dt
            out[j] = (1 - w) * prev_pos + w * pos
            j += 1
        prev_pos, prev_t = pos.copy(), t
    return times[:j], out[:j]
