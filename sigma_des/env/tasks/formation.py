"""Formation tasks: a leader on a random route, followers keeping V-slots.

:class:`FormationTask` is the paper's demonstration (§V.B.1); :class:`TightTask` makes
delay matter by construction (a fast, sharply turning leader, 6 m slots) and adds the
age of every shown state it uses to the observation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.formation import formation_slots
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.core.rng import Stream
from sigma_des.env.scene_axis import (
    formation_targets_many,
    nearest_many,
    slot_offsets,
    velocity_many,
)
from sigma_des.env.task_kernels import formation_observe, formation_reward, tight_observe
from sigma_des.env.tasks.base import AGE_REF, OBS_CLIP, Array, Task, nearest, velocity
from sigma_des.errors import ConfigError

__all__ = ["FormationTask", "TightTask"]


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
        done = ep.get("turned")  # the turns of the segments before m, summed once a segment
        if done is None or done[0] != m:
            done = ep["turned"] = (m, w[:m].sum())
        return float(ep["psi0"] + self.segment * done[1] + (t - m * self.segment) * w[m])

    def targets(self, obs: Array, ep: Any, t: float) -> Array:
        slots = formation_slots(obs, 0, self.d, math.radians(self.theta_deg))
        return np.concatenate([slots, np.full((obs.shape[0], 1), obs[0, 11])], axis=1)

    def _extra_obs(self, obs: Array) -> list[Array]:
        return [np.broadcast_to(velocity(obs[:1]) / self.v_ref, (obs.shape[0], 2))]

    def scripted(self, view: SwarmView, ep: Any, t: float) -> Array:
        g = np.full((view.obs.shape[0], 4), np.nan)
        g[0, :3] = (self.leader_speed, self._heading(ep, t), ep["h0"])
        return g

    def targets_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        return formation_targets_many(obs, self.d, math.radians(self.theta_deg))

    def _extra_obs_many(self, obs: Array) -> list[Array]:
        return [np.broadcast_to(velocity_many(obs[:, :1]) / self.v_ref, obs.shape[:2] + (2,))]

    # The scene-axis observation and reward compiled (task_kernels: the same operations
    # as the numpy path of Task, which GoalTask and the tests keep using).
    def _leaders(self, obs: Array) -> tuple[Array, Array, Array, Array]:
        """Slot offsets and the cos/sin of each scene's leader heading (``math``, as
        ``formation_targets_many``)."""
        dx, dy = slot_offsets(obs.shape[1], self.d, math.radians(self.theta_deg))
        psi = obs[:, 0, 5].tolist()
        return (dx, dy, np.array([math.cos(p) for p in psi]),
                np.array([math.sin(p) for p in psi]))

    def observe_many(self, obs: Array, valid: NDArray[np.bool_], eps: list[Any], t: Array,
                     agents: list[int], age: Array | None = None) -> NDArray[np.float32]:
        dx, dy, lc, ls = self._leaders(obs)
        lead = (velocity_many(obs[:, :1]) / self.v_ref).reshape(-1, 2)
        return formation_observe(np.ascontiguousarray(obs, dtype=np.float64), valid,
                                 np.cos(obs[..., 5]), np.sin(obs[..., 5]), lead, lc, ls, dx, dy,
                                 np.asarray(agents, dtype=np.int64), self.d, self.v_ref,
                                 OBS_CLIP)

    def reward_many(
        self, truth: Array, eps: list[Any], t: Array, agents: list[int], actions: Array
    ) -> tuple[Array, NDArray[np.bool_], Array]:
        dx, dy, lc, ls = self._leaders(truth)
        L = self.scale()
        return formation_reward(np.ascontiguousarray(truth, dtype=np.float64), lc, ls, dx, dy,
                                np.asarray(agents, dtype=np.int64),
                                np.ascontiguousarray(actions, dtype=np.float64), L,
                                self.div * L, self.w_sep, self.r_safe, self.w_u, self.r_col,
                                self.penalty)

    def scripted_many(self, obs: Array, eps: list[Any], t: Array) -> Array:
        g = np.full(obs.shape[:2] + (4,), np.nan)
        g[:, 0, 0] = self.leader_speed
        g[:, 0, 1] = [self._heading(ep, float(tt)) for ep, tt in zip(eps, t, strict=True)]
        g[:, 0, 2] = [ep["h0"] for ep in eps]
        return g


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
        vel = velocity(obs) / self.v_ref
        a = (age / AGE_REF)[:, None]
        rel, _, j = nearest(pos[:, :2])
        return [(tgt[:, 0:2] - obs[:, 9:11]) / self.d, ((tgt[:, 2] - obs[:, 11]) / 10.0)[:, None],
                vel, a, np.broadcast_to(vel[:1], (n, 2)), np.broadcast_to(a[:1], (n, 1)),
                rel / self.d, vel[j], a[j]]

    def observe_many(self, obs: Array, valid: NDArray[np.bool_], eps: list[Any], t: Array,
                     agents: list[int], age: Array | None = None) -> NDArray[np.float32]:
        dx, dy, lc, ls = self._leaders(obs)
        return tight_observe(np.ascontiguousarray(obs, dtype=np.float64), valid,
                             np.zeros(obs.shape[:2]) if age is None
                             else np.ascontiguousarray(age, dtype=np.float64),
                             np.cos(obs[..., 5]), np.sin(obs[..., 5]), lc, ls, dx, dy,
                             np.asarray(agents, dtype=np.int64), self.d, self.v_ref, AGE_REF,
                             OBS_CLIP)

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
