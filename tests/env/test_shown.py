"""What a step gathers of its scenes (``sigma_des.env.shown``): the true states of many
scenes in one ``observe`` call only for a model whose rows are independent, and a
step's views reused only while every scene waits at the tick they were gathered at.

The batched control plane on the delay study's configuration (the compiled control
loop, no metrics; shown and perfect information; both restarting modes) gives the
scene-by-scene bits.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.agents.pointmass import PointMass
from sigma_des.env import SwarmVec
from sigma_des.env.scenes import Scene
from sigma_des.env.shown import Shown, truths
from tests.env.nested import flat_arrays
from tests.env.test_batched import _play as _play_batched
from tests.env.test_env_engines import STUDY

KW: dict[str, Any] = {"task": "tight", "method": "bides", "scenario": STUDY, "metrics": False}


class _Counted:
    """A model's ``observe`` with its calls counted (``rows``: say ``observe_rows``)."""

    def __init__(self, dyn: Any, rows: bool) -> None:
        self._dyn = dyn
        self.calls = 0
        if rows:
            self.observe_rows = True

    def observe(self, state: np.ndarray) -> np.ndarray:
        self.calls += 1
        return self._dyn.observe(state)  # type: ignore[no-any-return]


def _stepped(n_scenes: int, steps: int, **kw: Any) -> SwarmVec:
    env = SwarmVec(n_scenes=n_scenes, max_steps=40, **{**KW, **kw})
    env.reset(seed=4)
    rng = np.random.default_rng(2)
    for _ in range(steps):
        env.step(rng.uniform(-0.5, 0.5, (n_scenes, env.n_agents, 3)))
    return env


@pytest.mark.parametrize("rows", [True, False])
def test_truths_are_each_scenes_truth_in_one_call_only_for_row_wise_models(
        rows: bool, monkeypatch: Any) -> None:
    env = _stepped(4, 6)
    scenes = env.batch.scenes
    want = np.stack([sc.truth() for sc in scenes])
    per_scene: list[Scene] = []
    real = Scene.truth

    def counted(sc: Scene) -> np.ndarray:
        per_scene.append(sc)
        return real(sc)

    monkeypatch.setattr(Scene, "truth", counted)
    dyn = _Counted(env.dyn, rows)
    got = truths(scenes, dyn)  # type: ignore[arg-type]
    assert (dyn.calls, len(per_scene)) == ((1, 0) if rows else (0, 4))
    assert got.shape == (4, 5, 12) and got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)
    assert np.unique(got[:, :, 9]).size > 10  # the scenes' positions differ
    one = truths(scenes[:1], dyn)  # type: ignore[arg-type]  # one scene: its own call
    assert one.shape == (1, 5, 12) and len(per_scene) == (0 if rows else 4) + 1


def test_point_mass_observe_is_row_wise_bit_for_bit() -> None:
    pm = PointMass()
    assert pm.observe_rows
    rng = np.random.default_rng(8)
    blocks = [rng.normal(0.0, s, (5, 6)) for s in (1e-300, 1e-3, 1.0, 30.0, 1e12)]
    blocks.append(np.zeros((5, 6)))
    blocks.append(np.array([[0.0, -0.0, 1.0, -0.0, 0.0, -0.0]] * 3 + [[np.inf] * 6, [-1.0] * 6]))
    together = pm.observe(np.concatenate(blocks))
    alone = np.concatenate([pm.observe(b) for b in blocks])
    assert np.array_equal(together, alone, equal_nan=True)
    assert np.array_equal(np.signbit(together), np.signbit(alone))


def test_views_are_reused_only_at_the_tick_they_were_gathered_at() -> None:
    env = _stepped(3, 3)
    shown = env._shown
    assert shown is not None and shown.ids == [0, 1, 2]  # the last observation's views
    scenes = env.batch.scenes
    assert shown.of(scenes, [0, 1, 2]) is shown
    sub = shown.of(scenes, [2, 0])
    assert sub is not None and sub.ids == [2, 0]
    fresh = Shown.gather(scenes, [2, 0], env.dyn, False)
    for name in ("obs", "valid", "frame", "gen", "t"):
        np.testing.assert_array_equal(getattr(sub, name), getattr(fresh, name))
    assert sub.eps[0] is scenes[2].ep and sub.keys[1] is scenes[0].view
    assert fresh.of(scenes, [1]) is None  # never gathered
    assert fresh.of(scenes, [0]) is not None
    # a scene that moved on (its view published): gathered again
    scenes[1].capture.view = None
    assert shown.of(scenes, [0, 1]) is None
    assert shown.of(scenes, [0, 1, 2]) is None
    assert shown.of(scenes, [0, 2]) is not None


@pytest.mark.parametrize(("perfect", "autoreset"),
                         [(False, "next_step"), (False, "same_step"), (True, "next_step")])
def test_batched_control_plane_in_the_compiled_loop_equals_scene_by_scene(
        perfect: bool, autoreset: str) -> None:
    kw = {**KW, "n_scenes": 3, "max_steps": 7, "perfect_info": perfect, "autoreset": autoreset}
    if perfect:
        kw.update(method="none", scenario={"nodes": 5})
    one = _play_batched(False, 16, **kw)
    many = _play_batched(True, 16, **kw)
    a, b = flat_arrays(one), flat_arrays(many)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)
    ended = np.stack([s[2] | s[3] for s in one[2:]])
    assert ended.any()
