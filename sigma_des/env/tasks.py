"""Learning tasks of the swarm environment: observation, action, reward, termination.

A task turns what the distributed loop delivers (the *aligned* swarm view of the
alignment server, :class:`~sigma_des.core.models.SwarmView`) into per-agent
observations, the agents' actions into command rows that travel to the nodes, and
the *true* swarm state (the physics at the latest frame) into rewards and
terminations. Observations see the network; rewards see the truth.

Action (every task): ``a in [-1, 1]^3`` per agent = desired north and east velocity
``(a0, a1) * v_max`` (m/s) and an altitude change ``a2 * dh_max`` (m) from the
agent's shown altitude, sent as the guidance row ``[v, chi, h, nan]`` (the autopilot's
guidance interface, one level above the paper's attitude and throttle).

Tasks:

* :class:`FormationTask` (the paper's demonstration): node 0, the leader, flies a
  random route per episode (stream ``env.route``; its commands travel over the
  network too); nodes ``1..n-1`` are the agents and keep the V-slots. Observation (9 columns,
  clipped to [-10, 10], from the shown states): slot error, altitude error to the
  leader, leader and own velocity, nearest neighbour's offset. Reward per agent:
  ``-(e / d)^2 - w_sep max(0, 1 - d_min / r_safe)^2 - w_u |a|^2 / 3`` (``e`` the true
  slot error clipped at ``div * d``); ``-penalty`` more for a collision or a
  divergence, which terminates every agent.
* :class:`GoalTask` (quick tests): every node flies to its own goal (7 columns);
  reward ``-(e / radius)^2`` plus the same separation, effort and ending terms.
* :class:`TightTask` (delay matters by construction): a fast, sharply turning leader
  and 6 m slots; the observation adds the *age* of every shown state it uses (14).

An agent whose own state has not been shown yet observes zeros and sends nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.behaviours import to_command
from sigma_des.agents.formation import formation_slots
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.core.rng import Stream
from sigma_des.env.scene_axis import formation_targets_many, nearest_many, velocity_many
from sigma_des.errors import ConfigError

__all__ = ["TASKS", "Task", "FormationTask", "GoalTask", "TightTask", "make_task", "ACTION_DIM",
           "AGE_REF"]

Array = NDArray[np.float64]

#: Action columns per agent: north velocity, east velocity, altitude change (normalised).
ACTION_DIM = 3
OBS_CLIP = 10.0
#: Age scale of the observed ages (s): an observed age of 1 is 100 ms.
AGE_REF = 0.1


def _nearest(pos: Array) -> tuple[Array, Array, NDArray[np.intp]]:
    """Offset to the nearest other node, its distance and index, per node (O(n^2))."""
    diff = pos[None, :, :] - pos[:, None, :]
    dist = np.sqrt((diff**2).sum(-1))
    np.fill_diagonal(dist, np.inf)
    j = np.argmin(dist, axis=1)
    i = np.arange(len(pos))
    return diff[i, j], dist[i, j], j


def _velocity(obs: Array) -> Array:
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
        rel, _, _ = _nearest(pos[:, :2])
        L = self.scale()
        cols = [
            (tgt[:, 0:2] - obs[:, 9:11]) / L,
            ((tgt[:, 2] - obs[:, 11]) / 10.0)[:, None],
        ]
        cols += self._extra_obs(obs)
        return cols + [_velocity(obs) / self.v_ref, rel / L]

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
        _, dmin, _ = _nearest(truth[:, 9:12])
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


@dataclass(frozen=True)
class FormationTask(Task):
    """Leader on a random route, followers keep V-slots (paper §V.B.1).

    Attributes:
        d: slot spacing (m).
        theta_deg: V half-angle (degrees).
        leader_speed: leader ground speed (m/s).
        turn_max: largest leader turn rate (rad/s).
        segment: duration of one constant-turn segment of the route (s).
    """

    d: float = 15.0
    theta_deg: float = 45.0
    leader_speed: float = 10.0
    turn_max: float = 0.15
    segment: float = 2.0

    name = "formation"
    obs_dim = 9

    def __post_init__(self) -> None:
        super().__post_init__()
        for key in ("d", "leader_speed", "segment"):
            if not getattr(self, key) > 0:
                raise ConfigError(f"task.{key}", f"must be > 0, got {getattr(self, key)}")

    def agents(self, n: int) -> list[int]:
        return list(range(1, n))

    def scale(self) -> float:
        return self.d

    def initial_state(self, dyn: DynamicsModel, n: int) -> Array:
        """The model's initial state; a point mass starts in its slot, flying north."""
        s = dyn.initial_state(n)
        if getattr(dyn, "name", "") == "pointmass":
            obs = np.zeros((n, 12))
            obs[0, 9:12] = s[0, 0:3]
            slots = formation_slots(obs, 0, self.d, math.radians(self.theta_deg))
            s[:, 0:2] = slots
            s[:, 2] = s[0, 2]
            s[:, 3] = self.leader_speed
            s[:, 4:6] = 0.0
        return s

    def episode(self, stream: Stream, initial_obs: Array) -> Any:
        """Route: start heading and per-segment turn rates (from ``env.route``)."""
        return {"psi0": float(initial_obs[0, 5]), "h0": float(initial_obs[0, 11]),
                "stream": stream}

    def _heading(self, ep: Any, t: float) -> float:
        m = int(t // self.segment)
        w = ep.get("turns")
        if w is None or w.size <= m:  # the draws are per segment id: a longer prefix
            u = ep["stream"].uniform(np.arange(max(m + 1, 32, 0 if w is None else 2 * w.size)))
            w = ep["turns"] = self.turn_max * (2.0 * u - 1.0)
        return float(ep["psi0"] + self.segment * w[:m].sum() + (t - m * self.segment) * w[m])

    def targets(self, obs: Array, ep: Any, t: float) -> Array:
        slots = formation_slots(obs, 0, self.d, math.radians(self.theta_deg))
        return np.concatenate([slots, np.full((obs.shape[0], 1), obs[0, 11])], axis=1)

    def _extra_obs(self, obs: Array) -> list[Array]:
        return [np.broadcast_to(_velocity(obs[:1]) / self.v_ref, (obs.shape[0], 2))]

    def scripted(self, view: SwarmView, ep: Any, t: float) -> Array:
        g = np.full((view.obs.shape[0], 4), np.nan)
        g[0, :3] = (self.leader_speed, self._heading(ep, t), ep["h0"])
        return g

    def targets_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        return formation_targets_many(obs, self.d, math.radians(self.theta_deg))

    def _extra_obs_many(self, obs: Array) -> list[Array]:
        return [np.broadcast_to(velocity_many(obs[:, :1]) / self.v_ref, obs.shape[:2] + (2,))]

    def scripted_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        g = np.full(obs.shape[:2] + (4,), np.nan)
        g[:, 0, 0] = self.leader_speed
        g[:, 0, 1] = [self._heading(ep, float(tt)) for ep, tt in zip(eps, t, strict=True)]
        g[:, 0, 2] = [ep["h0"] for ep in eps]
        return g


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


@dataclass(frozen=True)
class TightTask(FormationTask):
    """Tight, fast formation under a manoeuvring leader: delay matters by construction.

    The leader flies at 15 m/s and turns at up to 0.6 rad/s, changing turn rate every
    second; slots are 6 m apart. 200 ms of age is 3 m of leader travel — half a slot
    spacing — so a follower steering to the *shown* slot lags it. The observation
    carries what a policy needs to extrapolate: each shown state's age and velocity.

    Observation (14 columns, each clipped to [-10, 10]; ages ``/ AGE_REF`` = 0.1 s,
    velocities ``/ v_ref``, offsets ``/ d``, from the shown states): slot error N/E,
    altitude error ``/ 10 m``, own velocity N/E, own age; leader velocity N/E, leader
    age; nearest neighbour's offset N/E, velocity N/E and age. Ages are 0 under
    ``perfect_info`` (the true current state). Reward, termination: as the formation
    task (slot error, separation with r_safe = 3 m, collision below 1 m, divergence
    beyond ``div * d`` = 30 m).
    """

    d: float = 6.0
    leader_speed: float = 15.0
    turn_max: float = 0.6
    segment: float = 1.0
    r_safe: float = 3.0

    name = "tight"
    obs_dim = 14

    def columns(self, obs: Array, ep: Any, t: float, age: Array) -> list[Array]:
        n = obs.shape[0]
        pos = np.nan_to_num(obs[:, 9:12], nan=1e9)
        tgt = self.targets(obs, ep, t)
        vel = _velocity(obs) / self.v_ref
        a = (age / AGE_REF)[:, None]
        rel, _, j = _nearest(pos[:, :2])
        return [(tgt[:, 0:2] - obs[:, 9:11]) / self.d, ((tgt[:, 2] - obs[:, 11]) / 10.0)[:, None],
                vel, a, np.broadcast_to(vel[:1], (n, 2)), np.broadcast_to(a[:1], (n, 1)),
                rel / self.d, vel[j], a[j]]

    def columns_many(self, obs: Array, eps: list[Any], t: Array, age: Array) -> list[Array]:
        S, n = obs.shape[:2]
        pos = np.nan_to_num(obs[..., 9:12], nan=1e9)
        tgt = self.targets_many(obs, eps, t)
        vel = velocity_many(obs) / self.v_ref
        a = (age / AGE_REF)[..., None]
        rel, _, j = nearest_many(pos[..., :2])
        s = np.arange(S)[:, None]
        return [(tgt[..., 0:2] - obs[..., 9:11]) / self.d,
                ((tgt[..., 2] - obs[..., 11]) / 10.0)[..., None],
                vel, a, np.broadcast_to(vel[:, :1], (S, n, 2)),
                np.broadcast_to(a[:, :1], (S, n, 1)), rel / self.d, vel[s, j], a[s, j]]


#: Task name -> class.
TASKS: dict[str, type[Task]] = {"formation": FormationTask, "goal": GoalTask,
                                "tight": TightTask}


def make_task(name: str, params: dict[str, Any] | None = None) -> Task:
    """The task called ``name`` with ``params`` (unknown names and keys are errors)."""
    if name not in TASKS:
        raise ConfigError("task", f"unknown task {name!r}; allowed: {sorted(TASKS)}")
    cls = TASKS[name]
    allowed = {f.name for f in fields(cls)}
    for k in params or {}:
        if k not in allowed:
            raise ConfigError(f"task.{k}", f"unknown key for task {name!r}; allowed: "
                              f"{sorted(allowed)}")
    return cls(**(params or {}))
