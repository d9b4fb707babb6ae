"""Replaced scenes free their runs: a reset of the batch leaves none of the earlier
episode's runs alive (they are reference cycles, which Python's collector would keep
for many episodes), and an autoreset scene's old run gives up its rings at once."""

from __future__ import annotations

import weakref

import numpy as np

from sigma_des.env import SwarmVec


def test_a_reset_leaves_no_run_of_the_previous_episode_alive() -> None:
    env = SwarmVec(method="none", n_scenes=3, scenario={"nodes": 4}, max_steps=20)
    env.reset(seed=0)
    old = [weakref.ref(s.run) for s in env.batch.scenes]
    env.reset(seed=1)
    assert [r() for r in old] == [None, None, None]
    assert all(not s.run.truth.released for s in env.batch.scenes)  # the new ones run


def test_a_restarted_scene_releases_its_old_run() -> None:
    env = SwarmVec(method="none", n_scenes=2, scenario={"nodes": 4}, max_steps=20)
    env.reset(seed=0)
    first = env.batch.scenes[1]
    env.batch.restart([1])
    assert first.run.truth.released and env.batch.scenes[1] is not first
    assert not env.batch.scenes[0].run.truth.released
    obs, *_ = env.step(np.zeros((2, env.n_agents, 3)))
    assert np.isfinite(obs).all()
