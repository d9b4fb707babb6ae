"""A scene's bits do not depend on the scenes stepped beside it, on the delay study's
configuration (BiDES at 200 ms with 10 % loss: rate adaptation and restarts put the
scenes at different frames and steps): on the kernel's path, where the point mass's
physics of scenes at different frames with the same step share one call
(``frame_free``), and in the compiled control loop (each scene steps its own)."""

from __future__ import annotations

from typing import Any

import numpy as np

from sigma_des.env import SwarmVec
from sigma_des.env.scenes import Scene, SceneBatch
from tests.env.test_env_engines import STUDY, _same

KW: dict[str, Any] = {"task": "tight", "method": "bides", "max_steps": 6, "scenario": STUDY,
                      "metrics": False}


def _play(env: SwarmVec, acts: np.ndarray) -> list[Any]:
    """Every output of ``env`` over ``acts`` (reset, steps with autoresets, ``state()``)."""
    out: list[Any] = list(env.reset(seed=9))
    for a in acts:
        out += list(env.step(a))
    out.append(env.state())
    return out


def _pick(x: Any, s: int) -> Any:
    """Scene ``s`` of a batched output (dicts entry by entry)."""
    if isinstance(x, dict):
        return {k: _pick(v, s) for k, v in x.items()}
    return x[s : s + 1]


def _env(control: bool, **kw: Any) -> SwarmVec:
    env = SwarmVec(**KW, **kw)
    env.batch.control = control  # before the first reset builds the scenes
    return env


def test_a_scene_alone_equals_the_scene_in_a_batch(monkeypatch: Any) -> None:
    acts = np.random.default_rng(3).uniform(-1.0, 1.0, (18, 5, 4, 3))
    frames_together: list[int] = []  # distinct frames stepped in one physics call
    real = SceneBatch._step_physics

    def spy(self: SceneBatch, due: list[Scene]) -> None:
        by_dt: dict[float, set[int]] = {}
        for s in due:
            k, dt = s.run.next_trigger()
            by_dt.setdefault(dt, set()).add(k)
        frames_together.append(max(len(v) for v in by_dt.values()) if by_dt else 0)
        real(self, due)

    monkeypatch.setattr(SceneBatch, "_step_physics", spy)
    batch = _env(False, n_scenes=5)
    together = _play(batch, acts)
    assert max(frames_together) >= 2  # scenes at different frames shared a call
    assert max(batch.batch.episode) >= 1  # scenes restarted (autoreset)
    for s in range(5):
        alone = _play(_env(False, n_scenes=1, scene_ids=[s]), acts[:, s : s + 1])
        _same(alone, [_pick(v, s) for v in together])


def test_a_scene_alone_equals_the_scene_in_a_batch_in_the_compiled_control_loop() -> None:
    acts = np.random.default_rng(3).uniform(-1.0, 1.0, (18, 5, 4, 3))
    batch = _env(True, n_scenes=5)
    together = _play(batch, acts)
    assert all(sc.control is not None for sc in batch.batch.scenes)
    assert max(batch.batch.episode) >= 1  # scenes restarted (autoreset)
    for s in range(5):
        alone = _play(_env(True, n_scenes=1, scene_ids=[s]), acts[:, s : s + 1])
        _same(alone, [_pick(v, s) for v in together])
