"""config.with_overrides / set_key: the one key=value override implementation."""

from __future__ import annotations

import pytest

from sigma_des import load
from sigma_des.config import set_key, with_overrides
from sigma_des.errors import ConfigError


def test_with_overrides_sets_dotted_keys_and_validates() -> None:
    base = load(overrides=["nodes=4", "hosts=2"])
    sc = with_overrides(base, ["nodes=6", "net.qos=0", "lockstep.eviction_timeout=0.5"])
    assert (sc.nodes, sc.hosts, sc.net.qos, sc.lockstep.eviction_timeout) == (6, 2, 0, 0.5)
    assert (base.nodes, base.net.qos) == (4, 1)
    assert with_overrides(base, []) is base
    assert sc == load(overrides=["nodes=4", "hosts=2", "nodes=6", "net.qos=0",
                                 "lockstep.eviction_timeout=0.5"])


def test_with_overrides_names_the_bad_key() -> None:
    base = load()
    with pytest.raises(ConfigError, match="no_such_key"):
        with_overrides(base, ["no_such_key=1"])
    with pytest.raises(ConfigError, match="key=value"):
        with_overrides(base, ["nodes"])


def test_set_key_makes_tables_and_refuses_a_sub_key_of_a_value() -> None:
    data: dict[str, object] = {"a": 1, "b": None}
    set_key(data, "x.y.z", 2)
    set_key(data, "b.c", 3)  # None counts as absent
    assert data == {"a": 1, "b": {"c": 3}, "x": {"y": {"z": 2}}}
    with pytest.raises(ConfigError, match="is not a table"):
        set_key(data, "a.b", 1)
