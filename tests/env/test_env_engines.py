"""The env on the delay study's configuration: the compiled message core (``cohort``, the
env's engine: its draw tables filled a block of indices at a time, rollbacks re-simulated
in one compiled call) gives the per-message engine's bits (``events``: each draw sampled
one vector at a time, the executable specification).

Same seeds, same random actions, episode ends and partial resets (``reset_mask`` in the
``disabled`` autoreset mode, per-scene seeds); every array returned must be equal bit for
bit (NaN where NaN), and a second play of the same seed too.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.env import SwarmVec
from tests.env.nested import flat_arrays

STUDY = {"nodes": 5, "net.host_link.latency": {"dist": "normal", "mean": 0.2, "std": 0.04},
         "net.host_link.loss": {"p": 0.1}}


def _play(engine: str, seed: int, method: str, perfect: bool, **kw: Any) -> list[Any]:
    env = SwarmVec(task="tight", method=method, n_scenes=3, perfect_info=perfect,
                   max_steps=8, autoreset="disabled",
                   scenario={**(STUDY if method != "none" else {"nodes": 5}), "engine": engine},
                   **kw)
    obs, infos = env.reset(seed=seed)
    out: list[Any] = [obs, infos]
    rng = np.random.default_rng(seed)
    for k in range(14):
        if env.done.any():  # partial reset: the finished scenes only, one with a new seed
            mask = env.done.copy()
            seeds: list[int | None] = [None] * env.n_scenes
            seeds[int(np.flatnonzero(mask)[0])] = seed + 100 + k
            out.append(env.reset(seed=seeds, options={"reset_mask": mask}))
        out.append(env.step(rng.uniform(-1.0, 1.0, (env.n_scenes, env.n_agents, 3))))
    out.append(env.state())
    core = type(env.batch.scenes[0].run.core).__name__
    assert core == {"cohort": "CompiledCore", "events": "EventCore"}[engine]
    if method == "bides":  # late commands rolled the nodes back (re-simulations ran)
        assert sum(sc.run.truth.rollbacks for sc in env.batch.scenes) > 0
    return out


def _same(a: list[Any], b: list[Any]) -> None:
    fa, fb = flat_arrays(a), flat_arrays(b)
    assert len(fa) == len(fb)
    for x, y in zip(fa, fb, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize(("method", "perfect", "seed"),
                         [("bides", False, 3), ("bides", False, 41), ("none", True, 7)])
def test_compiled_core_env_equals_per_message_engine(method: str, perfect: bool,
                                                      seed: int) -> None:
    cohort = _play("cohort", seed, method, perfect)
    events = _play("events", seed, method, perfect)
    _same(cohort, events)
    _same(cohort, _play("cohort", seed, method, perfect))  # same seed, same bits
    # not trivial: rewards vary, episodes end and scenes were reset
    rewards = np.concatenate([np.ravel(s[1]) for s in cohort if isinstance(s, tuple)
                              and len(s) == 5])
    assert np.unique(rewards).size > 10
    assert any(isinstance(s, tuple) and len(s) == 2 for s in cohort[2:])  # a partial reset
