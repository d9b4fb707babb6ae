"""Shared fixtures: tiny hand-computable scenarios."""

from __future__ import annotations

from typing import Any

import pytest

from sigma_des import Scenario, load

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

    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as fh:
        fh.write(tomli_w.dumps(TINY))
    return load(fh.name, sets)


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
