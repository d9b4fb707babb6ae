"""A minimal flocking behaviour for the core simulator: velocity consensus plus cohesion.

Each node steers towards the mean velocity of the swarm it is shown plus a pull
towards the shown centroid. It works with any dynamics model whose command is a
desired NED velocity ``(vn, ve, vh)`` (the point mass) or the common guidance
command ``(v, chi, h)`` (speed, course, altitude).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import DynamicsModel, SwarmView

__all__ = ["Cohesion", "velocity_to_command"]


def velocity_to_command(
    dynamics: DynamicsModel,
    vn: NDArray[np.float64],
    ve: NDArray[np.float64],
    h: NDArray[np.float64],
    vh: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Express desired NED velocity / altitude in ``dynamics``'s command columns."""
    names = tuple(getattr(dynamics, "command_names", ("vn", "ve", "vh")))
    cols = {
        "vn": vn,
        "ve": ve,
        "vh": vh,
        "v": np.hypot(vn, ve),
        "v_cmd": np.hypot(vn, ve),
        "chi": np.arctan2(ve, vn),
        "chi_cmd": np.arctan2(ve, vn),
        "h": h,
        "h_cmd": h,
    }
    out = np.full((vn.shape[0], dynamics.command_dim), np.nan)
    for j, name in enumerate(names[: dynamics.command_dim]):
        if name in cols:
            out[:, j] = cols[name]
    return out


class Cohesion:
    """Velocity consensus + cohesion.

    Args:
        gain: pull towards the centroid (1/s).
        max_pull: cap of the pull speed (m/s).
    """

    name = "cohesion"

    def __init__(self, gain: float = 0.05, max_pull: float = 3.0) -> None:
        if gain < 0:
            raise ValueError(f"cohesion.gain must be >= 0, got {gain}")
        self.gain = gain
        self.max_pull = max_pull

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> NDArray[np.float64]:
        obs = view.obs
        valid = view.valid
        n = obs.shape[0]
        out = np.full((n, dynamics.command_dim), np.nan)
        if not valid.any():
            return out
        o = obs[valid]
        speed, psi = o[:, 0], o[:, 5]
        vn_mean = float(np.mean(speed * np.cos(psi)))
        ve_mean = float(np.mean(speed * np.sin(psi)))
        centroid = o[:, 9:12].mean(axis=0)
        pull = self.gain * (centroid[None, :] - o[:, 9:12])
        norm = np.linalg.norm(pull[:, :2], axis=1, keepdims=True)
        scale = np.minimum(1.0, self.max_pull / np.maximum(norm, 1e-12))
        pull[:, :2] *= scale
        vn = vn_mean + pull[:, 0]
        ve = ve_mean + pull[:, 1]
        vh = np.clip(pull[:, 2], -1.0, 1.0)
        out[valid] = velocity_to_command(dynamics, vn, ve, centroid[2] + 0 * vn, vh)
        return out
