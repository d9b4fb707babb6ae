"""A GPU-free learner for the swarm envs: cross-entropy method over a shared linear policy.

Policy (parameter sharing, decentralised execution): every agent maps its own
observation ``o`` (``obs_dim`` columns) to ``a = tanh(W o + b)``; ``theta = [W | b]``
is a ``3 x (obs_dim + 1)`` matrix shared by the agents. CEM keeps a diagonal
Gaussian over ``theta``; each iteration samples ``population`` candidates, scores
each on ``episodes`` episodes and refits the Gaussian to the ``elite`` best.

All candidates of an iteration run at once in one :class:`~sigma_des.env.SwarmVec`
of ``population x episodes`` scenes; candidate ``c``'s ``e``-th episode uses scene
id ``e``, so every candidate meets the same routes and network draws (common random
numbers). Fitness = mean reward per agent-step over ``max_steps`` steps; a scene
that terminates early scores its remaining agent-steps at ``-task.div^2`` (the
clipped worst error cost), so ending an episode never pays.

Sampling uses the counter-based streams of :mod:`sigma_des.core.rng` (no global RNG).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from sigma_des.core.rng import Stream
from sigma_des.env.tasks import ACTION_DIM
from sigma_des.env.vector import SwarmVec
from sigma_des.errors import ConfigError

__all__ = ["CEMConfig", "act", "rollout", "score", "train", "evaluate"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CEMConfig:
    """Cross-entropy method settings.

    Attributes:
        population: candidates per iteration.
        elite: candidates the Gaussian is refitted to.
        iterations: iterations.
        episodes: episodes per candidate and iteration.
        init_std: initial standard deviation of every parameter.
        min_std: floor of the standard deviation (keeps exploring).
        seed: root seed of the sampling stream and the episodes.
    """

    population: int = 16
    elite: int = 4
    iterations: int = 20
    episodes: int = 2
    init_std: float = 0.5
    min_std: float = 0.02
    seed: int = 0

    def __post_init__(self) -> None:
        for key in ("population", "elite", "iterations", "episodes"):
            if getattr(self, key) < 1:
                raise ConfigError(f"cem.{key}", f"must be >= 1, got {getattr(self, key)}")
        if self.elite > self.population:
            raise ConfigError("cem.elite", f"must be <= population ({self.population}), "
                              f"got {self.elite}")


def act(theta: Array, obs: NDArray[np.float32]) -> Array:
    """Actions ``(S, A, 3)`` of per-scene policies ``theta (S, 3, D+1)`` on ``obs (S, A, D)``."""
    o = obs.astype(np.float64)
    return np.tanh(np.einsum("sad,skd->sak", o, theta[:, :, :-1]) + theta[:, None, :, -1])


def rollout(theta: Array, env_kwargs: Mapping[str, Any], episodes: int, seed: int
            ) -> dict[str, Array]:
    """Score ``theta (P, 3, D+1)`` on ``episodes`` common episodes each.

    Returns:
        Per candidate: ``fitness`` (see module docstring), ``error`` (mean true slot
        or goal error over the agent-steps flown, m), ``failed`` (fraction of its
        episodes that terminated).
    """
    P = theta.shape[0]
    owner = np.repeat(np.arange(P), episodes)
    th = theta[owner]
    res = score(lambda obs: act(th, obs), env_kwargs, episodes, seed, copies=P)
    return {k: v.reshape(P, episodes).mean(axis=1) for k, v in res.items()}


def score(policy: Callable[[NDArray[np.float32]], Array], env_kwargs: Mapping[str, Any],
          episodes: int, seed: int, copies: int = 1) -> dict[str, Array]:
    """Per-episode scores of ``policy`` (obs ``(S, A, D)`` -> actions ``(S, A, 3)``).

    Runs ``copies x episodes`` scenes of one :class:`SwarmVec`; scene ``c * episodes +
    e`` plays held-out episode ``e`` (scene id ``e``, root ``seed``), so every copy and
    every policy scored with the same ``seed`` meets the same episodes. A policy with a
    ``reset()`` method (a stateful one, e.g. :class:`sigma_des.env.ppo.Acting`) is reset
    first.

    Returns:
        Per scene: ``fitness``, ``error`` (m) and ``failed`` (0 or 1), see the module
        docstring.
    """
    begin = getattr(policy, "reset", None)
    if callable(begin):  # a stateful policy (frame stack, LSTM): new episodes start here
        begin()
    ids = [e for _ in range(copies) for e in range(episodes)]
    vec = SwarmVec(n_scenes=copies * episodes, scene_ids=ids, **dict(env_kwargs))
    obs, _ = vec.reset(seed=seed)
    S, A, T = vec.n_scenes, vec.n_agents, vec.opts.max_steps
    total = np.zeros(S)
    err_sum = np.zeros(S)
    flown = np.zeros(S)
    alive = np.ones(S, dtype=bool)
    failed = np.zeros(S, dtype=bool)
    worst = -vec.task.div**2
    for _ in range(T):  # finished scenes autoreset and are no longer scored
        obs, r, term, trunc, info = vec.step(np.clip(policy(obs), -1.0, 1.0))
        total[alive] += r[alive].sum(axis=1)
        err_sum[alive] += np.nan_to_num(info["error"][alive]).sum(axis=1)
        flown[alive] += 1
        newly = alive & term[:, 0]
        failed |= newly
        alive &= ~(term[:, 0] | trunc[:, 0])
    total += (T - flown) * A * worst
    return {"fitness": total / (T * A), "error": err_sum / np.maximum(flown * A, 1),
            "failed": failed.astype(np.float64)}


def train(env_kwargs: Mapping[str, Any], cfg: CEMConfig,
          log: Callable[[dict[str, float]], None] | None = None
          ) -> tuple[Array, list[dict[str, float]]]:
    """Train a shared linear policy with CEM; returns the final mean and the history.

    Each history row: ``iteration``, ``mean_fitness`` (population), ``elite_fitness``
    (mean of the elite), ``best_fitness``, ``best_error``.
    """
    probe = SwarmVec(**dict(env_kwargs))
    shape = (ACTION_DIM, probe.obs_dim + 1)
    mean = np.zeros(shape)
    std = np.full(shape, cfg.init_std)
    stream = Stream(cfg.seed, "env.cem")
    k = np.arange(int(np.prod(shape)))
    history: list[dict[str, float]] = []
    for it in range(cfg.iterations):
        p = np.arange(cfg.population)
        z = ndtri(stream.uniform(it, p[:, None], k[None, :])).reshape((cfg.population,) + shape)
        cand = mean[None] + std[None] * z
        cand[0] = mean  # the current mean is always scored
        res = rollout(cand, env_kwargs, cfg.episodes, seed=cfg.seed * 100_003 + it)
        order = np.argsort(-res["fitness"], kind="stable")
        elite = cand[order[: cfg.elite]]
        mean = elite.mean(axis=0)
        std = np.maximum(elite.std(axis=0), cfg.min_std)
        row = {"iteration": float(it), "mean_fitness": float(res["fitness"].mean()),
               "elite_fitness": float(res["fitness"][order[: cfg.elite]].mean()),
               "best_fitness": float(res["fitness"][order[0]]),
               "best_error": float(res["error"][order[0]])}
        history.append(row)
        if log is not None:
            log(row)
    return mean, history


def evaluate(theta: Array, env_kwargs: Mapping[str, Any], episodes: int, seed: int
             ) -> dict[str, float]:
    """Fitness, mean true error (m) and failure rate of one policy over ``episodes``."""
    res = rollout(theta[None], env_kwargs, episodes, seed)
    return {k: float(v[0]) for k, v in res.items()}
