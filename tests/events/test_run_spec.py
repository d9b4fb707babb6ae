"""The events layer's run spec: built from the scenario, validated, and the layering it buys."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

from sigma_des.errors import ConfigError
from tests.conftest import tiny

PKG = Path(__file__).resolve().parents[2] / "sigma_des"


def test_run_spec_takes_the_scenario_fields_and_the_layers_specs() -> None:
    sc = tiny(nodes=5, hosts=2, **{"bides.theta_warp": 7, "bides.time_warp": False,
                                    "fidelity.log_rate": 20.0})
    spec = sc.run_spec()
    assert spec.host_of == (0, 0, 0, 1, 1) == tuple(sc.host_of)
    assert (spec.nodes, spec.hosts, spec.seed, spec.f_trig) == (5, 2, sc.seed, sc.f_trig)
    assert (spec.theta_warp, spec.time_warp, spec.log_rate) == (7, False, 20.0)
    assert spec.compute is sc.compute and spec.commands is sc.commands
    assert spec.faults == sc.faults and spec.clocks is sc.clocks
    assert spec.net.topology.host_of == spec.host_of
    assert spec.collect.history_frames == sc.history_frames
    assert spec.align.bides is sc.bides


def test_a_bad_run_spec_names_its_field() -> None:
    spec = tiny(nodes=3).run_spec()
    with pytest.raises(ConfigError, match="host_of"):
        dataclasses.replace(spec, host_of=(0, 0))
    with pytest.raises(ConfigError, match="host_of"):
        dataclasses.replace(spec, host_of=(0, 0, 5))
    with pytest.raises(ConfigError, match="warmup"):
        dataclasses.replace(spec, warmup=spec.duration)


def _imports(path: Path) -> list[str]:
    out: list[str] = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.append(node.module)
        elif isinstance(node, ast.Import):
            out.extend(a.name for a in node.names)
    return out


def test_events_import_no_scenario_and_no_aircraft_and_core_imports_nothing_above() -> None:
    above = ("sigma_des.config", "sigma_des.specs", "sigma_des.api", "sigma_des.cli",
             "sigma_des.factory", "sigma_des.agents")
    bad = [(str(p.relative_to(PKG)), m) for p in (PKG / "events").rglob("*.py")
           for m in _imports(p) if m.startswith(above)]
    assert bad == []
    own = ("sigma_des.core", "sigma_des.errors")
    core = [(str(p.relative_to(PKG)), m) for p in (PKG / "core").rglob("*.py")
            for m in _imports(p) if m.startswith("sigma_des") and not m.startswith(own)]
    assert core == []
