"""``net.<link>.latency_down``: an optional per-direction latency (what ``calibrate`` fits
for triggers against states). Absent, nothing changes (not even the config hash)."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des import Scenario, load
from sigma_des.api import run_method
from sigma_des.config import config_hash, to_toml
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError
from sigma_des.live.shim import DOWN, UP, Impairment
from sigma_des.net.latency import Dist
from sigma_des.net.loss import LossSpec
from sigma_des.net.spec import LinkSpec, NetSpec

SMALL = ["nodes=4", "hosts=2", "duration=1.0", "warmup=0.2", "commands.enabled=false"]


def test_absent_means_latency_and_leaves_the_hash_alone() -> None:
    sc = Scenario()
    assert sc.net.host_link.latency_down is None
    assert sc.net.host_link.latency_of(False) == sc.net.host_link.latency
    assert "latency_down" not in to_toml(sc)
    assert config_hash(sc) == config_hash(load(None, []))
    down = load(None, ["net.host_link.latency_down=0.005"])
    assert down.net.host_link.latency_of(False) == Dist(dist="constant", value=0.005)
    assert down.net.host_link.latency_of(True) == sc.net.host_link.latency
    assert config_hash(down) != config_hash(sc)
    with pytest.raises(ConfigError, match="net.host_link.latency_down.dist: must be one of"):
        load(None, ["net.host_link.latency_down={dist='gamma'}"])


def test_a_random_down_direction_needs_a_random_latency_on_a_lossless_link() -> None:
    with pytest.raises(ConfigError, match="latency_down: a random down latency"):
        LinkSpec(latency_down=Dist(dist="exponential", mean=0.001))
    LinkSpec(latency_down=Dist(dist="exponential", mean=0.001), loss=LossSpec(p=0.01))
    LinkSpec(latency=Dist(dist="uniform", low=0.001, high=0.001),
             latency_down=Dist(dist="exponential", mean=0.001))


def test_triggers_take_the_down_direction_states_the_up_one() -> None:
    # trigger: server up (0.25 ms) + host down (5 ms); state: host up + server down (0.25 each)
    sc = load(None, [*SMALL, "net.host_link.latency_down=0.005"])
    m = run_method(sc, "none")["metrics"]
    base = run_method(load(None, SMALL), "none")["metrics"]
    assert m["latency_state_mean"] == pytest.approx(base["latency_state_mean"], abs=1e-9)
    assert m["latency_trigger_mean"] - base["latency_trigger_mean"] == pytest.approx(4.75, abs=0.01)


def test_both_engines_agree_with_random_directions() -> None:
    sets = [*SMALL, "net.host_link.latency={dist='uniform', low=0.0002, high=0.004}",
            "net.host_link.latency_down={dist='exponential', mean=0.002}",
            "net.server_link.latency={dist='uniform', low=0.0001, high=0.0003}",
            "net.server_link.latency_down={dist='lognormal', mean=0.002, std=0.002}"]
    for method in ("none", "bides"):
        fast = run_method(load(None, [*sets, "engine=cohort"]), method)
        ref = run_method(load(None, [*sets, "engine=events"]), method)
        assert fast["engine"]["used"] == "cohort"
        np.testing.assert_equal(fast["metrics"], ref["metrics"])  # NaN == NaN here


def test_the_live_shim_delays_incoming_messages_by_the_down_direction() -> None:
    link = LinkSpec(latency=Dist(dist="constant", value=0.001),
                    latency_down=Dist(dist="constant", value=0.004))
    imp = Impairment(link, NetSpec(transport="datagram"), RandomStreams(1), 0)
    assert imp.delay(0.0, UP, 2, 0, 0) == 0.001
    assert imp.delay(0.0, DOWN, 2, 0, 0) == 0.004
