"""The one plain-text table formatter of the project.

``sigma-des compare``'s table (:meth:`sigma_des.api.Results.table`), the studies'
tables (the lab's studies), the benchmarks' and the reports' all go
through :func:`text_table` (right-aligned columns) or :func:`md_table` (Markdown);
:func:`cell` formats one value with a placeholder for a missing one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["MISSING", "cell", "md_table", "text_table"]

#: The placeholder of a value that was not measured.
MISSING = "-"


def cell(x: Any, spec: str) -> str:
    """``x`` formatted with ``spec`` (as :func:`format`), or :data:`MISSING` for ``None``
    or ``""``."""
    if x is None or (isinstance(x, str) and x == ""):
        return MISSING
    return format(x, spec)


def text_table(rows: Sequence[Sequence[str]]) -> str:
    """Rows of cells (the first is the header) as right-aligned columns, two spaces apart."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows)


def md_table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table: the header ``head``, a rule, then one line per row."""
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)
