"""What a study writes: ``results.csv``, ``timeseries.csv`` and ``summary.json``.

* ``results.csv`` — tidy, one row per variant × seed × method × metric with the
  columns of :data:`CSV_COLUMNS` (``seed``, ``config_hash`` and ``version`` come
  from :meth:`sigma_des.api.Results.rows`);
* ``timeseries.csv`` — per render tick: AoI mean/max, frame spread, trigger rate,
  latest trigger and aligned frame, per variant × seed × method;
* ``summary.json`` — the command that produced the outputs, the resolved scenario
  of every variant, and per method the mean, standard deviation (over seeds) and
  per-seed values of every metric; ``experiments/make_report.py`` reads it.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import sigma_des
from sigma_des.api import TIDY_COLUMNS
from sigma_des.config import to_dict
from sigma_lab.studies.args import command_line
from sigma_lab.studies.derived import DERIVED_UNITS
from sigma_lab.studies.model import RunRecord, Study
from sigma_lab.studies.tables import variant_table

__all__ = [
    "CSV_COLUMNS",
    "TS_KEYS",
    "aggregate",
    "json_ready",
    "tidy_rows",
    "update_plot_list",
    "finish",
    "write_rows",
    "write_study",
    "write_summary",
]

#: Columns of every study's ``results.csv``: the study and variant, then a tidy
#: :meth:`~sigma_des.api.Results.rows` row.
CSV_COLUMNS = ("study", "variant", *TIDY_COLUMNS)
#: Columns of ``timeseries.csv`` after the identifying ones.
TS_KEYS = ("t", "aoi_mean", "aoi_max", "spread", "f_trig", "latest_trigger", "aligned_frame")


def json_ready(x: Any) -> Any:
    """``x`` with arrays, NumPy scalars and tuples made plain; NaN → None, ±inf → text."""
    if isinstance(x, dict):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_ready(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_ready(x.tolist())
    if isinstance(x, np.generic):
        return json_ready(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


#: Per metric: the seed mean, the population std and the per-seed values.
SeedStats = tuple[dict[str, float], dict[str, float], dict[str, list[float]]]


def _seed_stats(runs: list[RunRecord]) -> SeedStats:
    """Mean, population std and per-seed values of every metric over ``runs`` (NaN left out)."""
    mean: dict[str, float] = {}
    std: dict[str, float] = {}
    per: dict[str, list[float]] = {}
    for name in runs[0].metrics:
        xs = np.array([r.metrics[name] for r in runs], dtype=float)
        per[name] = xs.tolist()
        ok = xs[~np.isnan(xs)]
        mean[name] = float(ok.mean()) if ok.size else math.nan
        std[name] = float(ok.std()) if ok.size > 1 else 0.0 if ok.size else math.nan
    return mean, std, per


def aggregate(study: Study) -> dict[str, Any]:
    """Per variant and label: mean, std (over seeds) and per-seed values of every metric."""
    out: dict[str, Any] = {}
    for v, sc in study.variants.items():
        var: dict[str, Any] = {
            "scenario": {k: x for k, x in to_dict(sc).items() if k not in ("seed", "methods")},
            "config_hash": {},
            "overrides": {},
            "methods": {},
            "std": {},
            "per_seed": {},
            "links_mbps": {},
        }
        for lab in study.labels(v):
            runs = study.runs(v, lab)
            var["config_hash"][lab] = runs[0].results.config_hash
            var["overrides"][lab] = list(runs[0].spec.overrides)
            var["methods"][lab], var["std"][lab], var["per_seed"][lab] = _seed_stats(runs)
            links = runs[0].results.links_mbps[runs[0].spec.method]
            var["links_mbps"][lab] = {
                k: float(np.mean([r.results.links_mbps[r.spec.method][k] for r in runs]))
                for k in links
            }
        out[v] = var
    return out


def tidy_rows(study: Study) -> list[dict[str, Any]]:
    """Tidy rows of every record (``Results.rows()`` relabelled, plus derived metrics)."""
    rows: list[dict[str, Any]] = []
    for r in study.records:
        base = None
        for row in r.results.rows(include_wall=False):
            if row["method"] != r.spec.method:
                continue
            row = {**row, "study": study.name, "variant": r.variant, "method": r.label}
            rows.append(row)
            base = row
        if base is None:
            raise ValueError(f"run {r.variant}/{r.label} has no metric rows")
        for name, value in r.derived.items():
            rows.append(
                {**base, "metric": name, "value": value, "unit": DERIVED_UNITS.get(name, "")}
            )
    return rows


def write_rows(out: Path, rows: Iterable[dict[str, Any]]) -> Path:
    """Write tidy rows (keys :data:`CSV_COLUMNS`) to ``out/results.csv``."""
    path = Path(out) / "results.csv"
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for row in rows:
            w.writerow({k: row[k] for k in CSV_COLUMNS})
    return path


def write_summary(out: Path, summary: dict[str, Any]) -> Path:
    """Write ``summary`` (made JSON-safe; NaN becomes null) to ``out/summary.json``."""
    path = Path(out) / "summary.json"
    path.write_text(json.dumps(json_ready(summary), indent=2, sort_keys=True) + "\n")
    return path


def write_timeseries(study: Study, out: Path) -> Path:
    """Write every record's render-tick series to ``out/timeseries.csv``."""
    path = Path(out) / "timeseries.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["study", "variant", "seed", "method", *TS_KEYS])
        for r in study.records:
            cols = [np.asarray(r.timeseries[k]) for k in TS_KEYS]
            for i in range(cols[0].size):
                w.writerow([study.name, r.variant, r.seed, r.label, *(c[i].item() for c in cols)])
    return path


def write_study(study: Study, paper: dict[str, Any] | None = None) -> Path:
    """Write ``results.csv``, ``timeseries.csv`` and ``summary.json`` into ``args.out``.

    Args:
        study: what ran.
        paper: the paper's reference figures for this study (stored in the summary).

    Returns:
        The output directory.
    """
    out = Path(study.args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_rows(out, tidy_rows(study))
    write_timeseries(study, out)
    summary = {
        "study": study.name,
        "command": command_line(study.name),
        "quick": bool(study.args.quick),
        "seeds": list(study.args.seeds),
        "version": sigma_des.__version__,
        "paper": paper or {},
        "variants": aggregate(study),
        "extra": study.extra,
        "plots": sorted(p.name for p in out.glob("*.png")),
        "wall": {"total_s": study.wall_s},
    }
    write_summary(out, summary)
    return out


def update_plot_list(out: Path) -> None:
    """Refresh the ``plots`` list of ``out/summary.json`` from the PNG files present."""
    path = Path(out) / "summary.json"
    data = json.loads(path.read_text())
    data["plots"] = sorted(p.name for p in Path(out).glob("*.png"))
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")


def finish(
    study: Study,
    plots: Callable[[Study], None],
    paper: dict[str, Any] | None = None,
    table: Sequence[tuple[str, str]] = (),
    notes: Sequence[str] = (),
) -> int:
    """Write the study's outputs and plots, print its tables; the script's exit status (0).

    Args:
        study: what ran.
        plots: draws the study's PNG files into ``study.args.out``.
        paper: the paper's reference figures (stored in ``summary.json``).
        table: ``(metric, header)`` columns printed per variant (none: no table).
        notes: further lines printed after the tables.
    """
    write_study(study, paper)
    plots(study)
    update_plot_list(study.args.out)
    if table:
        for v in study.variants:
            print(variant_table(study, v, table))
    for line in notes:
        print(line)
    print(f"wrote {study.args.out}")
    return 0
