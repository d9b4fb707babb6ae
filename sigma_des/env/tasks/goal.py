"""The goal task: every node flies to its own random goal near its start (quick tests)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sigma_des.core.models import DynamicsModel
from sigma_des.core.rng import Stream
from sigma_des.env.tasks.base import Array, Task
from sigma_des.errors import ConfigError

__all__ = ["GoalTask"]


@dataclass(frozen=True)
class GoalTask(Task):
    """Every node flies to its own goal near its start (a quick task).

    Attributes:
        radius: largest goal offset from the start position (m).
    """

    radius: float = 20.0

    name = "goal"
    obs_dim = 7

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.radius > 0:
            raise ConfigError("task.radius", f"must be > 0, got {self.radius}")

    def scale(self) -> float:
        return self.radius

    def initial_state(self, dyn: DynamicsModel, n: int) -> Array:
        """The model's initial state; a point mass starts at rest on its grid."""
        s = dyn.initial_state(n)
        if getattr(dyn, "name", "") == "pointmass":
            s[:, 0:2] *= 2.0  # 20 m grid: goals of neighbours may not coincide
            s[:, 3:6] = 0.0
        return s

    def episode(self, stream: Stream, initial_obs: Array) -> Any:
        n = initial_obs.shape[0]
        i = np.arange(n)
        r = self.radius * np.sqrt(stream.uniform(i, 0))
        a = 2.0 * math.pi * stream.uniform(i, 1)
        goal = initial_obs[:, 9:12].copy()
        goal[:, 0] += r * np.cos(a)
        goal[:, 1] += r * np.sin(a)
        return {"goal": goal}

    def targets(self, obs: Array, ep: Any, t: float) -> Array:
        return np.asarray(ep["goal"])

    def targets_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        return np.stack([np.asarray(ep["goal"]) for ep in eps])
