"""What every learning task shares: the action, the observation and reward pipeline.

:class:`Task` turns the aligned swarm view into per-agent observations (its
``columns``), the agents' actions into guidance command rows, and the true swarm
state into rewards and failures. Each operation exists twice: for one scene, and
``*_many`` with a leading scene axis — the same operations, so the same bits
(``tests/env/test_batched.py``) — which the vector env uses to make a few numpy calls
per step instead of a few per scene. A task subclass supplies its targets, its
scripted nodes and any extra observation columns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.behaviours import to_command
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.core.rng import Stream
from sigma_des.env.scene_axis import nearest_many, velocity_many
from sigma_des.env.task_kernels import agent_guidance, velocity_commands
from sigma_des.errors import ConfigError

__all__ = ["Task", "ACTION_DIM", "OBS_CLIP", "AGE_REF", "nearest", "velocity"]

Array = NDArray[np.float64]

#: Action columns per agent: north velocity, east velocity, altitude change (normalised).
ACTION_DIM = 3
OBS_CLIP = 10.0
#: Age scale of the observed ages (s): an observed age of 1 is 100 ms.
AGE_REF = 0.1


def nearest(pos: Array) -> tuple[Array, Array, NDArray[np.intp]]:
    """Offset to the nearest other node, its distance and index, per node (O(n^2))."""
    diff = pos[None, :, :] - pos[:, None, :]
    dist = np.sqrt((diff**2).sum(-1))
    np.fill_diagonal(dist, np.inf)
    j = np.argmin(dist, axis=1)
    i = np.arange(len(pos))
    return diff[i, j], dist[i, j], j


#: the command columns of a velocity-commanded model (the point mass)
_VELOCITY = ("vn", "ve", "vh")


def _velocity_commands_many(g: Array, speed: Array, course: Array, a: Array, obs: Array,
                            valid: NDArray[np.bool_], agents: list[int], dh_max: float
                            ) -> tuple[NDArray[np.bool_], Array]:
    """:meth:`Task.commands_many` after its speed and course, for a model commanded in
    ``vn, ve, vh`` (:func:`~sigma_des.agents.behaviours.to_command`'s columns): the
    arithmetic compiled (:mod:`~sigma_des.env.task_kernels`), the cos and sin numpy's on
    the sent rows as ``to_command`` takes them; the same bits."""
    send = np.empty(g.shape[:2], dtype=np.bool_)
    obs = np.ascontiguousarray(obs)
    agent_guidance(g, speed, course, np.ascontiguousarray(a), obs,
                   np.ascontiguousarray(valid), np.asarray(agents, dtype=np.int64), dh_max,
                   send)
    cmds = np.zeros(g.shape[:2] + (3,))
    rows = g[send]
    if rows.shape[0]:
        chi = rows[:, 1]
        velocity_commands(rows, np.cos(chi), np.sin(chi), obs, send, cmds)
    return send, cmds


def velocity(obs: Array) -> Array:
    """North/east velocity from the published body speed and heading."""
    return np.stack([obs[:, 0] * np.cos(obs[:, 5]), obs[:, 0] * np.sin(obs[:, 5])], axis=1)


@dataclass(frozen=True)
class Task:
    """Parameters and logic shared by the tasks (see the module docstring).

    Attributes:
        v_max: speed of a full action (m/s).
        dh_max: altitude change of a full action (m).
        v_ref: velocity scale of observations (m/s).
        r_safe: separation below which the separation penalty starts (m).
        r_col: true separation that counts as a collision (m).
        div: divergence threshold in units of the task's length scale.
        w_sep: weight of the separation penalty.
        w_u: weight of the control-effort penalty.
        penalty: extra negative reward of a colliding or diverging agent.
    """

    v_max: float = 20.0
    dh_max: float = 10.0
    v_ref: float = 10.0
    r_safe: float = 5.0
    r_col: float = 1.0
    div: float = 5.0
    w_sep: float = 1.0
    w_u: float = 0.01
    penalty: float = 10.0

    name = "task"
    obs_dim = 0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"task.{f.name}", f"must be a finite number >= 0, got {v!r}")
        for key in ("v_max", "v_ref", "r_safe", "div"):
            if not getattr(self, key) > 0:
                raise ConfigError(f"task.{key}", f"must be > 0, got {getattr(self, key)}")

    # ---------------------------------------------------------------- per task
    def agents(self, n: int) -> list[int]:
        """Node ids of the learning agents of an ``n``-node swarm."""
        return list(range(n))

    def scale(self) -> float:
        """Length scale of errors (m)."""
        raise NotImplementedError

    def initial_state(self, dyn: DynamicsModel, n: int) -> Array:
        """The fixed initial state of every episode (the model's own, by default)."""
        return dyn.initial_state(n)

    def episode(self, stream: Stream, initial_obs: Array) -> Any:
        """Per-episode random data (route, goals) from the scene's stream."""
        return None

    def targets(self, obs: Array, ep: Any, t: float) -> Array:
        """``(n, 3)`` target north, east, altitude of every node given states ``obs``."""
        raise NotImplementedError

    def scripted(self, view: SwarmView, ep: Any, t: float) -> Array:
        """``(n, 4)`` guidance of the scripted (non-agent) nodes; NaN rows elsewhere."""
        return np.full((view.obs.shape[0], 4), np.nan)

    # ---------------------------------------------------------------- shared
    def observe(self, view: SwarmView, ep: Any, t: float, agents: list[int],
                age: Array | None = None) -> NDArray[np.float32]:
        """``(len(agents), obs_dim)`` observations from the shown swarm view.

        ``age`` (s, per node: now minus the generation time of its shown state; NaN
        where none; None = all 0) is used by the tasks that observe it (``tight``).
        Columns come from :meth:`columns`; rows of agents with no shown state are 0.
        """
        n = view.obs.shape[0]
        age = np.zeros(n) if age is None else np.nan_to_num(age, nan=0.0)
        out = np.concatenate(self.columns(view.obs, ep, t, age), axis=1)[agents]
        out[~view.valid[agents]] = 0.0
        return np.clip(np.nan_to_num(out, nan=0.0), -OBS_CLIP, OBS_CLIP).astype(np.float32)

    def columns(self, obs: Array, ep: Any, t: float, age: Array) -> list[Array]:
        """Observation column blocks ``(n, k)`` of every node from shown states ``obs``."""
        pos = np.nan_to_num(obs[:, 9:12], nan=1e9)
        tgt = self.targets(obs, ep, t)
        rel, _, _ = nearest(pos[:, :2])
        L = self.scale()
        cols = [
            (tgt[:, 0:2] - obs[:, 9:11]) / L,
            ((tgt[:, 2] - obs[:, 11]) / 10.0)[:, None],
        ]
        cols += self._extra_obs(obs)
        return cols + [velocity(obs) / self.v_ref, rel / L]

    def _extra_obs(self, obs: Array) -> list[Array]:
        return []

    def commands(
        self, actions: Array, view: SwarmView, ep: Any, t: float, agents: list[int],
        dyn: DynamicsModel,
    ) -> tuple[NDArray[np.int64], Array]:
        """Nodes to command and their command rows (scripted nodes and agents)."""
        n = view.obs.shape[0]
        g = self.scripted(view, ep, t)
        a = np.asarray(actions, dtype=np.float64)
        vn, ve = a[:, 0] * self.v_max, a[:, 1] * self.v_max
        g[agents, 0] = np.hypot(vn, ve)
        g[agents, 1] = np.arctan2(ve, vn)
        g[agents, 2] = view.obs[agents, 11] + a[:, 2] * self.dh_max
        send = ~np.isnan(g[:, 0]) & ~np.isnan(g[:, 2]) & view.valid
        nodes = np.flatnonzero(send)
        cmds = np.zeros((n, dyn.command_dim))
        if nodes.size:
            cmds[nodes] = to_command(g[nodes], dyn, view.obs[nodes])
        return nodes.astype(np.int64), cmds

    def reward(
        self, truth: Array, ep: Any, t: float, agents: list[int], actions: Array
    ) -> tuple[Array, NDArray[np.bool_], Array]:
        """Rewards, per-agent failure (collision or divergence), true errors (m)."""
        tgt = self.targets(truth, ep, t)
        e = np.linalg.norm(tgt - truth[:, 9:12], axis=1)[agents]
        _, dmin, _ = nearest(truth[:, 9:12])
        return self._scored(e, dmin[agents], actions)

    def _scored(self, e: Array, dmin: Array, actions: Array
                ) -> tuple[Array, NDArray[np.bool_], Array]:
        """Rewards and failures from true errors ``e`` and nearest distances ``dmin`` (any
        leading shape, one scene or many; ``actions`` has one more axis, the last)."""
        L = self.scale()
        lim = self.div * L
        r = -(np.minimum(e, lim) / L) ** 2
        r -= self.w_sep * np.maximum(0.0, 1.0 - dmin / self.r_safe) ** 2
        r -= self.w_u * (np.asarray(actions, dtype=np.float64) ** 2).sum(axis=-1) / 3.0
        fail = (dmin < self.r_col) | (e > lim) | ~np.isfinite(e)
        r = np.where(fail, r - self.penalty, r)
        return r, fail, e

    # ------------------------------------------- many scenes at once (numpy over scenes)
    # The same operations as the one-scene methods above on arrays with a leading scene
    # axis, so every figure is the same bits (tests/env/test_batched.py); the env's
    # control plane then makes a few numpy calls per step instead of a few per scene.
    def targets_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        """``(S, n, 3)`` :meth:`targets` of every scene (``obs`` ``(S, n, 12)``)."""
        return np.stack([self.targets(o, ep, float(tt)) for o, ep, tt in zip(obs, eps, t,
                                                                              strict=True)])

    def scripted_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        """``(S, n, 4)`` :meth:`scripted` guidance of every scene."""
        return np.full(obs.shape[:2] + (4,), np.nan)

    def columns_many(self, obs: Array, eps: list[Any], t: Array, age: Array) -> list[Array]:
        """:meth:`columns` of every scene: blocks ``(S, n, k)``."""
        pos = np.nan_to_num(obs[..., 9:12], nan=1e9)
        tgt = self.targets_many(obs, eps, t)
        rel, _, _ = nearest_many(pos[..., :2])
        L = self.scale()
        cols = [
            (tgt[..., 0:2] - obs[..., 9:11]) / L,
            ((tgt[..., 2] - obs[..., 11]) / 10.0)[..., None],
        ]
        cols += self._extra_obs_many(obs)
        return cols + [velocity_many(obs) / self.v_ref, rel / L]

    def _extra_obs_many(self, obs: Array) -> list[Array]:
        return []

    def observe_many(self, obs: Array, valid: NDArray[np.bool_], eps: list[Any], t: Array,
                     agents: list[int], age: Array | None = None) -> NDArray[np.float32]:
        """``(S, len(agents), obs_dim)`` :meth:`observe` of every scene."""
        age = np.zeros(obs.shape[:2]) if age is None else np.nan_to_num(age, nan=0.0)
        out = np.concatenate(self.columns_many(obs, eps, t, age), axis=2)[:, agents]
        out[~valid[:, agents]] = 0.0
        return np.clip(np.nan_to_num(out, nan=0.0), -OBS_CLIP, OBS_CLIP).astype(np.float32)

    def commands_many(
        self, actions: Array, obs: Array, valid: NDArray[np.bool_], eps: list[Any], t: Array,
        agents: list[int], dyn: DynamicsModel,
    ) -> tuple[NDArray[np.bool_], Array]:
        """:meth:`commands` of every scene: ``(S, n)`` send mask, ``(S, n, dim)`` rows."""
        g = self.scripted_many(obs, eps, t)
        a = np.asarray(actions, dtype=np.float64)
        vn, ve = a[..., 0] * self.v_max, a[..., 1] * self.v_max
        if (dyn.command_dim == 3
                and tuple(getattr(dyn, "command_names", _VELOCITY)) == _VELOCITY):
            return _velocity_commands_many(g, np.hypot(vn, ve), np.arctan2(ve, vn), a, obs,
                                           valid, agents, self.dh_max)
        g[:, agents, 0] = np.hypot(vn, ve)
        g[:, agents, 1] = np.arctan2(ve, vn)
        g[:, agents, 2] = obs[:, agents, 11] + a[..., 2] * self.dh_max
        send = ~np.isnan(g[..., 0]) & ~np.isnan(g[..., 2]) & valid
        cmds = np.zeros(obs.shape[:2] + (dyn.command_dim,))
        if send.any():
            cmds[send] = to_command(g[send], dyn, obs[send])
        return send, cmds

    def reward_many(
        self, truth: Array, eps: list[Any], t: Array, agents: list[int], actions: Array
    ) -> tuple[Array, NDArray[np.bool_], Array]:
        """:meth:`reward` of every scene (``truth`` ``(S, n, 12)``): ``(S, A)`` arrays."""
        tgt = self.targets_many(truth, eps, t)
        e = np.linalg.norm(tgt - truth[..., 9:12], axis=2)[:, agents]
        _, dmin, _ = nearest_many(truth[..., 9:12])
        return self._scored(e, dmin[:, agents], actions)
