"""Episode restarts reuse what does not depend on the episode's seed (the placed model,
its initial observation, the validated run spec, the core's resolved state declaration):
the observations and rewards of several episodes are those of scenes built the long way
(every part made again, the spec validated again), and the shared parts are unchanged by
the runs, whatever order the scenes' episodes use them in."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.env import SwarmVec
from sigma_des.env import scenes as S

STUDY = {"nodes": 5, "net.host_link.latency": {"dist": "normal", "mean": 0.2, "std": 0.04},
         "net.host_link.loss": {"p": 0.1}}
STEPS = 14


def _play(scene_ids: list[int], method: str = "bides") -> tuple[SwarmVec, list[bytes]]:
    """Observations and rewards (bytes) per scene and step, episodes of <= 4 decisions."""
    env = SwarmVec(task="tight", method=method, n_scenes=len(scene_ids), scenario=STUDY,
                   max_steps=4, seed=11, scene_ids=scene_ids, metrics=False)
    obs, _ = env.reset()
    rng = np.random.default_rng(5)
    rows = [[obs[s].tobytes()] for s in range(len(scene_ids))]
    for _ in range(STEPS):
        a = rng.uniform(-1, 1, (env.n_scenes, env.n_agents, 3))
        a[:, :, :] = a[:1]  # every scene the same actions: scenes comparable across envs
        obs, rew, term, trunc, _ = env.step(a)
        for s in range(len(scene_ids)):
            rows[s].append(obs[s].tobytes() + rew[s].tobytes() + term[s].tobytes()
                           + trunc[s].tobytes())
    assert max(env.batch.episode) >= 2  # several restarts happened
    return env, [b"".join(r) for r in rows]


def _long_way(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every episode built from scratch: the spec replaced (validated again), the
    placed model and its observation made for the scene, and new core arrays (the
    retired scene's are not refilled)."""
    def fresh(self: S.SceneBatch, s: int, spare: Any = None) -> S.Scene:
        seed = S.scene_seed(self.roots[s], self.ids[s], self.episode[s])
        spec = replace(self.spec, seed=seed, align=replace(self.spec.align, seed=seed))
        return S.Scene(spec, self.method, self.dyn, self.task, self.metrics)

    monkeypatch.setattr(S.SceneBatch, "_fresh", fresh)


@pytest.mark.parametrize("method", ["bides", "none"])
def test_restarts_give_the_episodes_built_the_long_way(
        monkeypatch: pytest.MonkeyPatch, method: str) -> None:
    _, cached = _play([0, 1, 2], method)
    with monkeypatch.context() as m:
        _long_way(m)
        _, long_way = _play([0, 1, 2], method)
    assert cached == long_way
    assert len(set(cached)) == 3  # the scenes differ: the comparison can fail


def test_shared_parts_are_not_changed_by_the_runs() -> None:
    env, rows = _play([0, 1, 2])
    batch = env.batch
    model, obs0 = S.placed(batch.dyn, batch.task, batch.sc.nodes)
    assert batch.start[0].initial_state(5).tobytes() == model.initial_state(5).tobytes()
    assert batch.start[1].tobytes() == obs0.tobytes()
    assert not batch.start[1].flags.writeable
    assert batch.spec == batch.sc.run_spec()  # the seeds went into copies
    # the same scenes in another order (their episodes restart in another order)
    _, other = _play([2, 0, 1])
    assert other == [rows[2], rows[0], rows[1]]


def test_a_write_to_the_shared_observation_is_refused() -> None:
    env, _ = _play([0])
    with pytest.raises(ValueError, match="read-only"):
        env.batch.start[1][0, 0] = 1.0


def test_with_seed_leaves_the_base_spec() -> None:
    env = SwarmVec(task="tight", scenario=STUDY, metrics=False)
    base: Any = env.batch.spec
    before = (base.seed, base.align.seed)
    got = S.with_seed(base, 99)
    assert (base.seed, base.align.seed) == before
    assert got.seed == 99 and got.align.seed == 99 and got.net is base.net
