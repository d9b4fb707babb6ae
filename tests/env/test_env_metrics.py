"""``SwarmVec(metrics=False)``: the scenes' runs collect no measurements (a null
collector, no render ticks, no fidelity log) and play the very same episodes: every
array the env returns is equal bit for bit to the measuring env's, on the delay study's
configuration (BiDES 200 ms with 10 % loss: rollbacks; perfect information), with
episode ends and partial resets (``tests/env/test_env_engines.py``'s play), on both
message cores, and a second play of the same seed too.
"""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.env import SwarmEnv, SwarmVec
from sigma_des.errors import ConfigError
from sigma_des.events.server import AlignmentServer
from sigma_des.events.truth import NO_LOG
from sigma_des.metrics.null import NullCollector
from tests.env.test_env_engines import _play, _same


@pytest.mark.parametrize(("engine", "method", "perfect", "seed"),
                         [("cohort", "bides", False, 3), ("cohort", "bides", False, 41),
                          ("cohort", "none", True, 7), ("events", "bides", False, 5)])
def test_env_without_metrics_plays_the_same_bits(engine: str, method: str, perfect: bool,
                                                 seed: int) -> None:
    ref = _play(engine, seed, method, perfect)
    off = _play(engine, seed, method, perfect, metrics=False)
    _same(ref, off)
    _same(off, _play(engine, seed, method, perfect, metrics=False))  # same seed, same bits


def test_env_without_metrics_runs_no_collector_and_no_render_ticks(
        monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[float] = []
    real = AlignmentServer._render

    def counted(self: AlignmentServer) -> None:
        calls.append(self.clock.now)
        real(self)

    monkeypatch.setattr(AlignmentServer, "_render", counted)
    for metrics in (True, False):
        calls.clear()
        env = SwarmVec(task="tight", method="bides", n_scenes=2, max_steps=20,
                       metrics=metrics)
        env.reset(seed=2)
        for _ in range(6):
            env.step(np.zeros((2, env.n_agents, 3)))
        run = env.batch.scenes[0].run
        if metrics:  # 5 Hz render ticks over >= 0.6 s of two scenes
            assert len(calls) >= 4
            assert run.collector.triggers > 0
            assert run.truth.traj is not NO_LOG
        else:
            assert calls == []
            assert isinstance(run.collector, NullCollector)
            assert run.truth.traj is NO_LOG
            with pytest.raises(RuntimeError, match="no metrics"):
                run.finish()


def test_env_metrics_option_must_be_a_bool() -> None:
    with pytest.raises(ConfigError, match="metrics"):
        SwarmVec(task="tight", metrics="no")  # type: ignore[arg-type]


def test_pettingzoo_env_without_metrics_plays_the_same_episode() -> None:
    envs = [SwarmEnv(task="tight", max_steps=6, metrics=m) for m in (True, False)]
    outs = []
    for env in envs:
        obs, infos = env.reset(seed=4)
        out = [obs, infos]
        rng = np.random.default_rng(4)
        while env.agents:
            out.append(env.step({a: rng.uniform(-1, 1, 3) for a in env.agents}))
        outs.append(out)
    assert isinstance(envs[1].vec.batch.scenes[0].run.collector, NullCollector)
    assert not isinstance(envs[0].vec.batch.scenes[0].run.collector, NullCollector)
    _same(outs[0], outs[1])
