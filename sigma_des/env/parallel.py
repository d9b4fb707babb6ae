"""The PettingZoo ``ParallelEnv`` of one scene: agents are the physics nodes.

``SwarmEnv()`` builds the formation task at a small default size (5 point-mass
nodes: a scripted leader and 4 learning followers, BiDES alignment). Agents are
named ``node_<i>`` after their node ids. Underneath runs the full distributed
loop; see :mod:`sigma_des.env.vector` (this env is its one-scene case without
autoreset) and :mod:`sigma_des.env.tasks` for the observation, action and reward.

Errors: an action of the wrong shape, non-float dtype, NaN/inf or outside [-1, 1],
an action for an unknown or finished agent, or a missing action of a live agent
raise a ``ValueError`` naming the agent and field, before anything is changed;
stepping a finished episode (or before ``reset``) raises ``RuntimeError``.
Reset options are not used: an unknown option is reported with a warning (the
PettingZoo API test passes one).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from sigma_des.env.resets import RENDER_MODES
from sigma_des.env.tasks import ACTION_DIM, OBS_CLIP
from sigma_des.env.vector import SwarmVec

__all__ = ["SwarmEnv"]


class SwarmEnv(ParallelEnv):  # type: ignore[misc]
    """PettingZoo parallel env over one scene (see module docstring).

    Args:
        task: ``formation`` or ``goal``.
        method: alignment method.
        scenario: scenario overrides (dotted keys -> values).
        task_params: task parameters.
        max_steps: decisions per episode.
        perfect_info: observe the true state instead of the aligned view.
        seed: root seed used by the first ``reset()`` without a seed.
        render_mode: None or ``"ansi"`` (:meth:`render` returns a text table of the
            true state, the agents' ages and errors).
        metrics: the scene's runs collect the simulator's measurements (False: none,
            faster, the same episodes; see :class:`~sigma_des.env.vector.SwarmVec`).
    """

    metadata = {"name": "sigma_des_swarm_v0", "render_modes": RENDER_MODES}

    def __init__(self, task: str = "formation", method: str = "bides",
                 scenario: Mapping[str, Any] | None = None,
                 task_params: Mapping[str, Any] | None = None, max_steps: int = 100,
                 perfect_info: bool = False, seed: int | None = None,
                 render_mode: str | None = None, metrics: bool = True) -> None:
        self.vec = SwarmVec(task, method, 1, scenario, task_params, max_steps, perfect_info,
                            seed, autoreset="disabled", render_mode=render_mode,
                            metrics=metrics)
        self.possible_agents = [f"node_{i}" for i in self.vec.agent_nodes]
        self.agents: list[str] = []
        self.render_mode = self.vec.render_mode
        self.state_space = self.vec.state_space

    @functools.cache  # noqa: B019 - spaces must be the same objects
    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        """Box of ``obs_dim`` float32 columns in [-10, 10] (see ``tasks``)."""
        self._index(agent)
        return gymnasium.spaces.Box(-OBS_CLIP, OBS_CLIP, (self.vec.obs_dim,), dtype=np.float32)

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        """Box of 3 float32 columns in [-1, 1] (see ``tasks``)."""
        self._index(agent)
        return gymnasium.spaces.Box(-1.0, 1.0, (ACTION_DIM,), dtype=np.float32)

    def _index(self, agent: str) -> int:
        try:
            return self.possible_agents.index(agent)
        except ValueError:
            raise ValueError(f"unknown agent {agent!r}; agents: {self.possible_agents}") from None

    def reset(self, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        """Start an episode (``seed``: episode 0 of that root seed; None: the next one)."""
        if options:
            warnings.warn(f"SwarmEnv.reset: options {sorted(options)} are not used "
                          "(configure the env at construction)", stacklevel=2)
        obs, infos = self.vec.reset(seed)
        self.agents = list(self.possible_agents)
        return self._dicts(obs[0]), self._info_dicts(infos)

    def step(self, actions: dict[str, Any]) -> tuple[dict[str, Any], ...]:
        """One decision of every live agent; returns obs, rewards, terms, truncs, infos."""
        if not self.agents:
            raise RuntimeError("step() on a finished episode (or before reset()): "
                               "call reset()")
        if not isinstance(actions, Mapping):
            raise TypeError(f"actions: must be a dict of agent name -> action (agents: "
                            f"{self.agents}), got {type(actions).__name__}")
        for agent in actions:
            if agent not in self.agents:
                self._index(agent)
                raise ValueError(f"{agent}: has no action to take (finished)")
        batch = np.zeros((1, len(self.possible_agents), ACTION_DIM))
        for agent in self.agents:
            if agent not in actions:
                raise ValueError(f"{agent}: missing action")
            a = np.asarray(actions[agent])
            if a.shape != (ACTION_DIM,):
                raise ValueError(f"{agent}: action shape must be ({ACTION_DIM},), got {a.shape}")
            if not np.issubdtype(a.dtype, np.floating):
                raise ValueError(f"{agent}: action dtype must be floating point, got {a.dtype}")
            batch[0, self._index(agent)] = a
        obs, rew, term, trunc, infos = self.vec.step(batch)
        o = self._dicts(obs[0])
        r = {a: float(rew[0, j]) for j, a in enumerate(self.possible_agents)}
        te = {a: bool(term[0, j]) for j, a in enumerate(self.possible_agents)}
        tr = {a: bool(trunc[0, j]) for j, a in enumerate(self.possible_agents)}
        inf = self._info_dicts(infos)
        if term[0].any() or trunc[0].any():
            self.agents = []
        return o, r, te, tr, inf

    def _dicts(self, obs: np.ndarray) -> dict[str, Any]:
        return {a: obs[j] for j, a in enumerate(self.possible_agents)}

    def _info_dicts(self, infos: dict[str, Any]) -> dict[str, Any]:
        return {a: {"aoi": float(infos["aoi"][0, j]), "frame": int(infos["frame"][0, j]),
                    "error": float(infos["error"][0, j]), "t": float(infos["t"][0])}
                for j, a in enumerate(self.possible_agents)}

    def state(self) -> np.ndarray:
        """The true ``(n, 12)`` published-state columns of every node (for a critic), an
        element of :attr:`state_space` (unbounded float64 ``(n, 12)``)."""
        return self.vec.batch.scenes[0].truth()

    def render(self) -> str | None:
        """``ansi``: the scene's text table (see ``render_mode``); None without a mode."""
        if self.render_mode is None:
            gymnasium.logger.warn("SwarmEnv.render() without a render_mode: pass "
                                  f"render_mode= one of {RENDER_MODES} at construction")
            return None
        out = self.vec.render()
        return None if out is None else out[0]

    def close(self) -> None:
        """Nothing to release."""
