"""studies/tables.py and studies/report.py: the table formatters and summary readers."""

from __future__ import annotations

import math
from pathlib import Path

from sigma_lab.studies.report import Templates, col, labels, method_table, num
from sigma_lab.studies.tables import md_table, text_table


def test_text_table_right_aligns_columns() -> None:
    assert text_table([["a", "bb"], ["ccc", "d"]]) == "  a  bb\nccc   d"


def test_md_table() -> None:
    assert md_table(["x", "y"], [["1", "2"], ["3", "4"]]) == (
        "| x | y |\n|---|---|\n| 1 | 2 |\n| 3 | 4 |"
    )


def test_num_formats() -> None:
    assert num(3.14159, 2) == "3.14"
    assert num(1234.5) == "1,234"  # large numbers: thousands, no decimals
    assert num(None) == "–" and num(math.nan) == "–" and num(math.inf) == "–"
    assert num("n/a") == "n/a"


def test_method_table_orders_labels_and_formats_columns() -> None:
    var = {
        "methods": {
            "bides": {"a": 1.0, "b": 0.25, "kib": 2048.0},
            "zeta": {"a": 3.0, "b": 0.5, "kib": 1024.0},
            "none": {"a": 2.0, "b": math.nan, "kib": 0.0},
        }
    }
    assert labels(var) == ["none", "bides", "zeta"]
    cols = (
        col("a ± b", "a", "b", nd=(0, 2)),
        col("KiB", "kib", nd=1, fn=lambda x: x / 1024),
        col("a / a", "a", "a", nd=1, sep=" / "),
    )
    head, rows = method_table(var, cols, lambda lab: lab.upper())
    assert head == ["method", "a ± b", "KiB", "a / a"]
    assert rows == [
        ["NONE", "2 ± –", "0.0", "2.0 / 2.0"],
        ["BIDES", "1 ± 0.25", "2.0", "1.0 / 1.0"],
        ["ZETA", "3 ± 0.50", "1.0", "3.0 / 3.0"],
    ]


def test_templates_fill_drops_one_final_newline(tmp_path: Path) -> None:
    (tmp_path / "s.md").write_text("N = {sc[nodes]}, {x:.1f} ms {{literal}}\n\n")
    assert Templates(tmp_path).fill("s", sc={"nodes": 5}, x=2.25) == "N = 5, 2.2 ms {literal}\n"
