"""Isolated scenes over the distributed loop, with physics batched across scenes.

A :class:`Scene` is one run of the simulator (:class:`~sigma_des.events.engine.MethodRun`
or the cohort engine, picked as in ``sigma-des compare``) whose behaviour only
*captures* the aligned view at each command tick: the run pauses there, the
learner decides, and the decisions are published as commands at the same
simulated time — exactly what a behaviour returning them would have done (see
``MethodRun.advance_until``). Each scene has its own kernel, broker, links,
aligner, collector and random streams; its scenario seed is a counter-based
function of ``(root seed, scene index, episode)``, so a scene's episodes never
depend on how many scenes run beside it.

:class:`SceneBatch` drives many scenes: every scene is advanced to its next
trigger issue (all messages before it processed, so its command rows are final),
then the physics of every waiting scene is stepped in one call of the dynamics
model per distinct ``(frame, dt)`` (per ``dt`` for a model whose step reads neither
frame nor node ids, ``frame_free``; rows are independent, so this is bit-identical
to each scene stepping alone), and the scenes go on, until each has paused at its
next command tick or reached the end of its scenario. A restarted scene's compiled core
refills the arrays of the scene it replaces (the same state as new arrays).
"""

from __future__ import annotations

import gc
from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from sigma_des.config import Scenario
from sigma_des.core.models import DynamicsModel, SwarmView
from sigma_des.core.rng import mix_int
from sigma_des.env.tasks import Task
from sigma_des.events.cohort import make_run
from sigma_des.events.engine import END, PAUSED, TRIGGER_DUE, MethodRun
from sigma_des.events.fast.control_run import CompiledControl, unsupported
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.growth import trims_batched
from sigma_des.events.fast.spare import Spare
from sigma_des.events.spec import RunSpec

__all__ = ["Scene", "SceneBatch", "scene_seed", "with_seed"]

Array = NDArray[np.float64]
_SEED_KEY = np.uint64(0x5CE7E5EED0000001)


_MASK63 = 2**63 - 1


def _root_ids(root: int) -> list[int]:
    """``root`` as hash ids: itself below 2^63; above, a marker, its number of 32-bit
    limbs and the limbs (Gymnasium takes any non-negative int: 2^63 must not be 0)."""
    if root <= _MASK63:
        return [root]
    limbs = [(root >> (32 * i)) & 0xFFFFFFFF for i in range((root.bit_length() + 31) // 32)]
    return [-1, len(limbs), *limbs]


def scene_seed(root: int, scene: int, episode: int) -> int:
    """The scenario seed of ``episode`` of ``scene`` under ``root`` (63-bit).

    ``root`` is any non-negative int; every bit of it counts.
    """
    return mix_int(_SEED_KEY, *_root_ids(int(root)), scene, episode) >> 1


def with_seed(spec: RunSpec, seed: int) -> RunSpec:
    """``spec`` with root seed ``seed``: ``Scenario.run_spec`` of the scenario with that
    seed (the seed is in the spec and its aligner's parameters, nowhere else), without
    validating and converting the whole scenario again for every episode.

    ``dataclasses.replace`` of both, without running their validation again (neither
    checks the seed, and every other field is the valid ``spec``'s own object).
    """
    return _reseeded(spec, seed, align=_reseeded(spec.align, seed))


_T = TypeVar("_T")


def _reseeded(obj: _T, seed: int, **more: Any) -> _T:
    """A copy of the frozen dataclass ``obj`` with field ``seed`` (and ``more``) replaced:
    its fields' objects shared, as ``replace`` shares them, ``__init__`` not run."""
    new = object.__new__(type(obj))
    fields = new.__dict__
    fields.update(obj.__dict__)
    fields["seed"] = seed
    fields.update(more)
    return new


class _Capture:
    """A behaviour that records the view of each command tick and sends nothing."""

    name = "env"

    def __init__(self) -> None:
        self.view: SwarmView | None = None

    def capture(self, view: SwarmView) -> None:
        """Record ``view`` (what the compiled control loop calls instead of
        :meth:`commands`: no rows to send)."""
        self.view = view

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> Array:
        self.view = view
        return np.full((view.obs.shape[0], dynamics.command_dim), np.nan)


class _Placed:
    """The shared dynamics model with the task's fixed initial state."""

    def __init__(self, dyn: DynamicsModel, initial: Array) -> None:
        self._dyn = dyn
        self._initial = initial
        self.name = dyn.name
        self.state_dim = dyn.state_dim
        self.command_dim = dyn.command_dim
        for hot in ("step", "observe", "step_frames", "default_command", "observe_into",
                    "step_into", "resimulate_into", "compiled_physics"):  # no lookup each
            if hasattr(dyn, hot):
                setattr(self, hot, getattr(dyn, hot))

    def initial_state(self, n: int) -> Array:
        return self._initial.copy()

    def __getattr__(self, item: str) -> Any:
        return getattr(self._dyn, item)


def placed(dyn: DynamicsModel, task: Task, nodes: int) -> tuple[_Placed, Array]:
    """The shared model with the task's initial state, and that state's observation.

    Neither depends on the episode's seed (a task's initial state is fixed, a model is
    pure), so a :class:`SceneBatch` makes them once for all its scenes and episodes.
    Both arrays are made read-only: a run gets a copy of the initial state
    (``initial_state``), a task's ``episode`` reads the observation, and any write to
    either would raise instead of leaking into the next episode.
    """
    initial = task.initial_state(dyn, nodes)
    obs = dyn.observe(initial)
    initial.setflags(write=False)
    obs.setflags(write=False)
    return _Placed(dyn, initial), obs


class Scene:
    """One isolated episode of the distributed loop (see module docstring).

    Args:
        spec: the run spec of this episode (its seed already derived: :func:`with_seed`).
        method: alignment method.
        dyn: the dynamics model (shared by all scenes: models are pure).
        task: the task.
        metrics: collect the run's measurements (False: none, see ``MethodRun``).
        start: :func:`placed` of ``(dyn, task, spec.nodes)`` if the caller keeps it
            (None: made here).
        control: run the control events in the compiled loop where it covers them.
        spare: what a retired scene's compiled core handed back (:func:`_retire`), for
            this scene's core to refill instead of making new arrays (the same episode).
    """

    def __init__(self, spec: RunSpec, method: str, dyn: DynamicsModel, task: Task,
                 metrics: bool = True, start: tuple[_Placed, Array] | None = None,
                 control: bool = True, spare: Spare | None = None) -> None:
        self.capture = _Capture()
        model, obs0 = placed(dyn, task, spec.nodes) if start is None else start
        self.run: MethodRun = make_run(spec, method, model, self.capture,  # type: ignore[arg-type]
                                       metrics, spare)[0]
        # the run's streams are those of the episode's seed (RandomStreams(spec.seed))
        self.ep = task.episode(self.run.streams.stream(f"env.{task.name}"), obs0)
        self.done = False
        self.ended = False
        self.tick = -1
        self.run.start()
        #: the run's control events in the compiled loop, where it covers them
        self.control = (CompiledControl(self.run)
                        if control and unsupported(self.run) is None else None)

    @property
    def view(self) -> SwarmView:
        """The aligned view of the current command tick."""
        assert self.capture.view is not None
        return self.capture.view

    def captured(self) -> bool:
        """True once the current command tick's view has been captured."""
        return self.capture.view is not None

    def publish(self, nodes: NDArray[np.int64], cmds: Array) -> None:
        """Send the command rows of ``nodes`` (stamped with the shown frame) and resume."""
        view = self.view
        if nodes.size:
            self.run.publish_commands(self.tick, view.aligned_frame, nodes, cmds)
        self.capture.view = None

    def truth(self) -> Array:
        """True ``(n, 12)`` published-state columns at the latest issued frame."""
        return self.run.dyn.observe(self.run.state)

    def now(self) -> float:
        """Simulated time (s)."""
        return self.run.kernel.now


def _retire(scene: Scene) -> Spare | None:
    """A scene being replaced frees its message core's event table and its physics rings
    now, and its run is taken apart: a run is a web of reference cycles (its parts call
    back into it) that Python's cyclic collector would keep for many episodes (100 scenes
    at N = 11 held 100 more runs, +47 MB, after each reset) and walk at every full
    collection; without them reference counting frees it with the scene. The scene's
    ``run`` keeps only its (released) ``truth``.

    Returns:
        What the compiled core hands to the next scene's core (its own arrays and kept
        seed-free values: :meth:`~sigma_des.events.fast.driver.CompiledCore.retire`);
        None: the run is not on the compiled core.
    """
    run = scene.run
    core = run.core
    spare = core.retire() if isinstance(core, CompiledCore) else None
    if spare is None:
        core.close()
    truth = run.truth
    truth.release()
    # the run's parts refer to it (hooks, the core's host): without its attributes
    # nothing refers back to it
    env = run.kernel.env
    for *_, ev in env._queue:  # type: ignore[attr-defined]  # never to be processed
        ev.callbacks = None  # type: ignore[assignment]  # (a Call's is bound to itself)
    vars(env).clear()  # SimPy's environment holds methods bound to itself
    vars(run).clear()
    run.truth = truth
    return spare


class SceneBatch:
    """``n_scenes`` isolated scenes stepped together (see module docstring).

    Args:
        sc: the scenario (its ``seed`` is replaced per scene and episode).
        method: alignment method.
        dyn: the dynamics model.
        task: the task.
        n_scenes: number of scenes.
        scene_ids: the identity of each scene in its seed (default ``0..n_scenes-1``);
            scenes with the same id replay the same episodes (common random numbers).
        metrics: the scenes' runs collect their measurements (False: none; the same
            episodes, see ``MethodRun``).
    """

    def __init__(self, sc: Scenario, method: str, dyn: DynamicsModel, task: Task,
                 n_scenes: int, scene_ids: list[int] | None = None,
                 metrics: bool = True, control: bool = True) -> None:
        self.sc = sc
        self.spec = sc.run_spec()
        self.metrics = metrics
        self.control = control
        self.method = method
        self.dyn = dyn
        self.task = task
        self.n_scenes = n_scenes
        self.ids = list(range(n_scenes)) if scene_ids is None else [int(i) for i in scene_ids]
        if len(self.ids) != n_scenes:
            raise ValueError(f"scene_ids: needs {n_scenes} ids, got {len(self.ids)}")
        self.roots = [sc.seed] * n_scenes
        self.episode = [0] * n_scenes
        self.scenes: list[Scene] = []
        #: the placed model and its initial observation, shared by every episode
        self.start = placed(dyn, task, sc.nodes)

    def reset(self, roots: Sequence[int | None], ids: Sequence[int] | None = None) -> None:
        """Restart scenes ``ids`` (default: all) and run them to their first tick.

        Scene ``s`` plays episode 0 of root ``roots[s]`` if that is given, else its next
        episode under its current root. The first reset must restart every scene.
        """
        ids = list(range(self.n_scenes)) if ids is None else [int(s) for s in ids]
        if not self.scenes and len(ids) != self.n_scenes:
            raise ValueError("reset_mask: the first reset must reset every scene")
        for s in ids:
            root = roots[s]
            if root is not None:
                self.roots[s] = int(root)
                self.episode[s] = 0
            elif self.scenes:
                self.episode[s] += 1
        with trims_batched():  # the C heap trimmed once for all the fresh scenes
            if not self.scenes:
                self.scenes = [self._fresh(s) for s in range(self.n_scenes)]
            elif len(ids) < self.n_scenes:
                for s in ids:
                    self.scenes[s] = self._fresh(s, _retire(self.scenes[s]))
            else:
                spares = [_retire(old) for old in self.scenes]
                self.scenes = []
                gc.collect()  # any cycle left of the old episodes: one a reset (~0.08 s)
                self.scenes = [self._fresh(s, spares[s]) for s in range(self.n_scenes)]
        self.advance([self.scenes[s] for s in ids])

    def restart(self, ids: list[int], advance: bool = True) -> None:
        """Start the next episode of scenes ``ids`` (run to their first tick if ``advance``).

        Without ``advance`` the fresh scenes wait for the next :meth:`advance` of the
        whole batch (a scene's episode does not depend on which call runs it).
        """
        with trims_batched():  # the C heap trimmed once for all the fresh scenes
            for s in ids:
                self.episode[s] += 1
                self.scenes[s] = self._fresh(s, _retire(self.scenes[s]))
        if advance and ids:
            self.advance([self.scenes[s] for s in ids])

    def _fresh(self, s: int, spare: Spare | None = None) -> Scene:
        """Scene ``s``'s current episode, its core refilling ``spare`` (the arrays of the
        scene it replaces, :func:`_retire`)."""
        seed = scene_seed(self.roots[s], self.ids[s], self.episode[s])
        return Scene(with_seed(self.spec, seed), self.method, self.dyn, self.task, self.metrics,
                     self.start, self.control, spare)

    def advance(self, scenes: list[Scene]) -> None:
        """Run ``scenes`` to their next command tick (or end), physics batched."""
        todo = [s for s in scenes if not s.ended]
        while todo:
            due: list[Scene] = []
            for s in todo:
                if s.control is not None:  # physics in the compiled loop: no batching
                    code = s.control.advance_until(s.captured)
                    if code == PAUSED:
                        s.tick = s.run.align_tick - 1
                    else:
                        s.ended = True
                    continue
                code = s.run.advance_until(s.captured)
                if code == TRIGGER_DUE:
                    due.append(s)
                elif code == PAUSED:
                    s.tick = s.run.align_tick - 1
                elif code == END:
                    s.ended = True
            self._step_physics(due)
            todo = due

    def _step_physics(self, due: list[Scene]) -> None:
        # a model whose step reads neither the frame nor the node ids steps the scenes
        # of every frame with the same dt in one call (rows are independent)
        free = getattr(self.dyn, "frame_free", False)
        groups: dict[tuple[int, float] | float, list[Scene]] = {}
        for s in due:
            k, dt = s.run.next_trigger()
            groups.setdefault(dt if free else (k, dt), []).append(s)
        for group in groups.values():
            runs = [s.run for s in group]
            k, dt = runs[0].next_trigger()
            if len(runs) > 1:
                state = np.concatenate([r.state for r in runs])
                cmd = np.concatenate([r.nodes.cmd for r in runs])
                nodes = np.concatenate([r.truth.nodes for r in runs])
            else:
                state, cmd, nodes = runs[0].state, runs[0].nodes.cmd, runs[0].truth.nodes
            new = self.dyn.step(state, cmd, dt, k, nodes)
            n = self.sc.nodes
            for j, r in enumerate(runs):
                r.pending_state = new[j * n : (j + 1) * n]
