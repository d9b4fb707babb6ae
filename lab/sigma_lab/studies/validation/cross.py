"""Residuals across validations: one session's calibration against another's live runs.

A user calibrates once and predicts later. A validation's own residuals hold its
held-out cells' errors under a calibration made minutes before them, so they leave out
how far live moves between sessions (the calibration setting's mean state latency,
in eight calibrations on one machine: 1.77-2.04 ms). Validations of the same grid give,
per held-out cell, method and metric, the DES's value under their calibration and
live's value; for two validations X and Y, X's DES value against Y's live value is the
residual of a prediction calibrated in X's session and checked in Y's, in X's regime
(the DES's, as ``predict`` decides it). :func:`cross_values` gives them for every
ordered pair, :func:`shipped_toml` joins them with each validation's own residuals into
the file ``predict`` reads.

The earlier validations' scored rows are kept in one table (:data:`COLUMNS`,
``docs/results/data/validations-previous.csv``), each scored by the model being filed;
``python -m sigma_lab.studies.validation.cross add TAG CELLS.csv TABLE`` adds a filed
validation's rows before a validation on new live runs replaces it.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections.abc import Iterable, Mapping, Sequence
from itertools import permutations
from pathlib import Path
from typing import Any

from sigma_des.calibrate.intervals import COVERAGE, residuals_toml
from sigma_lab.studies.validation.coverage import residual_rows
from sigma_lab.studies.validation.scoring import error

__all__ = ["COLUMNS", "add", "compact", "cross_values", "read_cells", "read_table",
           "shipped_toml", "validations", "within_values"]

#: The columns of the earlier validations' table.
COLUMNS = ("validation", "cell", "method", "metric", "regime", "live", "des", "rel_error")

Rows = Sequence[Mapping[str, Any]]


def _bool(v: Any) -> bool:
    """A ``cells.csv`` flag read back from text (``True``/``False``/empty) or a bool."""
    return v is True or str(v) == "True"


def read_cells(path: Path) -> list[dict[str, Any]]:
    """A validation's ``cells.csv`` with its flags and numbers as the suite holds them."""
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        r["held_out"] = _bool(r["held_out"])
        r["passed"] = "" if r["passed"] == "" else _bool(r["passed"])
        for k in ("live", "des", "rel_error"):
            r[k] = float(r[k]) if r[k] != "" else math.nan
    return rows


def compact(rows: Rows, tag: str) -> list[dict[str, Any]]:
    """The held-out rows of one validation with a residual, in :data:`COLUMNS`
    (:func:`~sigma_lab.studies.validation.coverage.residual_rows`)."""
    return [{"validation": tag, **{k: r[k] for k in COLUMNS[1:]}} for r in residual_rows(rows)]


def read_table(path: Path) -> dict[str, list[dict[str, Any]]]:
    """The earlier validations' rows by validation, in the table's order (none if the
    file does not exist)."""
    out: dict[str, list[dict[str, Any]]] = {}
    if not path.exists():
        return out
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            out.setdefault(r["validation"], []).append(
                {**r, **{k: float(r[k]) for k in ("live", "des", "rel_error")}})
    return out


def add(path: Path, tag: str, cells: Path) -> int:
    """Append the scored rows of the validation in ``cells`` (a ``cells.csv``) to the
    table at ``path`` as ``tag``; the rows added.

    Raises:
        ValueError: the table already holds ``tag``.
    """
    if tag in read_table(path):
        raise ValueError(f"{path} already holds validation {tag!r}")
    rows = compact(read_cells(cells), tag)
    new = not path.exists()
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, lineterminator="\n")
        if new:
            w.writeheader()
        w.writerows({**r, **{k: f"{r[k]:.6g}" for k in ("live", "des", "rel_error")}}
                    for r in rows)
    return len(rows)


def validations(previous: Path, filed: Path) -> dict[str, list[dict[str, Any]]]:
    """The earlier validations' rows (the table at ``previous``) and the filed one's
    (its ``cells.csv`` at ``filed``, as ``filed``), in that order.

    Raises:
        ValueError: the table already holds the filed validation (the same live values
            in every cell): its residuals would count twice.
    """
    out = read_table(previous)
    rows = compact(read_cells(filed), "filed")
    for tag, old in out.items():
        if _same_live(old, rows):
            raise ValueError(f"{previous} already holds the filed validation (as {tag!r})")
    out["filed"] = rows
    return out


def _same_live(a: Rows, b: Rows) -> bool:
    """The same cells, methods and metrics with the same live values (to the table's six
    significant digits)."""
    ka = {(r["cell"], r["method"], r["metric"]): float(r["live"]) for r in a}
    kb = {(r["cell"], r["method"], r["metric"]): float(r["live"]) for r in b}
    return ka.keys() == kb.keys() and all(
        math.isclose(v, kb[k], rel_tol=1e-5, abs_tol=1e-12) for k, v in ka.items())


def _put(out: dict[tuple[str, str], list[float]], metric: str, reg: str, e: float) -> None:
    out.setdefault((metric, reg), []).append(e)
    out.setdefault((metric, "any"), []).append(e)


def within_values(validations: Mapping[str, Rows]) -> dict[tuple[str, str], list[float]]:
    """Each validation's own residuals per ``(metric, regime)`` and ``(metric, "any")``."""
    out: dict[tuple[str, str], list[float]] = {}
    for rows in validations.values():
        for r in rows:
            _put(out, r["metric"], r["regime"], float(r["rel_error"]))
    return out


def cross_values(validations: Mapping[str, Rows]) -> dict[tuple[str, str], list[float]]:
    """For every ordered pair of validations X, Y: X's DES value against Y's live value
    of each held-out cell, method and metric both scored, in X's regime."""
    out: dict[tuple[str, str], list[float]] = {}
    keyed = {tag: {(r["cell"], r["method"], r["metric"]): r for r in rows}
             for tag, rows in validations.items()}
    for x, y in permutations(keyed, 2):
        for key, rx in keyed[x].items():
            ry = keyed[y].get(key)
            if ry is None:
                continue
            e = error(key[2], float(ry["live"]), float(rx["des"]))
            if math.isfinite(e):
                _put(out, key[2], rx["regime"], e)
    return out


def _join(parts: Iterable[dict[tuple[str, str], list[float]]]
          ) -> dict[tuple[str, str], list[float]]:
    out: dict[tuple[str, str], list[float]] = {}
    for p in parts:
        for k, v in p.items():
            out.setdefault(k, []).extend(v)
    return out


def shipped_toml(validations: Mapping[str, Rows], source: str) -> str:
    """``predict``'s residuals: every validation's own and every ordered pair's cross
    residuals, joined per metric and regime."""
    n = len(validations)
    meta = {"coverage": COVERAGE, "validations": n, "cross_pairs": n * (n - 1),
            "kind": f"per-cell residuals of held-out cells, {n} validations, each also "
                    f"against the other validations' live runs ({n * (n - 1)} pairs)",
            "source": source}
    return residuals_toml(_join([within_values(validations), cross_values(validations)]),
                          meta)


def main(argv: list[str] | None = None) -> int:
    """``add TAG CELLS.csv TABLE``: keep a filed validation's rows in the table."""
    p = argparse.ArgumentParser(prog="python -m sigma_lab.studies.validation.cross",
                                description=main.__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("add", help="append a validation's scored held-out rows")
    a.add_argument("tag", help="the validation's name in the table (e.g. its live runs' "
                   "start, 2026-12-07T14:05)")
    a.add_argument("cells", type=Path, help="its cells.csv")
    a.add_argument("table", type=Path, help="the table (created if missing)")
    args = p.parse_args(argv)
    try:
        n = add(args.table, args.tag, args.cells)
    except (OSError, ValueError, KeyError) as e:
        p.exit(2, f"{p.prog}: error: {e}\n")
    print(f"added {n} rows of {args.tag} to {args.table}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
