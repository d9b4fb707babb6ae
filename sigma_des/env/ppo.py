"""PPO recipes for the swarm envs (the ``learn`` extra): MLP, frame-stacked MLP, LSTM.

:func:`train` runs Stable-Baselines3 PPO (``policy="mlp"`` or ``"stack"``) or
sb3-contrib's RecurrentPPO (``policy="lstm"``, :data:`LSTM_HIDDEN` units) over a same-step
:class:`~sigma_des.env.sb3.SwarmSB3VecEnv` (parameter sharing: one sub-env per scene
and agent), with observation (and reward) normalisation (``VecNormalize``); the
``stack`` policy sees the last ``n_stack`` normalised observations (``VecFrameStack``).
Learning curve: after every rollout, the mean reward per agent-step of the episodes
that finished in it (``VecMonitor``), against agent-steps so far.

A training is resumable: with ``checkpoint`` (a path prefix), the model, the
normaliser's statistics and the curve are saved every ``save_every`` agent-steps and
at the end, and a later call with the same prefix goes on from the last save (the
continued run is not bit-identical to an uninterrupted one: the env restarts its
episodes).

:class:`Acting` is the trained policy as a deterministic function of the env's
batched observations ``(S, A, D)`` (normalised, stacked or with its LSTM state as in
training); call :meth:`Acting.reset` at the start of every batch of episodes.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.env.sb3 import SwarmSB3VecEnv
from sigma_des.env.tasks import ACTION_DIM

__all__ = ["LSTM_HIDDEN", "POLICIES", "PPO_DEFAULTS", "Acting", "train"]

POLICIES = ("mlp", "stack", "lstm")

#: PPO settings of :func:`train` unless overridden (short horizons, small action noise).
PPO_DEFAULTS: dict[str, Any] = {"n_steps": 64, "batch_size": 1024, "n_epochs": 10,
                                "learning_rate": 3e-4, "gamma": 0.95, "gae_lambda": 0.9,
                                "clip_range": 0.2, "ent_coef": 0.0}
#: hidden units of the ``lstm`` policy's recurrent layer (sb3-contrib's default, 256,
#: trains ~3x slower per agent-step on these small observations)
LSTM_HIDDEN = 64


class _Stop(Exception):
    """Raised between rollouts when the wall-time budget is spent."""


class Acting:
    """A trained policy on batched observations ``(S, A, D)`` -> actions ``(S, A, 3)``."""

    def __init__(self, model: Any, norm: Any, policy: str, n_stack: int) -> None:
        self.model, self.norm, self.policy, self.n_stack = model, norm, policy, n_stack
        self._stack: np.ndarray | None = None
        self._state: Any = None
        self._start: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the frames / LSTM state: the next call starts new episodes."""
        self._stack, self._state, self._start = None, None, None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        flat = obs.reshape(-1, obs.shape[-1]).astype(np.float32)
        x = self.norm.normalize_obs(flat) if self.norm is not None else flat
        if self.policy == "stack":
            d = x.shape[1]
            if self._stack is None:
                self._stack = np.zeros((x.shape[0], d * self.n_stack), dtype=np.float32)
            self._stack = np.roll(self._stack, -d, axis=1)
            self._stack[:, -d:] = x
            x = self._stack
        if self.policy == "lstm":
            if self._start is None:
                self._start = np.ones(x.shape[0], dtype=bool)
            a, self._state = self.model.predict(x, state=self._state,
                                                episode_start=self._start,
                                                deterministic=True)
            self._start = np.zeros(x.shape[0], dtype=bool)
        else:
            a, _ = self.model.predict(x, deterministic=True)
        return np.asarray(a, dtype=np.float64).reshape(obs.shape[:-1] + (ACTION_DIM,))


def _wrap(env_kwargs: Mapping[str, Any], n_scenes: int, seed: int, policy: str,
          n_stack: int, norm_path: Path | None, gamma: float) -> Any:
    from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor, VecNormalize

    env: Any = VecMonitor(SwarmSB3VecEnv(n_scenes=n_scenes, seed=seed, **dict(env_kwargs)))
    if norm_path is not None and norm_path.exists():
        env = VecNormalize.load(str(norm_path), env)
        env.training = True
    else:
        env = VecNormalize(env, norm_obs=True, norm_reward=True, clip_obs=10.0, gamma=gamma)
    if policy == "stack":
        env = VecFrameStack(env, n_stack=n_stack)
    return env


def _norm_of(env: Any) -> Any:
    from stable_baselines3.common.vec_env import VecNormalize

    while not isinstance(env, VecNormalize):
        env = env.venv
    return env


class _Saves:
    """The files of a checkpoint prefix (None: no saves)."""

    def __init__(self, prefix: str | Path | None) -> None:
        self.prefix = Path(prefix) if prefix is not None else None
        self.zip = self.prefix.with_suffix(".zip") if self.prefix else None
        self.norm = self.prefix.with_suffix(".norm.pkl") if self.prefix else None
        self.curve = self.prefix.with_suffix(".curve.json") if self.prefix else None

    def curve_rows(self) -> list[dict[str, float]]:
        """The saved learning curve (empty if none)."""
        if self.curve is None or not self.curve.exists():
            return []
        return list(json.loads(self.curve.read_text()))

    def save(self, model: Any, env: Any, history: list[dict[str, float]]) -> None:
        """Save the model, the normaliser and the curve (nothing without a prefix)."""
        if self.prefix is None or self.zip is None or self.norm is None or self.curve is None:
            return
        self.prefix.parent.mkdir(parents=True, exist_ok=True)
        model.save(str(self.zip))
        _norm_of(env).save(str(self.norm))
        self.curve.write_text(json.dumps(history) + "\n")


def _curve(save: Callable[[], None], history: list[dict[str, float]],
           log: Callable[[dict[str, float]], None] | None, save_every: int,
           max_wall_s: float | None, start_steps: int) -> Any:
    """The callback that appends a curve row per rollout, saves and keeps the budget."""
    from stable_baselines3.common.callbacks import BaseCallback

    wall0 = history[-1]["wall_s"] if history else 0.0
    t0 = time.perf_counter()

    class _Curve(BaseCallback):  # type: ignore[misc]
        last_save = start_steps
        finished: list[float] = []
        stop = False

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    self.finished.append(info["episode"]["r"] / info["episode"]["l"])
            return True

        def _on_rollout_end(self) -> None:
            done, self.finished[:] = list(self.finished), []
            row = {"agent_steps": float(self.num_timesteps),
                   "fitness": float(np.mean(done)) if done else float("nan"),
                   "episodes": float(len(done)), "wall_s": wall0 + time.perf_counter() - t0}
            history.append(row)
            if log is not None:
                log(row)
            if self.num_timesteps - self.last_save >= save_every:
                self.last_save = self.num_timesteps
                save()
            if max_wall_s is not None and time.perf_counter() - t0 >= max_wall_s:
                self.stop = True

        def _on_rollout_start(self) -> None:
            if self.stop:
                raise _Stop

    return _Curve()


def train(env_kwargs: Mapping[str, Any], total_steps: int, seed: int, policy: str = "mlp",
          n_scenes: int = 16, n_stack: int = 4, checkpoint: str | Path | None = None,
          save_every: int = 200_000, log: Callable[[dict[str, float]], None] | None = None,
          max_wall_s: float | None = None, **ppo_kwargs: Any
          ) -> tuple[Acting, list[dict[str, float]]]:
    """Train one policy to ``total_steps`` agent-steps (see module docstring).

    Args:
        env_kwargs: :class:`~sigma_des.env.SwarmVec` arguments (without ``n_scenes``).
        total_steps: agent-steps of training in all (incl. a resumed run's).
        seed: PPO's and the env's root seed.
        policy: ``mlp``, ``stack`` (``n_stack`` frames) or ``lstm`` (RecurrentPPO).
        n_scenes: scenes stepped together (``n_scenes x agents`` sub-envs).
        checkpoint: path prefix of the saves (None: no saves, no resume).
        save_every: agent-steps between saves.
        log: called with each curve row.
        max_wall_s: stop at the first rollout's end after this many seconds of this
            call (then save; a later call resumes); 0: only load the saved policy.
        **ppo_kwargs: override :data:`PPO_DEFAULTS` (and ``policy_kwargs``).

    Returns:
        The deterministic policy and the curve: rows ``agent_steps``, ``fitness`` (mean
        reward per agent-step of the episodes finished in the rollout; NaN if none),
        ``episodes``, ``wall_s`` (since this call started, plus a resumed run's).
    """
    if policy not in POLICIES:
        raise ValueError(f"policy: must be one of {POLICIES}, got {policy!r}")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    torch.set_num_threads(1)  # a shared machine: one core per training
    kw = {**PPO_DEFAULTS, **ppo_kwargs}
    kw.setdefault("policy_kwargs", {"log_std_init": -1.0, "net_arch": [64, 64]})
    if policy == "lstm":  # the caller's policy_kwargs win
        kw["policy_kwargs"] = {"lstm_hidden_size": LSTM_HIDDEN, **kw["policy_kwargs"]}
    saves = _Saves(checkpoint)
    env = _wrap(env_kwargs, n_scenes, seed, policy, n_stack, saves.norm, kw["gamma"])
    Algo: type[OnPolicyAlgorithm] = PPO
    name = "MlpPolicy"
    if policy == "lstm":
        from sb3_contrib import RecurrentPPO

        Algo, name = RecurrentPPO, "MlpLstmPolicy"
    history: list[dict[str, float]] = []
    if saves.zip is not None and saves.zip.exists():
        model = Algo.load(str(saves.zip), env=env, device="cpu")
        history = saves.curve_rows()
    else:
        model = Algo(name, env, seed=seed, device="cpu", verbose=0, **kw)
    # SB3's default logger makes a /tmp/SB3-<time> folder per training even when it
    # writes nothing; the curve is the record, so a logger with no outputs.
    model.set_logger(Logger(folder=None, output_formats=[]))
    remaining = total_steps - model.num_timesteps
    if remaining > 0 and (max_wall_s is None or max_wall_s > 0):
        cb = _curve(lambda: saves.save(model, env, history), history, log, save_every,
                    max_wall_s, model.num_timesteps)
        try:
            model.learn(total_timesteps=remaining, callback=cb, reset_num_timesteps=False)
        except _Stop:
            pass
        saves.save(model, env, history)
    norm = _norm_of(env)
    norm.training = False
    return Acting(model, norm, policy, n_stack), history
