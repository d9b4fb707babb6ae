"""Reading study summaries into Markdown: numbers, per-method tables, templates.

The section modules of ``lab/record/REPRODUCTION.md`` (``experiments/report_*.py``, joined
by ``experiments/make_report.py``) read each study's ``summary.json`` (written by
:func:`sigma_lab.studies.write_study`) and fill a ``str.format`` template of prose
(:class:`Templates`) with figures formatted here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

__all__ = [
    "ORDER",
    "Col",
    "Templates",
    "col",
    "get",
    "labels",
    "method_table",
    "num",
    "plots_line",
    "provenance",
    "sd",
]

#: The canonical order of method labels in tables.
ORDER = ("none", "lockstep", "lockstep_evict", "hlc", "bides")


class Templates:
    """The ``<name>.md`` templates of one folder (``str.format`` fields)."""

    def __init__(self, folder: Path) -> None:
        """Read templates from ``folder``."""
        self.folder = Path(folder)

    def text(self, name: str) -> str:
        """Template ``<name>.md`` as it is (no fields; its final newline dropped)."""
        return (self.folder / f"{name}.md").read_text(encoding="utf-8").removesuffix("\n")

    def fill(self, name: str, **fields: Any) -> str:
        """Template ``<name>.md`` (its final newline dropped) with ``fields`` filled in."""
        return self.text(name).format(**fields)


def num(x: Any, nd: int = 1) -> str:
    """A number with ``nd`` decimals ("–" for missing or NaN; large numbers unchanged)."""
    if x is None or isinstance(x, str):
        return "–" if x is None else str(x)
    x = float(x)
    if not math.isfinite(x):
        return "–"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{nd}f}"


def labels(var: dict[str, Any]) -> list[str]:
    """Method labels of a variant in canonical order (:data:`ORDER`, then the rest)."""
    ms = list(var["methods"])
    return sorted(ms, key=lambda m: ORDER.index(m) if m in ORDER else len(ORDER))


def get(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Mean over seeds of one metric (None if absent)."""
    return var["methods"].get(lab, {}).get(metric)


def sd(var: dict[str, Any], lab: str, metric: str) -> Any:
    """Standard deviation over seeds of one metric (None if absent)."""
    return var.get("std", {}).get(lab, {}).get(metric)


class Col(NamedTuple):
    """One column of a per-method table: ``metrics`` (seed means) joined by ``sep``.

    ``nd`` gives the decimals of every metric (one per metric, or one for all) and
    ``fn`` maps a raw value before formatting (e.g. bytes to KiB).
    """

    header: str
    metrics: tuple[str, ...]
    nd: tuple[int, ...]
    sep: str = " ± "
    fn: Callable[[Any], Any] | None = None


def col(header: str, *metrics: str, nd: int | tuple[int, ...] = 1, sep: str = " ± ",
        fn: Callable[[Any], Any] | None = None) -> Col:
    """A :class:`Col` (``nd`` repeated for every metric when an int)."""
    nds = nd if isinstance(nd, tuple) else (nd,) * len(metrics)
    return Col(header, metrics, nds, sep, fn)


def method_table(
    var: dict[str, Any], cols: Sequence[Col], name: Callable[[str], str] = str
) -> tuple[list[str], list[list[str]]]:
    """Header and rows (one per method label, first cell ``name(label)``) of ``cols``."""
    rows = []
    for lab in labels(var):
        row = [name(lab)]
        for c in cols:
            vals = [get(var, lab, m) for m in c.metrics]
            if c.fn is not None:
                vals = [c.fn(v) for v in vals]
            row.append(c.sep.join(num(v, nd) for v, nd in zip(vals, c.nd, strict=True)))
        rows.append(row)
    return ["method", *(c.header for c in cols)], rows


def provenance(s: dict[str, Any]) -> str:
    """Command, seeds and version line of a study."""
    mode = " (**quick mode** — a smoke test, not the study)" if s.get("quick") else ""
    seeds = ",".join(str(x) for x in s.get("seeds", []))
    return (
        f"Command: `{s.get('command', '?')}`{mode} — seeds {seeds}, sigma_des "
        f"{s.get('version', '?')}."
    )


def plots_line(name: str, s: dict[str, Any], outputs: Path) -> str:
    """Where the plots are."""
    ps = s.get("plots", [])
    if not ps:
        return ""
    return "Plots: " + ", ".join(f"`{outputs.name}/{name}/{p}`" for p in ps) + "."
