"""``scenes.with_seed``: an episode's run spec made from the env's spec by replacing the
seed equals the one made the long way (the scenario with that seed, then ``run_spec``),
field for field, on the default and the delay study's scenario."""

from __future__ import annotations

from dataclasses import replace

import pytest

from sigma_des.env.options import EnvOptions, build_scenario
from sigma_des.env.scenes import scene_seed, with_seed

STUDY = {"nodes": 5, "net.host_link.latency": {"dist": "normal", "mean": 0.2, "std": 0.04},
         "net.host_link.loss": {"p": 0.1}}


@pytest.mark.parametrize("over", [{}, STUDY])
def test_with_seed_equals_the_scenario_with_that_seed(over: dict[str, object]) -> None:
    sc = build_scenario(EnvOptions(task="tight"), over)
    base = sc.run_spec()
    for seed in (0, 12345, scene_seed(7, 3, 2), 2**63 - 1):
        got = with_seed(base, seed)
        want = replace(sc, seed=seed).run_spec()
        assert got == want
        assert got.seed == seed and got.align.seed == seed
    assert with_seed(base, 1) != with_seed(base, 2)
