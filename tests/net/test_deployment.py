"""``[deployment]``: validation naming the key, and defaults that change nothing."""

from __future__ import annotations

import pytest

from sigma_des import load
from sigma_des.config import config_hash, to_toml
from sigma_des.errors import ConfigError
from sigma_des.events.fast.support import unsupported


def test_defaults_are_not_written_and_leave_the_hash_alone() -> None:
    sc = load(None, [])
    assert "deployment" not in to_toml(sc)
    same = load(None, ["deployment.preset='none'", "deployment.cores=2",
                       "deployment.clients='node'"])
    assert config_hash(same) == config_hash(sc)
    on = load(None, ["deployment.preset='colocated'"])
    assert "[deployment]" in to_toml(on)
    assert config_hash(on) != config_hash(sc)
    # written out, it loads back the same
    assert load(None, ["deployment.preset='colocated'", "deployment.cores=8"]).deployment \
        .cores == 8


@pytest.mark.parametrize(("override", "message"), [
    (["deployment.host_demand=1e-4"],
     "deployment.host_demand: needs deployment.preset colocated or dedicated"),
    (["deployment.server_tick=1e-4"],
     "deployment.server_tick: needs deployment.preset colocated or dedicated"),
    (["deployment.background=0.5"],
     "deployment.background: needs deployment.preset colocated or dedicated"),
    (["deployment.bundle=true"], "deployment.bundle: needs deployment.clients = 'host'"),
    (["deployment.cores=0"], r"deployment.cores: must be in 1..4096, got 0"),
    (["deployment.preset='colocated'", "deployment.cores=2", "deployment.background=2"],
     r"deployment.background: must be in \[0, cores=2\)"),
    (["deployment.preset='colocated'", "deployment.server_demand=2"],
     r"deployment.server_demand: must be in \[0, 1\] s"),
    (["deployment.preset='cluster'"], "deployment.preset: must be one of none, colocated"),
    (["deployment.clients='process'"], "deployment.clients: must be one of node, host"),
    (["deployment.cpus=2"], "deployment.cpus: unknown key"),
    (["deployment.lock_switch=0.005"],
     "deployment.lock_switch: needs deployment.preset colocated or dedicated"),
    (["deployment.preset='colocated'", "deployment.lock_switch=-0.001"],
     r"deployment.lock_switch: must be in \[0, 1\] s"),
    (["deployment.preset='colocated'", "deployment.host_wake=1e-4"],
     "deployment.host_wake: needs deployment.host_demand > 0"),
    (["deployment.preset='colocated'", "deployment.server_demand=1e-4",
      "deployment.server_wake=2"], r"deployment.server_wake: must be in \[0, 1\] s"),
    (["deployment.preset='colocated'", "deployment.host_demand=1e-4",
      "deployment.host_record=2e-4"],
     r"deployment.host_record: must be in \[0, deployment.host_demand = 0.0001\] s"),
    (["deployment.server_record=1e-5"],
     r"deployment.server_record: must be in \[0, deployment.server_demand = 0.0\] s"),
    (["deployment.preset='colocated'", "deployment.server_demand=1e-4",
      "deployment.server_record=-1e-5"], r"deployment.server_record: must be in \[0, 1\] s"),
    (["deployment.clients='host'", "methods='rpc'"], "deployment.clients: 'host' does not"),
    (["deployment.host_runq=0.5"],
     "deployment.host_runq: needs deployment.preset colocated or dedicated"),
    (["deployment.runq_growth=true"],
     "deployment.runq_growth: needs deployment.preset colocated or dedicated"),
    (["deployment.preset='colocated'", "deployment.broker_runq=-0.1"],
     r"deployment.broker_runq: must be in \[0, 100\] s per CPU second"),
    (["deployment.preset='colocated'", "deployment.host_demand=1e-4",
      "deployment.host_wake_side=1e-4"],
     r"deployment.host_wake_side: needs deployment.host_wake > 0"),
    (["deployment.preset='colocated'", "deployment.server_demand=1e-4",
      "deployment.server_wake=1e-4", "deployment.server_wake_side=2"],
     r"deployment.server_wake_side: must be in \[0, 1\] s"),
    (["deployment.preset='colocated'", "net.middleware='dds'", "net.transport='datagram'",
      "net.qos=0"], "deployment.preset: needs net.middleware 'mqtt'"),
])
def test_refusals_name_the_key(override: list[str], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load(None, override)


def test_wake_and_switch_at_zero_leave_the_hash_of_a_deployment_alone() -> None:
    """Keys added in session 10 are not written at 0: a deployment of an earlier
    version hashes as before; set, they are written and change the hash."""
    base = ["deployment.preset='colocated'", "deployment.host_demand=1e-4"]
    old = load(None, base)
    zero = load(None, [*base, "deployment.host_wake=0.0", "deployment.lock_switch=0.0",
                       "deployment.host_record=0.0"])
    assert config_hash(zero) == config_hash(old)
    assert "host_wake" not in to_toml(old) and "lock_switch" not in to_toml(old)
    assert "host_record" not in to_toml(zero)
    on = load(None, [*base, "deployment.host_wake=5e-5", "deployment.lock_switch=0.005"])
    assert config_hash(on) != config_hash(old)
    assert "host_wake = 5e-05" in to_toml(on) and "lock_switch = 0.005" in to_toml(on)
    rec = load(None, [*base, "deployment.host_record=2e-5"])
    assert config_hash(rec) != config_hash(old) and "host_record = 2e-05" in to_toml(rec)
    rq = load(None, [*base, "deployment.server_runq=0.0", "deployment.runq_growth=false"])
    assert config_hash(rq) == config_hash(old) and "runq" not in to_toml(rq)
    rq = load(None, [*base, "deployment.runq_growth=true"])
    assert config_hash(rq) != config_hash(old) and "runq_growth = true" in to_toml(rq)
    on_wake = load(None, [*base, "deployment.host_wake=5e-5"])
    side = load(None, [*base, "deployment.host_wake=5e-5", "deployment.host_wake_side=0.0"])
    assert config_hash(side) == config_hash(on_wake) and "wake_side" not in to_toml(side)
    side = load(None, [*base, "deployment.host_wake=5e-5", "deployment.host_wake_side=1e-4"])
    assert config_hash(side) != config_hash(on_wake)
    assert "host_wake_side = 0.0001" in to_toml(side)


def test_clients_and_bundle_are_allowed_without_a_cpu_stage() -> None:
    sc = load(None, ["deployment.clients='host'", "deployment.bundle=true"])
    assert not sc.deployment.cpu


def test_the_compiled_core_falls_back_for_bundles_only_and_says_why() -> None:
    assert unsupported(load(None, []).run_spec(), "none") is None
    # the CPU stage and per-host clients are mirrored (tests/events/test_cohort_deployment.py)
    assert unsupported(load(None, ["deployment.preset='dedicated'", "deployment.clients='host'"])
                       .run_spec(), "none") is None
    why = unsupported(load(None, ["deployment.clients='host'", "deployment.bundle=true"])
                      .run_spec(), "bides")
    assert why is not None and "deployment.bundle" in why
