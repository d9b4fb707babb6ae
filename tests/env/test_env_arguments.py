"""Bad arguments to the swarm envs (issue 26): the right exception type, the argument
named in the message; seeds follow Gymnasium's rule (None or a non-negative int)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sigma_des.env import SwarmEnv, SwarmVectorEnv

SMALL = {"nodes": 3}


@pytest.mark.parametrize("cls", [SwarmEnv, SwarmVectorEnv])
@pytest.mark.parametrize(("kwargs", "pattern"), [
    ({"scenario": 5}, r"^scenario: must be a dict of keys to values .*got int 5$"),
    ({"scenario": [("nodes", 3)]}, r"^scenario: must be a dict .*got list"),
    ({"task_params": "w_u=1"}, r"^task_params: must be a dict .*got str 'w_u=1'$"),
    ({"seed": "a"}, r"^seed: must be a non-negative int or None, got str 'a'$"),
    ({"seed": 1.5}, r"^seed: must be a non-negative int or None, got float 1.5$"),
])
def test_construction_arguments_of_the_wrong_type(cls: Any, kwargs: dict[str, Any],
                                                  pattern: str) -> None:
    kw = {"scenario": SMALL, **kwargs}
    with pytest.raises(TypeError, match=pattern):
        cls(**kw)


@pytest.mark.parametrize("cls", [SwarmEnv, SwarmVectorEnv])
def test_reset_seed_must_be_a_non_negative_int_or_none(cls: Any) -> None:
    env = cls(scenario=SMALL, max_steps=3)
    with pytest.raises(TypeError, match=r"^seed: must be a non-negative int or None, "
                       r"got str 'a'$"):
        env.reset(seed="a")
    with pytest.raises(TypeError, match=r"^seed: .* got bool True$"):
        env.reset(seed=True)
    with pytest.raises(ValueError, match=r"^seed: must be a non-negative int or None, "
                       r"got -1$"):
        env.reset(seed=-1)
    with pytest.raises(ValueError, match=r"^seed: .* got -1$"):
        cls(scenario=SMALL, seed=-1)
    # the refused seeds changed nothing: episode 0 of root 7 is still playing; 0 and a
    # numpy int are seeds like any other
    env.reset(seed=7)
    for bad in ("a", -1):
        with pytest.raises((TypeError, ValueError)):
            env.reset(seed=bad)
    assert env.vec.batch.roots[0] == 7 and env.vec.batch.episode[0] == 0
    env.reset(seed=np.int64(0))
    assert env.vec.batch.roots[0] == 0 and type(env.vec.batch.roots[0]) is int

def test_swarm_env_actions_must_be_a_dict() -> None:
    env = SwarmEnv(scenario=SMALL, max_steps=3)
    env.reset(seed=2)
    acts = [np.zeros(3) for _ in env.agents]
    with pytest.raises(TypeError, match=r"^actions: must be a dict of agent name -> action "
                       r"\(agents: \['node_1', 'node_2'\]\), got list$"):
        env.step(acts)
    # the refused step did not advance the episode: a dict of the same actions works
    _obs, rew, *_ = env.step(dict(zip(env.agents, acts, strict=True)))
    assert set(rew) == {"node_1", "node_2"}
