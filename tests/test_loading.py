"""loading.from_dict: a partial distribution table is read over the key's own default."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigma_des import compare, load
from sigma_des.config import with_overrides
from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist

SMALL = ["nodes=6", "hosts=2", "duration=0.6", "warmup=0.2"]


def test_a_set_field_keeps_the_other_fields_of_the_default() -> None:
    # the offender: `--set compute.step_time.mean=0.05` was a constant 0 step
    sc = load(None, ["compute.step_time.mean=0.05"])
    assert sc.compute.step_time == Dist(dist="lognormal", mean=0.05, std=0.0002)
    assert load(None, ["rpc.render_time.std=0.001"]).rpc.render_time == Dist(
        dist="lognormal", mean=0.008, std=0.001)
    assert load(None, ["broker.publish_service.value=1e-5"]).broker.publish_service == Dist(
        dist="constant", value=1e-5)
    # a table naming the default's own dist is completed from the default too
    assert load(None, ["rpc.render_time={dist='lognormal', mean=0.01}"]).rpc.render_time == Dist(
        dist="lognormal", mean=0.01, std=0.003)
    # with_overrides of a loaded scenario starts from that scenario's value
    base = load(None, ["compute.step_time.std=0.0001"])
    assert with_overrides(base, ["compute.step_time.mean=0.002"]).compute.step_time == Dist(
        dist="lognormal", mean=0.002, std=0.0001)


def test_a_file_table_without_dist_keeps_the_default(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text("[compute.step_time]\nmean = 0.05\n\n[net.server_link.latency]\nvalue = 0.002\n")
    sc = load(f)
    assert sc.compute.step_time == Dist(dist="lognormal", mean=0.05, std=0.0002)
    assert sc.net.server_link.latency == Dist(dist="constant", value=0.002)


def test_another_dist_is_a_new_distribution() -> None:
    sc = load(None, ["compute.step_time.dist='constant'", "compute.step_time.value=0.004"])
    assert sc.compute.step_time == Dist(dist="constant", value=0.004)
    sc = load(None, ["net.host_link.latency={dist='normal', mean=0.03}"])
    assert sc.net.host_link.latency == Dist(dist="normal", mean=0.03)


def test_a_key_without_a_default_distribution_needs_dist() -> None:
    with pytest.raises(ConfigError, match=r"net\.host_link\.latency_down\.dist: required"):
        load(None, ["net.host_link.latency_down.mean=0.001"])
    sc = load(None, ["net.host_link.latency_down={dist='exponential', mean=0.001}",
                     "net.host_link.latency={dist='uniform', low=0.0, high=0.001}"])
    assert sc.net.host_link.latency_down == Dist(dist="exponential", mean=0.001)


def test_the_default_mean_given_again_gives_the_default_results() -> None:
    # bit-identical tables: the partial table resolves to the default distribution
    a = compare(load(None, SMALL), ["none", "bides"], progress=False)
    b = compare(load(None, [*SMALL, "compute.step_time.mean=0.0008",
                            "rpc.render_time.std=0.003"]), ["none", "bides"], progress=False)
    assert list(a.rows(include_wall=False)) == list(b.rows(include_wall=False))
