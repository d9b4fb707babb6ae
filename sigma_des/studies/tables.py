"""The one table formatter of the studies, benchmarks and reports.

:func:`text_table` right-aligns plain-text columns (printed by the scripts);
:func:`md_table` writes a Markdown table (``docs/REPRODUCTION.md``);
:func:`variant_table` is a study variant's seed means as a text table.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sigma_des.studies.model import Study

__all__ = ["md_table", "text_table", "variant_table"]


def text_table(rows: Sequence[Sequence[str]]) -> str:
    """Rows of cells (the first is the header) as right-aligned columns, two spaces apart."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows)


def md_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table: the header ``head``, a rule, then one line per row."""
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def variant_table(study: Study, variant: str, columns: Sequence[tuple[str, str]]) -> str:
    """A plain-text table of one variant: one row per label, seed means of ``columns``.

    Args:
        study: what ran.
        variant: the variant shown.
        columns: ``(metric, header)`` pairs.
    """
    rows = [["method", *(h for _, h in columns)]]
    for lab in study.labels(variant):
        row = [lab]
        for metric, _ in columns:
            xs = study.values(variant, lab, metric)
            row.append(f"{np.nanmean(xs):.4g}" if np.isfinite(xs).any() else "nan")
        rows.append(row)
    return f"[{variant}]\n" + text_table(rows)
