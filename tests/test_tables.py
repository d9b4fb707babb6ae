"""sigma_des.tables: the one table formatter of compare, the studies and the benchmarks."""

from __future__ import annotations

import sigma_lab.studies.engine_tables as engine_tables
import sigma_lab.studies.tables as study_tables

import sigma_des.tables as tables


def test_one_formatter() -> None:
    assert study_tables.text_table is tables.text_table
    assert study_tables.md_table is tables.md_table
    assert engine_tables.text_table is tables.text_table and engine_tables.cell is tables.cell


def test_cell() -> None:
    assert tables.cell(None, ".2f") == "-" and tables.cell("", "g") == "-"
    assert tables.cell(1234.5, ",.0f") == "1,234" and tables.cell(0.0, ".2f") == "0.00"
    assert tables.cell("x", "") == "x"


def test_text_table_right_aligns() -> None:
    assert tables.text_table([("method", "Hz"), ("bides", "100.0")]) == (
        "method     Hz\n bides  100.0"
    )
