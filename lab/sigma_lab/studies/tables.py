"""Study tables: :func:`variant_table` and, re-exported, the project's one formatter.

:func:`text_table` right-aligns plain-text columns (printed by the scripts) and
:func:`md_table` writes a Markdown table (``lab/record/REPRODUCTION.md``); both live in
:mod:`sigma_des.tables`, shared with ``compare``'s table. :func:`variant_table` is a
study variant's seed means as a text table.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sigma_des.tables import md_table, text_table
from sigma_lab.studies.model import Study

__all__ = ["md_table", "text_table", "variant_table"]


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
