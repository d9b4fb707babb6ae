"""``hosts = 0`` (the default) places the paper's 20 nodes per host (issue 9.5)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sigma_des import ConfigError, load
from sigma_des.cli import main
from sigma_des.config import config_hash


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 1_000_000))
def test_any_node_count_works_without_hosts(n: int) -> None:
    sc = load(None, [f"nodes={n}"])
    assert sc.hosts == math.ceil(n / 20)
    per_host = [0] * sc.hosts
    for h in sc.host_of:
        per_host[h] += 1
    assert max(per_host) <= 20


def test_hand_cases_and_default_hash_unchanged() -> None:
    assert [load(None, [f"nodes={n}"]).hosts for n in (1, 4, 20, 21, 200, 1000)] == [
        1, 1, 1, 2, 10, 50,
    ]
    # the default (200 nodes) resolves to the former default hosts = 10: same hash
    assert config_hash(load(None, [])) == config_hash(load(None, ["hosts=10"]))


def test_explicit_hosts_still_checked() -> None:
    with pytest.raises(ConfigError) as ei:
        load(None, ["nodes=4", "hosts=10"])
    assert ei.value.key == "hosts" and "0 (auto" in ei.value.reason


def test_config_writes_automatic_hosts_as_0_so_editing_nodes_replaces_them(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``sigma-des config > a.toml``, then a new ``nodes`` in the file: hosts follow it."""
    assert main(["config", "--set", "nodes=4"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("# hosts = 0 means ceil(nodes / 20) hosts (here 1)")
    assert "\nhosts = 0\n" in out
    edited = tmp_path / "a.toml"
    edited.write_text(out.replace("\nnodes = 4\n", "\nnodes = 45\n"))
    assert load(edited).hosts == 3
    assert main(["config", "--set", "nodes=4", "--set", "hosts=2"]) == 0
    assert "\nhosts = 2\n" in capsys.readouterr().out  # explicit: kept as written


def test_sweep_points_place_their_own_nodes() -> None:
    """A grid over nodes on an auto-placed base gets ceil(nodes/20) hosts per point;
    a base with explicit hosts keeps them."""
    from sigma_des.sweep.grid import apply_point

    auto = load(None, [])
    assert [apply_point(auto, {"nodes": n}).hosts for n in (4, 50, 1000)] == [1, 3, 50]
    assert apply_point(auto, {"nodes": 50, "hosts": 5}).hosts == 5
    fixed = load(None, ["hosts=2"])
    assert apply_point(fixed, {"nodes": 50}).hosts == 2
