"""The interpolation study (the paper's Table III in kind): dense flights, sparse noisy logs.

:func:`dense_flight` flies aircraft in closed loop (the ideal run: behaviour on the true
state) and keeps every frame; :func:`sparse_log` decimates it to a log rate and adds
sensor noise (keyed counter-based draws); :func:`score` interpolates the log back at
every dense instant that is not a logged one (the held-out instants) and returns mean,
max and RMSE of the 3-D position error against the noise-free truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.ideal import closed_loop
from sigma_des.core.models import Behaviour, DynamicsModel
from sigma_des.core.rng import RandomStreams
from sigma_des.record.tap import obs_to_ned
from sigma_des.replay.interpolate import interpolate
from sigma_des.replay.window import WindowRule

__all__ = ["Flight", "Noise", "dense_flight", "score", "sparse_log"]

_F = NDArray[np.float64]


@dataclass(frozen=True)
class Flight:
    """Per node and frame: time, NED position, NED velocity, Euler angles.

    Attributes:
        t: ``(T,)`` times (s).
        pos, vel, att: ``(T, n, 3)``.
    """

    t: _F
    pos: _F
    vel: _F
    att: _F


@dataclass(frozen=True)
class Noise:
    """White sensor noise on the log (standard deviations per sample).

    Attributes:
        pos: position, m (each axis).
        vel: velocity, m/s (each axis).
        att: Euler angles, rad.
    """

    pos: float = 0.1
    vel: float = 0.05
    att: float = 0.01


def dense_flight(dynamics: DynamicsModel, behaviour: Behaviour | None, n: int,
                 duration: float, dt: float) -> Flight:
    """Fly ``n`` aircraft for ``duration`` s at step ``dt`` (the ideal closed loop,
    :func:`~sigma_des.agents.ideal.closed_loop`) and keep every frame."""
    frames = int(round(duration / dt))
    allobs = np.stack([obs.copy() for obs in closed_loop(dynamics, behaviour, n, frames, dt)])
    T = allobs.shape[0]
    pos, vel, att = obs_to_ned(allobs.reshape(T * n, -1))
    shape = (T, n, 3)
    t = np.arange(T, dtype=np.float64) * dt
    return Flight(t, pos.reshape(shape), vel.reshape(shape), att.reshape(shape))


def sparse_log(f: Flight, every: int, noise: Noise, seed: int, start: int = 0,
               ) -> tuple[NDArray[np.intp], Flight]:
    """Every ``every``-th frame from ``start``, with noise (stream ``replay.noise``).

    Returns:
        The logged frame indices and the noisy log.
    """
    idx = np.arange(start, f.t.size, every)
    st = RandomStreams(seed).stream("replay.noise")
    n = f.pos.shape[1]
    fr = idx[:, None, None]
    nd = np.arange(n)[None, :, None]

    def noisy(x: _F, sigma: float, ch: int) -> _F:
        axes = np.arange(3)[None, None, :] + ch
        return x[idx] + sigma * st.normal(nd, fr, axes) if sigma > 0 else x[idx].copy()

    return idx, Flight(f.t[idx], noisy(f.pos, noise.pos, 0), noisy(f.vel, noise.vel, 3),
                       noisy(f.att, noise.att, 6))


def score(f: Flight, idx: NDArray[np.intp], log: Flight, method: str,
          window: WindowRule | None = None) -> dict[str, float]:
    """3-D position error of ``method`` on the held-out dense instants, over all nodes.

    Held-out instants are the dense frames strictly inside the logged span that were
    not logged.
    """
    held = np.setdiff1d(np.arange(idx[0], idx[-1] + 1), idx)
    errs = []
    for i in range(f.pos.shape[1]):
        got = interpolate(log.t, log.pos[:, i], method=method, at=f.t[held],
                          velocities=log.vel[:, i], attitudes=log.att[:, i], window=window)
        errs.append(np.linalg.norm(got - f.pos[held, i], axis=1))
    e = np.concatenate(errs)
    return {"mean": float(e.mean()), "max": float(e.max()),
            "rmse": float(np.sqrt(np.mean(e**2))), "n": float(e.size)}
