"""Vectorised swarm env: ``n_scenes`` isolated scenes x agents, as batched arrays.

:class:`SwarmVec` is the batched array API: ``reset(seed)`` returns observations
``(n_scenes, n_agents, obs_dim)`` float32 and an info dict of ``(n_scenes,
n_agents)`` arrays; ``step(actions)`` takes ``(n_scenes, n_agents, 3)`` actions in
[-1, 1] and returns observations, rewards ``(S, A)``, terminations and truncations
``(S, A)`` bool and infos. Episode ends are per scene: a collision or a divergence
of any agent terminates the scene's agents; ``max_steps`` (or the end of the
scenario) truncates them. A finished scene restarts by Gymnasium's autoreset modes
(``autoreset=``):

* ``next_step`` (default): the *next* step restarts it, ignores its actions and
  returns the new episode's first observation with zero reward, no termination and
  no truncation (a step that is no transition: learners must skip it, as Gymnasium's
  own wrappers do);
* ``same_step``: the step that ends the episode restarts the scene at once and
  returns the new episode's first observation; the last observation of the finished
  episode is in ``infos["final_obs"]`` and that step's infos in
  ``infos["final_info"]`` (masks ``_final_obs``, ``_final_info``). Every step is a
  transition (what Stable-Baselines3 expects, see :mod:`sigma_des.env.sb3`);
* ``disabled``: stepping a finished scene raises ``RuntimeError``.

Both restarting modes play the same episodes for the same actions.

:class:`SwarmVectorEnv` adapts it to Gymnasium's :class:`~gymnasium.vector.VectorEnv`,
one sub-environment per (scene, agent), scene-major: ``num_envs = S * A``.

Infos: ``aoi`` (s, age of the agent's own shown state; NaN before any), ``frame``,
``error`` (true error, m; NaN on a non-transition), ``t``, ``episode_index``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import SwarmView
from sigma_des.env.options import EnvOptions, build_scenario
from sigma_des.env.resets import (
    RENDER_MODES,
    check_render_mode,
    check_seed,
    parse_reset,
    per_scene,
    render_ansi,
)
from sigma_des.env.scenes import Scene, SceneBatch
from sigma_des.env.shown import Shown, truths
from sigma_des.env.tasks import ACTION_DIM, OBS_CLIP, make_task
from sigma_des.errors import ConfigError
from sigma_des.factory import make_dynamics

__all__ = ["SwarmVec", "SwarmVectorEnv", "check_actions", "check_mapping", "check_seed"]

Array = NDArray[np.float64]


def check_mapping(value: Any, name: str, example: str) -> Mapping[str, Any]:
    """``value`` (None: empty) if it is a mapping, else a TypeError naming ``name``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"{name}: must be a dict of keys to values (e.g. {example}), got "
                        f"{type(value).__name__} {value!r}")
    return value


def check_actions(actions: Any, shape: tuple[int, ...], names: list[str]) -> Array:
    """``actions`` as float64 if valid, else a ValueError naming the agent and field.

    Args:
        actions: the batch of actions, shape ``shape`` ending in ``ACTION_DIM``.
        shape: the required shape.
        names: one name per row of the flattened leading axes (for messages).
    """
    a = np.asarray(actions)
    if a.shape != shape:
        raise ValueError(f"actions: shape must be {shape}, got {a.shape}")
    if not np.issubdtype(a.dtype, np.floating):
        raise ValueError(f"actions: dtype must be floating point, got {a.dtype}")
    flat = a.reshape(-1, ACTION_DIM).astype(np.float64)
    if (np.abs(flat) <= 1.0).all():  # (False for a NaN): the valid batch in one test
        return flat.reshape(shape)
    bad = ~np.isfinite(flat)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ValueError(f"{names[r]}: action[{c}] is {flat[r, c]} (must be finite)")
    out = np.abs(flat) > 1.0
    if out.any():
        r, c = np.argwhere(out)[0]
        raise ValueError(f"{names[r]}: action[{c}] = {flat[r, c]} outside the action "
                         "space [-1, 1]")
    return flat.reshape(shape)


class SwarmVec:
    """Batched array API over ``n_scenes`` scenes (see module docstring).

    Args:
        task: ``formation`` or ``goal``.
        method: alignment method.
        n_scenes: number of isolated scenes.
        scenario: scenario overrides (dotted keys -> values), see ``options``.
        task_params: task parameters (fields of the task class).
        max_steps: decisions per episode.
        perfect_info: observe the true state instead of the aligned view.
        seed: root seed (overrides ``scenario['seed']`` if given).
        autoreset: ``next_step``, ``same_step`` or ``disabled`` (module docstring).
        scene_ids: identity of each scene in its seed (default ``0..n_scenes-1``):
            scenes sharing an id replay the same episodes (common random numbers).
        batched: the control plane (commands, observations, rewards) as numpy over all
            scenes at once (the task's ``*_many`` methods); False: scene by scene (the
            reference; both give the same bits).
        render_mode: None or ``"ansi"`` (:meth:`render` gives one text table per scene).
        metrics: the scenes' runs collect the simulator's measurements (AoI and latency
            samples, render ticks, the fidelity log), which the env never returns;
            False skips them (faster; the same observations, rewards and infos).

    Raises:
        ConfigError: (a ValueError) an unknown task, key or out-of-range option.
    """

    def __init__(self, task: str = "formation", method: str = "bides", n_scenes: int = 1,
                 scenario: Mapping[str, Any] | None = None,
                 task_params: Mapping[str, Any] | None = None, max_steps: int = 100,
                 perfect_info: bool = False, seed: int | None = None,
                 autoreset: str = "next_step", scene_ids: list[int] | None = None,
                 batched: bool = True, render_mode: str | None = None,
                 metrics: bool = True) -> None:
        self.render_mode = check_render_mode(render_mode)
        scenario = check_mapping(scenario, "scenario", "{'nodes': 8}")
        task_params = check_mapping(task_params, "task_params", "{'w_u': 0.1}")
        seed = check_seed(seed)
        self.opts = EnvOptions(task, method, max_steps, perfect_info, n_scenes, autoreset)
        self.task = make_task(task, dict(task_params))
        self.sc = build_scenario(self.opts, scenario)
        self.dyn = make_dynamics(self.sc)
        self.agent_nodes = self.task.agents(self.sc.nodes)
        if not self.agent_nodes:
            raise ValueError(f"nodes: the {task} task needs at least 2 nodes")
        self.n_scenes = n_scenes
        self.n_agents = len(self.agent_nodes)
        self.obs_dim = self.task.obs_dim
        if not isinstance(metrics, bool):
            raise ConfigError("metrics", f"must be true or false, got {metrics!r}")
        self.batch = SceneBatch(self.sc, method, self.dyn, self.task, n_scenes, scene_ids,
                                metrics)
        self._seed = self.sc.seed if seed is None else int(seed)
        self.steps = np.zeros(n_scenes, dtype=np.int64)
        self.done = np.ones(n_scenes, dtype=bool)
        self._started = False
        self.batched = bool(batched)
        self._last_error = np.full((n_scenes, self.n_agents), np.nan)
        self._names = [f"scene {s} node_{i}" for s in range(n_scenes) for i in self.agent_nodes]
        self._agents = np.array(self.agent_nodes, dtype=np.intp)
        #: the views the last step gathered (reused while their scenes wait at that tick)
        self._shown: Shown | None = None

    # ------------------------------------------------------------ API
    def reset(self, seed: Any = None, options: Mapping[str, Any] | None = None
              ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Restart the scenes (all, or those of ``options["reset_mask"]``).

        ``seed``: None (each scene's next episode; the first reset: the construction
        seed), an int (episode 0 of that root seed) or one such entry per scene; see
        :mod:`sigma_des.env.resets`. Scenes outside the mask keep their episode and
        observation (their infos' ``error`` is NaN, as at any reset).

        Raises:
            TypeError, ValueError: a bad seed, option or mask, named.
        """
        roots, mask = parse_reset(seed, options, self.n_scenes)
        if not self._started:
            if mask is not None and not mask.all():
                raise ValueError("options['reset_mask']: the first reset must reset every "
                                 "scene")
            roots = [self._seed if r is None else r for r in roots]
        ids = np.arange(self.n_scenes) if mask is None else np.flatnonzero(mask)
        self.batch.reset(roots, ids.tolist())
        self._started = True
        self.steps[ids] = 0
        self.done[ids] = False
        self._last_error[ids] = np.nan
        return self._observe_all(), self._infos(None)

    def state(self) -> Array:
        """The true ``(n_scenes, nodes, 12)`` published states (:data:`state_space`'s
        batch; a centralised critic's input)."""
        return np.stack([sc.truth() for sc in self.batch.scenes])

    @property
    def state_space(self) -> gymnasium.spaces.Box:
        """One scene's state space: unbounded float64 ``(nodes, 12)``."""
        return gymnasium.spaces.Box(-np.inf, np.inf, (self.sc.nodes, 12), dtype=np.float64)

    def render(self) -> list[str] | None:
        """``ansi``: one text table per scene (true state, ages, errors); else None."""
        if self.render_mode is None:
            return None
        info = self._infos(None)
        return [render_ansi(sc.truth(), sc.now(), self.agent_nodes, info["aoi"][s],
                            self._last_error[s], f"scene {s} episode {self.batch.episode[s]}")
                for s, sc in enumerate(self.batch.scenes)]

    def step(self, actions: Any) -> tuple[NDArray[np.float32], Array, NDArray[np.bool_],
                                          NDArray[np.bool_], dict[str, Any]]:
        """One decision of every scene's agents (see module docstring)."""
        if not self._started:
            raise RuntimeError("step() before reset(): call reset() first")
        a = check_actions(actions, (self.n_scenes, self.n_agents, ACTION_DIM), self._names)
        if self.done.any() and self.opts.autoreset == "disabled":
            s = int(np.flatnonzero(self.done)[0])
            raise RuntimeError(f"scene {s}: the episode is finished; call reset()")
        scenes = self.batch.scenes
        restart = np.flatnonzero(self.done)  # next-step mode only: finished last step
        live = np.flatnonzero(~self.done).tolist()
        # a scene that ended before anything was shown sends nothing: truncated below
        self._publish([s for s in live if not scenes[s].ended], a)
        self._restart(restart.tolist(), advance=False)
        self.batch.advance(scenes)
        rew, term, trunc, err = self._score(live, a)
        self.steps[live] += 1
        self.done[:] = term[:, 0] | trunc[:, 0]
        if self.opts.autoreset != "same_step" or not self.done.any():
            return self._observe_all(), rew, term, trunc, self._infos(err)
        ended = np.flatnonzero(self.done)
        final_obs = self._observe_all()
        final_info = self._infos(err.copy())
        self._restart(ended.tolist(), advance=True)
        err[ended] = np.nan
        obs = self._observe_all()
        infos = self._infos(err)
        mask = np.zeros((self.n_scenes, self.n_agents), dtype=bool)
        mask[ended] = True
        final_obs[~mask] = 0.0
        infos.update(final_obs=final_obs, _final_obs=mask, final_info=final_info,
                     _final_info=mask.copy())
        return obs, rew, term, trunc, infos

    def _restart(self, ended: list[int], advance: bool) -> None:
        """Start the next episode of scenes ``ended`` (run to their first tick if ``advance``)."""
        if not ended:
            return
        self.batch.restart(ended, advance)
        self.steps[ended] = 0
        self.done[ended] = False

    def _score(self, live: list[int], a: Array
               ) -> tuple[Array, NDArray[np.bool_], NDArray[np.bool_], Array]:
        """Rewards, terminations, truncations and true errors of the ``live`` scenes."""
        S, A = self.n_scenes, self.n_agents
        rew = np.zeros((S, A))
        term = np.zeros((S, A), dtype=bool)
        trunc = np.zeros((S, A), dtype=bool)
        err = np.full((S, A), np.nan)
        scenes = self.batch.scenes
        if self.batched and live:
            picked = [scenes[s] for s in live]
            idx = np.array(live, dtype=np.intp)  # (one conversion for every index below)
            r, fail, e = self.task.reward_many(
                truths(picked, self.dyn), [sc.ep for sc in picked],
                np.array([sc.run.kernel.now for sc in picked]), self.agent_nodes, a[idx])
            rew[idx], err[idx] = r, e
            failed: NDArray[np.bool_] = fail.any(axis=1)  # type: ignore[assignment]
            term[idx] = failed[:, None]
            ended = np.array([sc.ended for sc in picked], dtype=bool)
            trunc[idx] = (~failed & ((self.steps[idx] + 1 >= self.opts.max_steps)
                                     | ended))[:, None]
            return rew, term, trunc, err
        for s in live:
            sc = scenes[s]
            r, fail, e = self.task.reward(sc.truth(), sc.ep, sc.now(), self.agent_nodes, a[s])
            rew[s], err[s] = r, e
            term[s] = bool(fail.any())
            trunc[s] = not term[s, 0] and (self.steps[s] + 1 >= self.opts.max_steps or sc.ended)
        return rew, term, trunc, err

    def _publish(self, ids: list[int], a: Array) -> None:
        """The agents' (and scripted nodes') commands of scenes ``ids``, sent."""
        scenes = self.batch.scenes
        if not self.batched:
            for s in ids:
                sc = scenes[s]
                nodes, cmds = self.task.commands(a[s], self._view(sc), sc.ep, sc.now(),
                                                 self.agent_nodes, self.dyn)
                sc.publish(nodes, cmds)
            return
        if not ids:
            return
        sh = self._views(ids)
        send, cmds = self.task.commands_many(a[ids], sh.obs, sh.valid, sh.eps, sh.t,
                                             self.agent_nodes, self.dyn)
        # every scene's sent nodes from one nonzero (row-major: scene by scene, in order)
        nodes = np.nonzero(send)[1].astype(np.int64, copy=False)
        ends = np.cumsum(send.sum(axis=1)).tolist()
        start = 0
        for k, s in enumerate(ids):
            scenes[s].publish(nodes[start:ends[k]], cmds[k])
            start = ends[k]

    def _observe_all(self) -> NDArray[np.float32]:
        """``(S, A, obs_dim)`` observations of every scene (zeros for an ended one)."""
        scenes = self.batch.scenes
        if not self.batched:
            return np.stack([self._observe(sc) for sc in scenes])
        out = np.zeros((self.n_scenes, self.n_agents, self.obs_dim), dtype=np.float32)
        ids = [s for s, sc in enumerate(scenes) if not sc.ended]
        if not ids:
            return out
        sh = self._views(ids)
        age = (np.zeros((len(ids), self.sc.nodes)) if self.opts.perfect_info
               else sh.t[:, None] - sh.gen)
        got = self.task.observe_many(sh.obs, sh.valid, sh.eps, sh.t, self.agent_nodes, age)
        if len(ids) == self.n_scenes:  # every scene: the new array itself
            return np.ascontiguousarray(got, dtype=np.float32)
        out[ids] = got
        return out

    # ------------------------------------------------------------ helpers
    def _views(self, ids: list[int]) -> Shown:
        """The views of scenes ``ids`` (each waiting at a command tick): those gathered
        last if every one is still at the tick gathered, else gathered now."""
        scenes = self.batch.scenes
        got = None if self._shown is None else self._shown.of(scenes, ids)
        if got is None:
            got = self._shown = Shown.gather(scenes, ids, self.dyn, self.opts.perfect_info)
        return got

    def _view(self, sc: Scene) -> SwarmView:
        if not self.opts.perfect_info:
            return sc.view
        run = sc.run
        n = self.sc.nodes
        k = run.latest_trigger
        return SwarmView(obs=sc.truth(), frame=np.full(n, k, dtype=np.int64),
                         valid=np.ones(n, dtype=bool), aligned_frame=k)

    def _observe(self, sc: Scene) -> NDArray[np.float32]:
        if sc.ended:
            return np.zeros((self.n_agents, self.obs_dim), dtype=np.float32)
        n = self.sc.nodes
        age = np.zeros(n) if self.opts.perfect_info else sc.now() - sc.run.aligner.shown_gen
        return self.task.observe(self._view(sc), sc.ep, sc.now(), self.agent_nodes, age)

    def _infos(self, err: Array | None) -> dict[str, Any]:
        S, A = self.n_scenes, self.n_agents
        if err is not None:
            self._last_error = err.copy()  # the last call of a step is what it returns
        scenes = self.batch.scenes
        t = np.array([sc.run.kernel.now for sc in scenes], dtype=np.float64)
        ids = [s for s, sc in enumerate(scenes) if sc.capture.view is not None]
        sh = None if self._shown is None or not ids else self._shown.of(scenes, ids)
        if sh is not None and len(ids) == S:  # the views just observed, of every scene
            aoi = sh.t[:, None] - sh.gen[:, self._agents]
            frame = sh.frame[:, self._agents].astype(np.int64, copy=False)
            return self._info_dict(aoi, frame, t, err)
        aoi = np.full((S, A), np.nan)
        frame = np.full((S, A), -1, dtype=np.int64)
        if sh is not None:  # the views just observed: the same reads, gathered
            aoi[ids] = sh.t[:, None] - sh.gen[:, self._agents]
            frame[ids] = sh.frame[:, self._agents]
        else:
            for s in ids:
                sc = scenes[s]
                aoi[s] = t[s] - sc.run.aligner.shown_gen[self.agent_nodes]
                frame[s] = sc.view.frame[self.agent_nodes]
        return self._info_dict(aoi, frame, t, err)

    def _info_dict(self, aoi: Array, frame: NDArray[np.int64], t: Array,
                   err: Array | None) -> dict[str, Any]:
        return {"aoi": aoi, "frame": frame, "t": t,
                "error": err if err is not None else np.full((self.n_scenes, self.n_agents),
                                                             np.nan),
                "episode_index": np.array(self.batch.episode, dtype=np.int64)}


_MODES = {"next_step": gymnasium.vector.AutoresetMode.NEXT_STEP,
          "same_step": gymnasium.vector.AutoresetMode.SAME_STEP,
          "disabled": gymnasium.vector.AutoresetMode.DISABLED}


class SwarmVectorEnv(gymnasium.vector.VectorEnv):  # type: ignore[misc]
    """Gymnasium vector adapter: one sub-env per (scene, agent), scene-major.

    ``metadata["autoreset_mode"]`` is the :class:`SwarmVec`'s ``autoreset`` (default
    next-step), so Gymnasium's vector wrappers (e.g. ``RecordEpisodeStatistics``)
    count every transition once. Per-scene infos are repeated for its agents.
    ``reset`` takes Gymnasium's ``seed`` list and ``options["reset_mask"]`` in their
    ``(num_envs,)`` forms (the agents of a scene must agree) or one entry per scene.

    Args:
        **kwargs: the arguments of :class:`SwarmVec` (incl. ``render_mode``).
    """

    metadata = {"autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP,
                "render_modes": RENDER_MODES}

    def __init__(self, **kwargs: Any) -> None:
        self.vec = SwarmVec(**kwargs)
        v = self.vec
        self.metadata = {"autoreset_mode": _MODES[v.opts.autoreset],
                         "render_modes": RENDER_MODES}
        self.render_mode = v.render_mode
        self.num_envs = v.n_scenes * v.n_agents
        self.single_observation_space = gymnasium.spaces.Box(
            -OBS_CLIP, OBS_CLIP, (v.obs_dim,), dtype=np.float32)
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (ACTION_DIM,),
                                                        dtype=np.float32)
        self.observation_space = gymnasium.vector.utils.batch_space(
            self.single_observation_space, self.num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(
            self.single_action_space, self.num_envs)

    def _flat_infos(self, infos: dict[str, Any]) -> dict[str, Any]:
        A, n = self.vec.n_agents, self.num_envs
        return {k: (self._flat_infos(v) if isinstance(v, dict)
                    else np.repeat(v, A) if v.ndim == 1 else v.reshape((n,) + v.shape[2:]))
                for k, v in infos.items()}

    def reset(self, *, seed: Any = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset the scenes (all, or those of ``options["reset_mask"]``), see the class."""
        v = self.vec
        seed = per_scene(seed, v.n_scenes, v.n_agents, "seed")
        opts = dict(options or {})
        if "reset_mask" in opts:
            opts["reset_mask"] = per_scene(opts["reset_mask"], v.n_scenes, v.n_agents,
                                           "options['reset_mask']")
        obs, infos = v.reset(seed, opts)
        return obs.reshape(self.num_envs, -1), self._flat_infos(infos)

    def render(self) -> tuple[str, ...] | None:
        """``ansi``: one text table per scene (see :meth:`SwarmVec.render`); else None."""
        out = self.vec.render()
        return None if out is None else tuple(out)

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        """Step with ``(num_envs, 3)`` actions."""
        v = self.vec
        a = np.asarray(actions)
        if a.shape != (self.num_envs, ACTION_DIM):
            raise ValueError(f"actions: shape must be {(self.num_envs, ACTION_DIM)}, "
                             f"got {a.shape}")
        obs, r, te, tr, infos = v.step(a.reshape(v.n_scenes, v.n_agents, ACTION_DIM))
        return (obs.reshape(self.num_envs, -1), r.reshape(-1), te.reshape(-1), tr.reshape(-1),
                self._flat_infos(infos))
