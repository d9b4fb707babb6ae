"""Shared fixtures: tiny hand-computable scenarios."""

from __future__ import annotations

import os
import shutil
import tempfile
from typing import Any

import pytest

from sigma_des import Scenario, load

#: The ideal-run cache directory (sigma_des.cache.ideal) of this test process and its
#: children: private, made at configure time and removed at the end, so tests never read
#: or fill ~/.cache. Made in a hook, not on import: test modules also import this file
#: as ``tests.conftest``, and a second import must not make a second directory.
_CACHE_ROOT: list[str] = []


def pytest_configure(config: pytest.Config) -> None:
    """Point the ideal-run cache at a fresh private directory."""
    _CACHE_ROOT.append(tempfile.mkdtemp(prefix="sigma_des_test_cache_"))
    os.environ["SIGMA_DES_CACHE_DIR"] = _CACHE_ROOT[-1]
    # tests that drive SB3 directly, as a user would: its default logger's folder
    os.environ["SB3_LOGDIR"] = os.path.join(_CACHE_ROOT[-1], "sb3")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Long tests marked ``early`` first: at the end they would run alone on one worker."""
    items.sort(key=lambda item: item.get_closest_marker("early") is None)  # stable


def pytest_unconfigure(config: pytest.Config) -> None:
    """Remove this process's ideal-run cache directory."""
    for d in _CACHE_ROOT:
        shutil.rmtree(d, ignore_errors=True)


#: A tiny deterministic scenario: 3 nodes on 2 hosts, constant latencies, no loss,
#: instantaneous broker, constant 2 ms compute, QoS 0, no commands, ideal clocks.
TINY: dict[str, Any] = {
    "nodes": 3,
    "dynamics": "pointmass",
    "hosts": 2,
    "cores_per_host": 4,
    "f_trig": 100.0,
    "f_align": 25.0,
    "f_render": 25.0,
    "align_phase": 0.0,
    "render_phase": 0.0,
    "duration": 1.0,
    "warmup": 0.2,
    "net": {
        "qos": 0,
        "transport": "stream",
        "host_link": {"latency": 0.001, "bandwidth_mbps": 100.0},
        "server_link": {"latency": 0.0005, "bandwidth_mbps": 100.0},
    },
    "broker": {"publish_service": 0.0, "delivery_service": 0.0},
    "compute": {"step_time": 0.002},
    "commands": {"enabled": False},
}


def tiny(**over: Any) -> Scenario:
    """The :data:`TINY` scenario with top-level or dotted overrides."""
    sets = [f"{k.replace('__', '.')}={_toml(v)}" for k, v in over.items()]
    import tempfile

    import tomli_w

    with tempfile.TemporaryDirectory(prefix="sigma_des_tiny_") as d:
        path = os.path.join(d, "tiny.toml")
        with open(path, "w") as fh:
            fh.write(tomli_w.dumps(TINY))
        return load(path, sets)


def _toml(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + "}"
    return repr(v)


@pytest.fixture
def tiny_scenario() -> Scenario:
    """The tiny hand-computable scenario."""
    return tiny()
