"""The ideal run: closed loop with zero latency and perfect alignment (MODEL.md, "Metrics").

Every frame the behaviour sees the true current state of every node (the view a
perfect alignment method would deliver with no delay), its commands take effect
at the next step, and positions are logged at ``log_rate`` Hz by linear
interpolation between frames — the reference trajectories for DTW fidelity.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import Behaviour, DynamicsModel, SwarmView

__all__ = ["fly"]


def fly(dynamics: DynamicsModel, behaviour: Behaviour | None, n: int, duration: float,
        dt: float, log_rate: float = 30.0, state: NDArray[np.float64] | None = None,
        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run the ideal closed loop.

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
    nodes = np.arange(n, dtype=np.int64)
    s = dynamics.initial_state(n) if state is None else np.array(state, dtype=np.float64)
    cmd = dynamics.default_command(s)
    frames = int(round(duration / dt))
    times = np.arange(int(np.floor(duration * log_rate + 1e-9)) + 1) / log_rate
    out = np.empty((len(times), n, 3))
    obs = dynamics.observe(s)
    prev_pos, prev_t, j = obs[:, 9:12].copy(), 0.0, 0
    valid = np.ones(n, dtype=bool)
    while j < len(times) and times[j] <= 0.0:
        out[j] = prev_pos
        j += 1
    for k in range(frames):
        if behaviour is not None:
            view = SwarmView(obs=obs, frame=np.full(n, k, dtype=np.int64), valid=valid,
                             aligned_frame=k)
            new = behaviour.commands(view, dynamics)
            rows = ~np.all(np.isnan(new), axis=1)
            cmd[rows] = new[rows]
        s = dynamics.step(s, cmd, dt, k + 1, nodes)
        obs = dynamics.observe(s)
        pos, t = obs[:, 9:12], (k + 1) * dt
        while j < len(times) and times[j] <= t + 1e-12:
            w = (times[j] - prev_t) / dt
            out[j] = (1 - w) * prev_pos + w * pos
            j += 1
        prev_pos, prev_t = pos.copy(), t
    return times[:j], out[:j]
