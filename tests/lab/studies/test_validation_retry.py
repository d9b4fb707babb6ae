"""A live cell that ran under load runs again, its loaded run set aside, tries counted."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from sigma_lab.studies.validation import suite
from sigma_lab.studies.validation.grid import Cell, Plan, full_plan, quick_plan
from sigma_lab.studies.validation.suite import run_again, set_aside

from sigma_des.errors import ConfigError


def _plan(retry: int) -> Plan:
    cell = Cell("n6-node", 6, "node")
    return Plan(("none",), 1.5, 0.5, cal_nodes=4, nodes=(6,), extra_nodes=6, repeats=1,
                cells=(cell,), retry_loaded=retry)


def _res(bg: float, tries: int | None = None) -> dict[str, Any]:
    r: dict[str, Any] = {"methods": {"none": {}}, "background_cores": bg, "load_before": 0.0}
    if tries is not None:
        r["tries"] = tries
    return r


def test_run_again_by_load_and_tries() -> None:
    plan = _plan(1)
    assert run_again(None, plan, 2) and run_again({"methods": {}}, plan, 2)
    assert not run_again(_res(0.5), plan, 2)  # 25 % of 2 cores is not above it
    assert run_again(_res(0.51), plan, 2)  # no tries recorded: the first
    assert not run_again(_res(0.51, tries=2), plan, 2)
    assert not run_again(_res(0.51), _plan(0), 2)
    assert run_again(_res(0.9, tries=3), _plan(3), 2)


def test_retry_loaded_range_and_defaults() -> None:
    with pytest.raises(ConfigError, match="--retry-loaded"):
        _plan(4)
    assert full_plan(("none",)).retry_loaded == 1
    assert quick_plan(("none",)).retry_loaded == 0


def test_set_aside_moves_the_run_out_of_live(tmp_path: Path) -> None:
    (tmp_path / "live" / "n6-node").mkdir(parents=True)
    (tmp_path / "live" / "n6-node" / "summary.json").write_text("{}")
    dest = set_aside(tmp_path, "n6-node", 1)
    assert dest == tmp_path / "loaded" / "n6-node-1"
    assert (dest / "summary.json").exists() and not (tmp_path / "live" / "n6-node").exists()


def test_live_pass_retries_a_loaded_cell_then_keeps_it(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    backgrounds = iter([1.2, 0.7, 0.1])  # cores of background in the runs, in order

    def fake_live_cell(cell: Cell, plan: Plan, out: Path) -> dict[str, Any]:
        out.mkdir(parents=True)
        bg = next(backgrounds)
        (out / "summary.json").write_text(json.dumps({"bg": bg}))
        return {"methods": {"none": {}}, "background_cores": bg, "load_before": 0.0,
                "load_after": 0.0, "timed_out": False, "exit": 0, "wall_s": 1.0}

    monkeypatch.setattr(suite, "live_cell", fake_live_cell)
    monkeypatch.setattr(suite.os, "cpu_count", lambda: 2)
    said: list[str] = []
    (tmp_path / "cells").mkdir()
    live = suite._live_all(_plan(1), tmp_path, said.append, 0.0)
    # run 1 loaded (1.2 cores), run 2 loaded (0.7) too: tries exhausted, run 2 kept
    assert live["n6-node"]["background_cores"] == 0.7 and live["n6-node"]["tries"] == 2
    assert json.loads((tmp_path / "loaded" / "n6-node-1" / "summary.json").read_text()) == {
        "bg": 1.2}
    assert json.loads((tmp_path / "live" / "n6-node" / "summary.json").read_text()) == {
        "bg": 0.7}
    assert sum("ran under load" in s for s in said) == 1
    # resumed with more retries allowed: the loaded run goes aside, the third is clean
    live = suite._live_all(_plan(2), tmp_path, said.append, 0.0)
    assert live["n6-node"]["background_cores"] == 0.1 and live["n6-node"]["tries"] == 3
    assert (tmp_path / "loaded" / "n6-node-2").exists()
    # and once more: kept
    live = suite._live_all(_plan(2), tmp_path, said.append, 0.0)
    assert said[-1].endswith("kept from an earlier run")
