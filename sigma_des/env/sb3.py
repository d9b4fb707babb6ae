"""Stable-Baselines3 adapter: :class:`SwarmSB3VecEnv`, an SB3 ``VecEnv`` over :class:`SwarmVec`.

Needs the ``learn`` extra (``pip install 'sigma-des[learn]'``: Stable-Baselines3,
which pulls PyTorch; install a CPU build of torch first to avoid a CUDA download).

One SB3 sub-environment per (scene, agent), scene-major, as
:class:`~sigma_des.env.SwarmVectorEnv` — parameter sharing over the agents of every
scene. It runs the :class:`~sigma_des.env.SwarmVec` in ``same_step`` autoreset, the
mode SB3 expects: every step is a transition; when a scene's episode ends, ``dones``
is True for its agents, their infos carry the finished episode's last observation
under ``terminal_observation`` and ``TimeLimit.truncated`` = truncated and not
terminated (so PPO bootstraps the value of a time-limit end and not of a collision),
and the returned observation is already the next episode's first. The infos of an
ended step are that step's (``aoi``, ``frame``, ``error``, ``t``,
``episode_index``), not the new episode's.

Why our own adapter rather than SuperSuit's ``pettingzoo_env_to_vec_env_v1`` +
``concat_vec_envs_v1(..., base_class="stable_baselines3")`` over
:class:`~sigma_des.env.SwarmEnv` (which also runs, see ``docs/howto/train-agent.md``): SuperSuit
runs one :class:`SwarmEnv` per scene (no physics batched across scenes), and it
never sets ``TimeLimit.truncated``, so SB3 treats every ``max_steps`` truncation as
a terminal state and learns a biased value there. SuperSuit's wrapper cannot take
a :class:`SwarmVectorEnv` at all (it expects single environments: a shape error).

Example:
    >>> from stable_baselines3 import PPO
    >>> from stable_baselines3.common.vec_env import VecMonitor
    >>> env = VecMonitor(SwarmSB3VecEnv(n_scenes=4, max_steps=100))
    >>> PPO("MlpPolicy", env, seed=0).learn(10_000)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np

from sigma_des.env.tasks import ACTION_DIM, OBS_CLIP
from sigma_des.env.vector import SwarmVec

try:
    from stable_baselines3.common.vec_env import VecEnv
except ModuleNotFoundError as exc:  # pragma: no cover - depends on the install
    raise ModuleNotFoundError(
        "sigma_des.env.sb3 needs stable-baselines3 (the 'learn' extra): "
        "pip install 'sigma-des[learn]'") from exc

__all__ = ["SwarmSB3VecEnv", "train_ppo"]

_INFO_KEYS = ("aoi", "frame", "error", "t", "episode_index")


class SwarmSB3VecEnv(VecEnv):  # type: ignore[misc]
    """SB3 ``VecEnv`` over a same-step :class:`SwarmVec` (see module docstring).

    Args:
        **kwargs: the arguments of :class:`SwarmVec` (``autoreset`` is fixed to
            ``same_step``; passing another value is an error).
    """

    def __init__(self, **kwargs: Any) -> None:
        mode = kwargs.pop("autoreset", "same_step")
        if mode != "same_step":
            raise ValueError(f"autoreset: SB3 needs 'same_step', got {mode!r}")
        self.vec = SwarmVec(autoreset="same_step", **kwargs)
        v = self.vec
        obs_space = gymnasium.spaces.Box(-OBS_CLIP, OBS_CLIP, (v.obs_dim,), dtype=np.float32)
        act_space = gymnasium.spaces.Box(-1.0, 1.0, (ACTION_DIM,), dtype=np.float32)
        self._actions: np.ndarray | None = None
        super().__init__(v.n_scenes * v.n_agents, obs_space, act_space)

    # ------------------------------------------------------------ stepping
    def reset(self) -> np.ndarray:
        """Restart every scene; a seed set by ``seed()`` makes it episode 0 of that seed."""
        seed = self._seeds[0]
        obs, infos = self.vec.reset(seed)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._info_list(infos, None)
        return obs.reshape(self.num_envs, -1)

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the ``(num_envs, 3)`` actions for :meth:`step_wait`."""
        a = np.asarray(actions)
        if a.shape != (self.num_envs, ACTION_DIM):
            raise ValueError(f"actions: shape must be {(self.num_envs, ACTION_DIM)}, "
                             f"got {a.shape}")
        self._actions = a

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        """Step every scene; returns observations, rewards, dones and per-env infos."""
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        v = self.vec
        a, self._actions = self._actions, None
        obs, rew, term, trunc, infos = v.step(a.reshape(v.n_scenes, v.n_agents, ACTION_DIM))
        done = (term | trunc).reshape(-1)
        out = self._info_list(infos, infos.get("final_info"))
        if done.any():
            final = infos["final_obs"].reshape(self.num_envs, -1)
            late = (trunc & ~term).reshape(-1)
            for i in np.flatnonzero(done):
                out[i]["terminal_observation"] = final[i]
                out[i]["TimeLimit.truncated"] = bool(late[i])
        return (obs.reshape(self.num_envs, -1), rew.reshape(-1).astype(np.float32), done, out)

    def _info_list(self, infos: dict[str, Any], final: dict[str, Any] | None
                   ) -> list[dict[str, Any]]:
        """Per-env info dicts (the ended step's values where a scene just restarted)."""
        A = self.vec.n_agents
        mask = infos.get("_final_info")
        rows = []
        for i in range(self.num_envs):
            s, j = divmod(i, A)
            src = final if final is not None and mask is not None and mask[s, j] else infos
            rows.append({k: (src[k][s] if src[k].ndim == 1 else src[k][s, j]).item()
                         for k in _INFO_KEYS})
        return rows

    # ------------------------------------------------------------ VecEnv plumbing
    def close(self) -> None:
        """Nothing to release."""

    def _all(self, indices: Any, what: str) -> None:
        if sorted(self._get_indices(indices)) != list(range(self.num_envs)):
            raise ValueError(f"{what}: the sub-envs share one SwarmVec; "
                             "pass indices=None (all of them)")

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """The attribute of this env (sub-envs share it), once per index."""
        value = getattr(self.vec, attr_name)  # incl. render_mode (SB3 reads it at init)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """Set an attribute of the shared :class:`SwarmVec` (all indices only)."""
        self._all(indices, "set_attr")
        setattr(self.vec, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list[Any]:
        """Call a method of the shared :class:`SwarmVec` once (all indices only)."""
        self._all(indices, "env_method")
        res = getattr(self.vec, method_name)(*method_args, **method_kwargs)
        return [res] * self.num_envs

    def env_is_wrapped(self, wrapper_class: type[gymnasium.Wrapper],
                       indices: Any = None) -> list[bool]:
        """No sub-env is a wrapped Gymnasium env."""
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """No rendering."""
        return [None] * self.num_envs


def train_ppo(env_kwargs: Mapping[str, Any], total_steps: int, seed: int, n_scenes: int = 4,
              log: Callable[[dict[str, float]], None] | None = None, **ppo_kwargs: Any
              ) -> tuple[Callable[[np.ndarray], np.ndarray], list[dict[str, float]]]:
    """Train SB3 PPO (``MlpPolicy``, CPU, one torch thread) on ``n_scenes`` scenes.

    Args:
        env_kwargs: :class:`SwarmVec` arguments (without ``n_scenes``).
        total_steps: agent-steps of training (SB3's ``total_timesteps``).
        seed: PPO's seed (also the env's root seed).
        n_scenes: scenes stepped together.
        log: called with each history row.
        **ppo_kwargs: passed to ``PPO`` (e.g. ``n_steps``, ``batch_size``).

    Returns:
        The deterministic policy (observations ``(S, A, D)`` -> actions ``(S, A, 3)``)
        and the history: per rollout, ``agent_steps`` so far and ``fitness`` = mean
        reward per agent-step of the latest ``num_envs`` finished episodes (NaN if none).
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor

    torch.set_num_threads(1)  # a shared machine: one core per training
    env = VecMonitor(SwarmSB3VecEnv(n_scenes=n_scenes, **dict(env_kwargs)))
    history: list[dict[str, float]] = []

    class _Curve(BaseCallback):  # type: ignore[misc]
        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            eps = list(self.model.ep_info_buffer or [])
            fit = (float(np.mean([e["r"] / e["l"] for e in eps[-env.num_envs:]]))
                   if eps else float("nan"))
            row = {"agent_steps": float(self.num_timesteps), "fitness": fit}
            history.append(row)
            if log is not None:
                log(row)

    model = PPO("MlpPolicy", env, seed=seed, device="cpu", verbose=0, **ppo_kwargs)
    # SB3's default logger makes a /tmp/SB3-<time> folder per training even when it
    # writes nothing; the curve above is the record, so a logger with no outputs.
    model.set_logger(Logger(folder=None, output_formats=[]))
    model.learn(total_timesteps=total_steps, callback=_Curve())

    def policy(obs: np.ndarray) -> np.ndarray:
        flat = obs.reshape(-1, obs.shape[-1])
        a, _ = model.predict(flat, deterministic=True)
        return np.asarray(a, dtype=np.float64).reshape(obs.shape[:-1] + (ACTION_DIM,))

    return policy, history
