"""Shared helpers of the paper-study scripts in ``experiments/`` (scripts-only code).

Every study script (``scale_200.py``, ``scale_1000.py``, ``latency_tolerance.py``,
``alignment_cost.py``, ``faults.py``) uses the same command-line flags
(:func:`study_parser`: ``--quick``, ``--seeds``, ``--out``, ``--jobs``,
``--progress``), runs its *variants* (a variant is one scenario family, e.g. one
transport or one fault) for every seed and method with :func:`run_study`, and
writes the same three kinds of output with :func:`write_study`:

* ``results.csv`` — tidy, one row per variant × seed × method × metric with the
  columns of :data:`CSV_COLUMNS` (``seed``, ``config_hash`` and ``version`` come
  from :meth:`sigma_des.api.Results.rows`);
* ``timeseries.csv`` — per render tick: AoI mean/max, frame spread, trigger rate,
  latest trigger and aligned frame, per variant × seed × method;
* ``summary.json`` — the command that produced the outputs, the resolved scenario
  of every variant, and per method the mean, standard deviation (over seeds) and
  per-seed values of every metric; ``make_report.py`` reads it.

Plots are written next to them as PNG files (matplotlib, Agg backend).

A *method label* is usually an alignment method name; a label may also be a
method run with scenario overrides (e.g. ``lockstep_evict`` = ``lockstep`` with
``lockstep.eviction_timeout`` set), see :class:`MethodSpec`.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import multiprocessing as mp
import shlex
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import sigma_des
from sigma_des.api import Results, compare
from sigma_des.config import Scenario, config_hash, from_dict, parse_set, to_dict
from sigma_des.plots import rate_series  # noqa: F401 - re-exported for the studies

__all__ = [
    "CSV_COLUMNS",
    "COLORS",
    "DERIVED_UNITS",
    "MethodSpec",
    "RunRecord",
    "Study",
    "aggregate",
    "derived_metrics",
    "plot_setup",
    "rate_series",
    "run_study",
    "study_parser",
    "write_study",
]

#: Columns of every study's ``results.csv``.
CSV_COLUMNS = (
    "study",
    "variant",
    "seed",
    "config_hash",
    "version",
    "method",
    "metric",
    "value",
    "unit",
)
#: Columns of ``timeseries.csv`` after the identifying ones.
TS_KEYS = ("t", "aoi_mean", "aoi_max", "spread", "f_trig", "latest_trigger", "aligned_frame")

#: One colour per method label, the same in every plot.
COLORS: dict[str, str] = {
    "none": "#7f7f7f",
    "lockstep": "#d62728",
    "lockstep_evict": "#ff9896",
    "hlc": "#1f77b4",
    "bides": "#2ca02c",
}

#: Units of the metrics derived here from the time series (see :func:`derived_metrics`).
DERIVED_UNITS: dict[str, str] = {
    "displacement_mean_ms": "ms",
    "displacement_max_ms": "ms",
    "f_trig_window_min_hz": "Hz",
    "f_trig_settled_hz": "Hz",
    "aligned_rate_hz": "Hz",
    "aligned_rate_std_hz": "Hz",
    "aoi_tick_mean_std_ms": "ms",
}


@dataclass(frozen=True)
class MethodSpec:
    """One column of a study: an alignment method, optionally with overrides.

    Attributes:
        label: the name shown in tables and plots (``lockstep_evict``).
        method: the alignment method run (``lockstep``).
        overrides: ``key=value`` scenario overrides applied for this label only.
    """

    label: str
    method: str
    overrides: tuple[str, ...] = ()


@dataclass
class RunRecord:
    """One method label of one variant and seed.

    Attributes:
        variant: variant name.
        seed: root seed.
        label: method label.
        results: the :class:`~sigma_des.api.Results` holding this run (its method is
            ``spec.method``).
        spec: the method spec.
        derived: metrics derived from the time series, ``{name: value}``.
    """

    variant: str
    seed: int
    label: str
    results: Results
    spec: MethodSpec
    derived: dict[str, float] = field(default_factory=dict)

    @property
    def metrics(self) -> dict[str, float]:
        """The engine's metrics of this run plus the derived ones."""
        return {**self.results.methods[self.spec.method], **self.derived}

    @property
    def timeseries(self) -> dict[str, Any]:
        """Per-render-tick arrays of this run."""
        return self.results.timeseries[self.spec.method]


@dataclass
class Study:
    """What a study script ran: its name, arguments, variants and records.

    Attributes:
        name: the study name (also the script's file stem).
        args: parsed command-line arguments.
        variants: variant name -> scenario of seed ``args.seeds[0]``.
        records: every run.
        wall_s: wall time of all runs (s).
        extra: study-specific JSON-ready results added to ``summary.json``.
    """

    name: str
    args: argparse.Namespace
    variants: dict[str, Scenario] = field(default_factory=dict)
    records: list[RunRecord] = field(default_factory=list)
    wall_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def labels(self, variant: str) -> list[str]:
        """Method labels of ``variant`` in run order (no duplicates)."""
        out: list[str] = []
        for r in self.records:
            if r.variant == variant and r.label not in out:
                out.append(r.label)
        return out

    def runs(self, variant: str, label: str) -> list[RunRecord]:
        """Every seed's record of one variant and label."""
        return [r for r in self.records if r.variant == variant and r.label == label]

    def values(self, variant: str, label: str, metric: str) -> np.ndarray:
        """One metric of one variant and label, one value per seed."""
        return np.array([r.metrics[metric] for r in self.runs(variant, label)], dtype=float)


# ------------------------------------------------------------------ command line


def parse_seeds(text: str) -> list[int]:
    """Parse ``1,2,3`` or ``1-5`` (or a mix, ``1,4-6``) into a list of seeds.

    Raises:
        argparse.ArgumentTypeError: on an empty or malformed list.
    """
    seeds: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if not part:
                continue
            if "-" in part:
                a, b = part.split("-", 1)
                seeds.extend(range(int(a), int(b) + 1))
            else:
                seeds.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad seed list {text!r}; use e.g. 1,2,3") from None
    if not seeds or any(s < 0 for s in seeds):
        raise argparse.ArgumentTypeError(f"bad seed list {text!r}; use e.g. 1,2,3")
    return list(dict.fromkeys(seeds))


def study_parser(
    name: str, doc: str | None, default_seeds: str = "1,2,3"
) -> argparse.ArgumentParser:
    """The common command line of a study script.

    Args:
        name: the study name; the default output directory is ``out/<name>``.
        doc: the script's module docstring (shown by ``--help``).
        default_seeds: seeds used when ``--seeds`` is not given.
    """
    p = argparse.ArgumentParser(
        prog=f"experiments/{name}.py",
        description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small, fast version (a few seconds; used by the test suite)",
    )
    p.add_argument(
        "--seeds",
        type=parse_seeds,
        default=None,
        help=f"root seeds, e.g. 1,2,3 or 1-5 (default: {default_seeds}; --quick: the first)",
    )
    p.add_argument("--out", type=Path, default=Path("out") / name, help="output directory")
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="run this many (variant, seed) cases in parallel processes (default 1)",
    )
    p.add_argument("--progress", action="store_true", help="show progress bars on stderr")
    p.set_defaults(_default_seeds=default_seeds, _study=name)
    return p


def finish_args(args: argparse.Namespace) -> argparse.Namespace:
    """Fill in the default seeds (``--quick`` uses only the first)."""
    if args.seeds is None:
        seeds = parse_seeds(args._default_seeds)
        args.seeds = seeds[:1] if args.quick else seeds
    if args.jobs < 1:
        raise SystemExit("--jobs must be >= 1")
    return args


def command_line(name: str) -> str:
    """The command that is running now, as a copy-pasteable string."""
    return shlex.join(["python", f"experiments/{name}.py", *sys.argv[1:]])


# ------------------------------------------------------------------ running


def _run_case(
    variant: str, sc: Scenario, specs: Sequence[MethodSpec], progress: bool
) -> list[tuple[str, MethodSpec, Results]]:
    """Run every method spec of one variant and seed (specs sharing overrides share a run)."""
    out: list[tuple[str, MethodSpec, Results]] = []
    groups: dict[tuple[str, ...], list[MethodSpec]] = {}
    for s in specs:
        groups.setdefault(s.overrides, []).append(s)
    for overrides, group in groups.items():
        scv = with_overrides(sc, overrides)
        res = compare(scv, methods=[s.method for s in group], progress=progress)
        for s in group:
            out.append((variant, s, res))
    order = {s.label: i for i, s in enumerate(specs)}
    out.sort(key=lambda x: order[x[1].label])
    return out


def with_overrides(sc: Scenario, overrides: Iterable[str]) -> Scenario:
    """``sc`` with extra ``key=value`` overrides (validated like ``--set``)."""
    overrides = tuple(overrides)
    if not overrides:
        return sc
    data = to_dict(sc)
    for item in overrides:
        key, value = parse_set(item)
        cur = data
        parts = key.split(".")
        for p in parts[:-1]:
            cur = cur.setdefault(p, {})
        cur[parts[-1]] = value
    return from_dict(Scenario, data)


def _case_worker(
    item: tuple[str, Scenario, tuple[MethodSpec, ...]],
) -> list[tuple[str, MethodSpec, Results]]:
    variant, sc, specs = item
    return _run_case(variant, sc, specs, False)


def run_study(
    name: str,
    args: argparse.Namespace,
    variants: Mapping[str, Callable[[int], Scenario]],
    specs: Mapping[str, Sequence[MethodSpec]],
) -> Study:
    """Run every variant × seed × method label and derive time-series metrics.

    Args:
        name: the study name.
        args: parsed arguments (seeds, jobs, progress).
        variants: variant name -> function building its scenario for a seed.
        specs: variant name -> its method labels.

    Returns:
        The study with one :class:`RunRecord` per variant × seed × label.
    """
    study = Study(name, args)
    cases: list[tuple[str, Scenario, tuple[MethodSpec, ...]]] = []
    for v, build in variants.items():
        for seed in args.seeds:
            sc = build(seed)
            if v not in study.variants:
                study.variants[v] = sc
            cases.append((v, sc, tuple(specs[v])))
    t0 = time.perf_counter()
    if args.jobs > 1 and len(cases) > 1:
        ctx = mp.get_context("spawn")
        with ctx.Pool(min(args.jobs, len(cases))) as pool:
            done = pool.map(_case_worker, cases, chunksize=1)
    else:
        done = [_run_case(v, sc, s, args.progress) for v, sc, s in cases]
    study.wall_s = time.perf_counter() - t0
    for case_out in done:
        for variant, spec, res in case_out:
            rec = RunRecord(variant, res.scenario.seed, spec.label, res, spec)
            rec.derived = derived_metrics(res.timeseries[spec.method], res.methods[spec.method])
            study.records.append(rec)
    return study


# ------------------------------------------------------------------ derived metrics


def derived_metrics(ts: dict[str, Any], m: dict[str, float]) -> dict[str, float]:
    """Metrics computed from one run's render-tick time series.

    * ``displacement_mean_ms`` / ``displacement_max_ms`` — the frame spread of the
      shown snapshot expressed as time (spread × the frame period in force at that
      tick): how far apart in simulated time the shown nodes are (the paper's
      "flicker" displacement).
    * ``f_trig_window_min_hz`` — lowest trigger rate in force during the measured
      window (taken from the time series; the engine's ``f_trig_min_hz`` ignores a
      rate set before the warm-up ended).
    * ``f_trig_settled_hz`` — median trigger rate over the last quarter of the run.
    * ``aligned_rate_hz`` / ``aligned_rate_std_hz`` — mean and standard deviation of
      the aligned frame's advance rate in 0.25 s windows (frames shown per second).
    * ``aoi_tick_mean_std_ms`` — standard deviation over render ticks of the
      per-tick mean AoI (how much the swarm's AoI wobbles over time).
    """
    t = np.asarray(ts["t"], dtype=float)
    out: dict[str, float] = {}
    if t.size == 0:
        return {k: math.nan for k in DERIVED_UNITS}
    f = np.asarray(ts["f_trig"], dtype=float)
    sp = np.asarray(ts["spread"], dtype=float)
    disp = sp / f * 1000.0
    out["displacement_mean_ms"] = float(disp.mean())
    out["displacement_max_ms"] = float(disp.max())
    out["f_trig_window_min_hz"] = float(f.min())
    out["f_trig_settled_hz"] = float(np.median(f[int(0.75 * f.size) :]))
    _, rate = rate_series(t, np.asarray(ts["aligned_frame"], dtype=float))
    out["aligned_rate_hz"] = float(rate.mean()) if rate.size else math.nan
    out["aligned_rate_std_hz"] = float(rate.std()) if rate.size else math.nan
    aoi = np.asarray(ts["aoi_mean"], dtype=float) * 1000.0
    aoi = aoi[~np.isnan(aoi)]
    out["aoi_tick_mean_std_ms"] = float(aoi.std()) if aoi.size else math.nan
    return out


# ------------------------------------------------------------------ aggregation and output


def _clean(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, np.generic):
        return _clean(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


def aggregate(study: Study) -> dict[str, Any]:
    """Per variant and label: mean, std (over seeds) and per-seed values of every metric."""
    out: dict[str, Any] = {}
    for v, sc in study.variants.items():
        labels = study.labels(v)
        var: dict[str, Any] = {
            "scenario": {k: x for k, x in to_dict(sc).items() if k not in ("seed", "methods")},
            "config_hash": {},
            "overrides": {},
            "methods": {},
            "std": {},
            "per_seed": {},
            "links_mbps": {},
        }
        for lab in labels:
            runs = study.runs(v, lab)
            var["config_hash"][lab] = runs[0].results.config_hash
            var["overrides"][lab] = list(runs[0].spec.overrides)
            names = list(runs[0].metrics)
            mean: dict[str, float] = {}
            std: dict[str, float] = {}
            per: dict[str, list[float]] = {}
            for name in names:
                xs = np.array([r.metrics[name] for r in runs], dtype=float)
                per[name] = xs.tolist()
                ok = xs[~np.isnan(xs)]
                mean[name] = float(ok.mean()) if ok.size else math.nan
                std[name] = float(ok.std()) if ok.size > 1 else 0.0 if ok.size else math.nan
            var["methods"][lab] = mean
            var["std"][lab] = std
            var["per_seed"][lab] = per
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
        assert base is not None
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
    path.write_text(json.dumps(_clean(summary), indent=2, sort_keys=True) + "\n")
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
    with (out / "timeseries.csv").open("w", newline="") as fh:
        w2 = csv.writer(fh)
        w2.writerow(["study", "variant", "seed", "method", *TS_KEYS])
        for r in study.records:
            ts = r.timeseries
            cols = [np.asarray(ts[k]) for k in TS_KEYS]
            for i in range(cols[0].size):
                w2.writerow([study.name, r.variant, r.seed, r.label, *(c[i].item() for c in cols)])
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


def update_plots(study: Study) -> None:
    """Refresh the list of plots in an already written ``summary.json``."""
    update_plot_list(Path(study.args.out))


def update_plot_list(out: Path) -> None:
    """Refresh the ``plots`` list of ``out/summary.json`` from the PNG files present."""
    path = Path(out) / "summary.json"
    data = json.loads(path.read_text())
    data["plots"] = sorted(p.name for p in Path(out).glob("*.png"))
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")


# ------------------------------------------------------------------ plotting


_FAST_PLOTS = False


def plot_setup(fast: bool = False) -> Any:
    """Import pyplot with the non-interactive Agg backend and a readable style.

    Args:
        fast: draft quality (lower resolution, no tight layout) — for ``--quick``
            runs, where drawing would otherwise take most of the run's time.
    """
    global _FAST_PLOTS
    _FAST_PLOTS = fast
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "figure.dpi": 110,
            "savefig.dpi": 110,
            "axes.grid": True,
            "grid.alpha": 0.3,
            "axes.titlesize": 11,
            "axes.labelsize": 10,
            "legend.fontsize": 8,
        }
    )
    return plt


def save(fig: Any, out: Path, name: str) -> Path:
    """Save ``fig`` as ``out/name`` (PNG) and close it."""
    path = Path(out) / name
    if _FAST_PLOTS:
        fig.savefig(path, dpi=50)
    else:
        fig.tight_layout()
        fig.savefig(path)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def bar_metric(
    ax: Any,
    study: Study,
    variant: str,
    metric: str,
    scale: float = 1.0,
    labels: Sequence[str] | None = None,
) -> None:
    """Bars of one metric per method label: mean over seeds, error bar = std over seeds."""
    labels = list(labels) if labels is not None else study.labels(variant)
    means, errs = [], []
    for lab in labels:
        xs = study.values(variant, lab, metric) * scale
        means.append(float(np.nanmean(xs)) if xs.size else math.nan)
        errs.append(float(np.nanstd(xs)) if xs.size > 1 else 0.0)
    x = np.arange(len(labels))
    ax.bar(x, means, yerr=errs, capsize=4, color=[COLORS.get(lab, "C0") for lab in labels])
    ax.set_xticks(x, labels)
    for xi, m in zip(x, means, strict=True):
        if math.isfinite(m):
            ax.annotate(
                f"{m:.3g}",
                (xi, m),
                ha="center",
                va="bottom",
                fontsize=8,
                xytext=(0, 2),
                textcoords="offset points",
            )


def scenario_for(base: Scenario, seed: int) -> Scenario:
    """``base`` with another root seed."""
    return replace(base, seed=seed)


def known(overrides: Iterable[str]) -> list[str]:
    """The overrides whose top-level key is a :class:`Scenario` field (others dropped).

    Lets a script pin optional parts of the model (e.g. ``fidelity.enabled``) that an
    older or newer version of the package may not have.
    """
    import dataclasses

    names = {f.name for f in dataclasses.fields(Scenario)}
    return [o for o in overrides if o.split("=", 1)[0].split(".", 1)[0].strip() in names]


def load_scenario(path: str | Path | None, overrides: Iterable[str]) -> Callable[[int], Scenario]:
    """A per-seed scenario builder: ``load(path, overrides)`` with ``seed`` set.

    Overrides naming a top-level key the scenario does not have are dropped (see
    :func:`known`).
    """
    from sigma_des import load

    base = load(path, known(overrides))
    return lambda seed: scenario_for(base, seed)


def config_hash_of(sc: Scenario) -> str:
    """Config hash of a scenario (seed and methods excluded)."""
    return config_hash(sc)


def plot_aoi_time(ax: Any, study: Study, variant: str, labels: Sequence[str] | None = None) -> None:
    """AoI over time (first seed): per-tick mean AoI as a line, per-tick max as a band."""
    labels = list(labels) if labels is not None else study.labels(variant)
    for lab in labels:
        r = study.runs(variant, lab)[0]
        ts = r.timeseries
        t = np.asarray(ts["t"], dtype=float)
        mean = np.asarray(ts["aoi_mean"], dtype=float) * 1000.0
        mx = np.asarray(ts["aoi_max"], dtype=float) * 1000.0
        c = COLORS.get(lab, None)
        ax.plot(t, mean, color=c, lw=1.0, label=f"{lab} (mean over nodes)")
        ax.fill_between(t, mean, mx, color=c, alpha=0.12, lw=0)
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("AoI (ms)")
    ax.legend(loc="upper right", ncols=2)


def plot_aoi_dist(ax: Any, study: Study, variant: str, labels: Sequence[str] | None = None) -> None:
    """AoI distribution per method: violins of the per-render-tick mean AoI (all seeds).

    Markers show the engine's p50/p95/p99 over all (render tick × node) samples (mean
    over seeds), so both the swarm-average wobble and the per-node tail are visible.
    """
    labels = list(labels) if labels is not None else study.labels(variant)
    data = []
    for lab in labels:
        xs = np.concatenate(
            [np.asarray(r.timeseries["aoi_mean"], dtype=float) for r in study.runs(variant, lab)]
        )
        xs = xs[~np.isnan(xs)] * 1000.0
        data.append(xs if xs.size else np.array([np.nan]))
    pos = np.arange(1, len(labels) + 1)
    ok = [i for i, d in enumerate(data) if np.isfinite(d).any()]
    if ok:
        parts = ax.violinplot([data[i] for i in ok], positions=pos[ok], showmedians=True)
        for body, i in zip(parts["bodies"], ok, strict=True):
            body.set_facecolor(COLORS.get(labels[i], "C0"))
            body.set_alpha(0.5)
    for q, mk in (("p50", "o"), ("p95", "^"), ("p99", "v")):
        ys = [float(np.nanmean(study.values(variant, lab, f"aoi_{q}"))) for lab in labels]
        ax.scatter(pos + 0.25, ys, marker=mk, color="k", s=18, label=f"{q} of node samples")
    ax.set_xticks(pos, labels)
    ax.set_ylabel("AoI (ms)")
    ax.legend(loc="upper left")


def text_table(study: Study, variant: str, columns: Sequence[tuple[str, str]]) -> str:
    """A plain-text table of one variant: one row per label, seed means of ``columns``."""
    head = ["method", *(h for _, h in columns)]
    rows = [head]
    for lab in study.labels(variant):
        row = [lab]
        for metric, _ in columns:
            xs = study.values(variant, lab, metric)
            row.append(f"{np.nanmean(xs):.4g}" if np.isfinite(xs).any() else "nan")
        rows.append(row)
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return f"[{variant}]\n" + "\n".join(lines)
