"""SwarmVec's control plane batched over scenes (numpy) gives the scene-by-scene bits.

Both paths (``batched=True``, the default, and ``batched=False``, the task's one-scene
methods) play the same seeds with the same random actions, through episode ends
(collisions of full-speed random actions, divergence, ``max_steps``) and restarts, and
every array they return must be equal bit for bit (NaN where NaN).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.env import SwarmVec
from tests.env.nested import flat_arrays


def _play(batched: bool, steps: int, **kw: Any) -> list[Any]:
    env = SwarmVec(batched=batched, **kw)
    obs, infos = env.reset(seed=11)
    out: list[Any] = [obs, infos]
    rng = np.random.default_rng(5)
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, (env.n_scenes, env.n_agents, 3))
        out.append(env.step(a))
    return out


@pytest.mark.parametrize(
    ("kw", "steps"),
    [
        ({"task": "formation", "method": "bides", "autoreset": "same_step", "max_steps": 6}, 14),
        ({"task": "goal", "method": "none", "max_steps": 5}, 12),
        ({"task": "tight", "method": "hlc", "autoreset": "same_step", "max_steps": 6}, 10),
        ({"task": "formation", "method": "lockstep", "perfect_info": True, "max_steps": 4}, 8),
    ],
)
def test_batched_control_plane_equals_scene_by_scene(kw: dict[str, Any], steps: int) -> None:
    common = {"n_scenes": 3, "scenario": {"nodes": 4}, **kw}
    one = _play(False, steps, **common)
    many = _play(True, steps, **common)
    a, b = flat_arrays(one), flat_arrays(many)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)
    # the plays are not trivial: rewards vary and (with random full actions) episodes end
    rewards = np.stack([s[1] for s in one[2:]])
    assert np.unique(rewards).size > 10
    ended = np.stack([s[2] | s[3] for s in one[2:]])
    assert ended.any()
