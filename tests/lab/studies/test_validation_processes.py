"""The validation suite's process table (studies/validation/processes.py): cores per
window second, per cell, method and process kind, from each live run's CPU table."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from sigma_lab.studies.validation.processes import process_md, process_rows

from sigma_des.live.cpu import write_cpu


def _row(name: str, cpu: float, loop: float, wall: float, runq: float) -> dict[str, object]:
    return {"process": name, "pid": 1, "idle_s": 1.0, "idle_cpu_s": 0.0, "window_s": 2.0,
            "cpu_s": cpu, "messages": 100, "wakes": 10, "calls": 20, "loop_cpu_s": loop,
            "skk": 50.0, "skc": 0.01, "loop_wall_s": wall, "runq_wait_s": runq}


def test_cores_per_window_second_per_kind_and_hosts_averaged(tmp_path: Path) -> None:
    rows = [{**_row("server", 1.2, 0.5, 0.8, 1.0), "net_cpu_s": 0.6, "net_switches": 300,
             "main_switches": 500},
            {**_row("host0", 0.6, 0.3, 0.4, 0.2), "net_cpu_s": 0.2, "net_switches": 100},
            {**_row("host1", 1.0, 0.5, 0.8, 0.6), "net_cpu_s": 0.4, "net_switches": 300},
            {**_row("broker", 0.3, math.nan, math.nan, 0.1), "wakes": math.nan},
            {**_row("background", 0.1, math.nan, math.nan, math.nan), "pid": -1}]
    (tmp_path / "n30-node").mkdir()
    write_cpu({"none": {"cpu": rows}}, tmp_path / "n30-node")
    got = {r["kind"]: r for r in process_rows(tmp_path, ["n30-node", "absent"])}
    assert set(got) == {"server", "host", "broker"}  # background left out; no table: no rows
    assert got["server"]["cpu_cores"] == pytest.approx(0.6)
    assert got["server"]["loop_busy"] == pytest.approx(0.4)
    assert got["server"]["runq_cores"] == pytest.approx(0.5)
    h = got["host"]
    assert h["processes"] == 2
    assert (h["cpu_cores"], h["loop_cpu_cores"], h["loop_busy"], h["runq_cores"]) == \
        pytest.approx((0.4, 0.2, 0.3, 0.2))
    # the other threads (paho's): CPU in cores, voluntary switches per second
    assert (got["server"]["net_cpu_cores"], got["server"]["net_switch_rate"],
            got["server"]["main_switch_rate"]) == pytest.approx((0.3, 150.0, 250.0))
    assert (h["net_cpu_cores"], h["net_switch_rate"]) == pytest.approx((0.15, 100.0))
    assert math.isnan(h["main_switch_rate"])  # not recorded for the hosts here
    assert math.isnan(got["broker"]["loop_busy"]) and got["broker"]["runq_cores"] == 0.05
    md = process_md(process_rows(tmp_path, ["n30-node"]))
    assert md[2] == "| n30-node | 0.60 | 0.40 | 0.50 | 0.40 | 0.30 | 0.20 | 0.15 |"


def test_a_table_recorded_before_the_new_columns_gives_nan_not_an_error(tmp_path: Path) -> None:
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "cpu.csv").write_text(
        "method,process,pid,idle_s,idle_cpu_s,window_s,cpu_s,messages\n"
        "bides,server,1,1,0,2,1.0,10\n")
    (r,) = process_rows(tmp_path, ["c"])
    assert r["cpu_cores"] == 0.5 and math.isnan(r["runq_cores"]) and math.isnan(r["loop_busy"])
    assert process_md([r])[2] == "| c | 0.50 | - | - | - | - | - | - |"
