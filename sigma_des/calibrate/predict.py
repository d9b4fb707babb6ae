"""``sigma-des predict``: a calibrated model's prediction of a target, with intervals.

:func:`predict` prepares the calibration for the target
(:func:`~sigma_des.calibrate.target.prepare`, the function the validation suite uses),
runs every method over ``R`` seeds (the scenario's seed, then the next ``R - 1``) and
gives each figure (:data:`~sigma_des.calibrate.target.FIGURES`) its interval
(:mod:`sigma_des.calibrate.intervals`): the seeds' spread and the residuals the last
validation measured for that metric in the prediction's regime (per node or bundled;
near capacity when the DES's mean machine utilisation reaches 70 % or its mean
missed-frame fraction 1 %; a trigger rate below 95 % of the nominal among the rates
not held). :meth:`Prediction.write` writes ``results.csv`` (tidy: one
row per seed, method and figure, as ``compare`` writes it) and ``summary.json`` (per
method: the mean, the seeds' standard deviation, the interval, the regime and where its
residuals come from).
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

from sigma_des.calibrate.intervals import (
    COVERAGE,
    RATE_METRIC,
    Interval,
    Residual,
    interval,
    load_residuals,
    lookup,
    rate_regime,
    regime,
)
from sigma_des.calibrate.target import FIGURES, des_figures, prepare, state_hop_ratio
from sigma_des.config import ALL_METHODS, METHODS, Scenario, config_hash, load
from sigma_des.errors import ConfigError
from sigma_des.outputs import check_out_dir, write_files
from sigma_des.tables import text_table
from sigma_des.version import __version__

__all__ = ["MAX_SEEDS", "Prediction", "UNITS", "load_calibration", "parse_methods", "predict"]

#: Units of the figures (the missed-frame fraction is a share).
UNITS = {"aoi_mean": "ms", "aoi_p99": "ms", "latency_state_mean": "ms",
         "trigger_rate_hz": "Hz", "missed_frac": "1"}
#: Most seeds one prediction runs.
MAX_SEEDS = 20
TIDY_COLUMNS = ("seed", "config_hash", "version", "method", "metric", "value", "unit")


def load_calibration(path: str | Path, key: str = "CAL") -> tuple[Scenario, dict[str, Any]]:
    """A calibrated scenario and its report (``CAL.json`` next to ``CAL.toml``).

    Raises:
        ConfigError: (``key``) no such file, or no report beside it.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(key, f"{p} is not a file (expected `sigma-des calibrate --out` TOML)")
    rep = p.with_suffix(".json")
    try:
        report = json.loads(rep.read_text())
    except FileNotFoundError:
        raise ConfigError(key, f"{p} has no report {rep.name} beside it: a calibration is "
                          "the TOML and the JSON `sigma-des calibrate --out` wrote") from None
    except (OSError, json.JSONDecodeError) as e:
        raise ConfigError(key, f"cannot read its report {rep}: {e}") from None
    if not isinstance(report, dict):
        raise ConfigError(key, f"{rep} is not a calibration report")
    return load(str(p)), report


def parse_methods(text: str | None) -> list[str]:
    """``--methods`` (comma-separated; None: all four)."""
    if text is None:
        return list(METHODS)
    out = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in out if m not in ALL_METHODS]
    if bad or not out:
        raise ConfigError("--methods", f"unknown {bad or 'empty list'}; allowed: "
                          f"{', '.join(ALL_METHODS)}")
    return out


@dataclass
class Prediction:
    """A prediction: the target scenario, per method the seeds' figures and intervals."""

    scenario: Scenario
    bundle: bool
    seeds: list[int]
    runs: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    intervals: dict[str, dict[str, Interval]] = field(default_factory=dict)
    regimes: dict[str, str] = field(default_factory=dict)
    rate_regimes: dict[str, str] = field(default_factory=dict)
    coverage: float = COVERAGE
    residual_meta: dict[str, Any] = field(default_factory=dict)
    state_hops: tuple[float, str] = (1.0, "")

    def table(self) -> str:
        """The figures per method: mean [interval], the regime."""
        head = ["method", "regime", *(f"{k} ({UNITS[k]})" if UNITS[k] != "1" else "missed %"
                                      for k in FIGURES)]
        rows = [head]
        for m, ivs in self.intervals.items():
            reg = self.regimes[m]
            rate = self.rate_regimes.get(m, reg)
            rows.append([m, reg if rate == reg else f"{reg}, rate {rate.split('-')[1]}",
                         *(_fmt(k, ivs[k]) for k in FIGURES)])
        foot = (f"\n{len(self.seeds)} seed(s); [interval] for live at {self.coverage:.0%} "
                "from the seeds' spread and the last validations' residuals of the metric "
                "in the regime (a trigger rate below 95 % of f_trig: of the rates not held)")
        missing = sorted({f"{k}/{self.regimes[m]}" for m, ivs in self.intervals.items()
                          for k, iv in ivs.items() if iv.residual is None})
        if missing:
            foot += f"\nno validated residuals for {', '.join(missing)}: seed spread only"
        few = sorted({f"{iv.residual.metric}/{iv.residual.regime}"
                      for ivs in self.intervals.values() for iv in ivs.values()
                      if iv.residual is not None and not iv.residual.enough})
        if few:
            foot += (f"\ntoo few validated cells for {self.coverage:.0%} in "
                     f"{', '.join(few)}: their full range")
        return text_table(rows) + foot

    def rows(self) -> list[dict[str, Any]]:
        """Tidy rows (``results.csv``): one per seed, method and figure."""
        out = []
        for m, runs in self.runs.items():
            for seed, figs in zip(self.seeds, runs, strict=True):
                h = config_hash(replace(self.scenario, seed=seed))
                out += [{"seed": seed, "config_hash": h, "version": __version__, "method": m,
                         "metric": k, "value": figs[k], "unit": UNITS[k]} for k in FIGURES]
        return out

    def summary(self) -> dict[str, Any]:
        """``summary.json``: the target, per method the figures with their intervals."""
        def res(r: Residual | None) -> dict[str, Any] | None:
            return None if r is None else {"regime": r.regime, "lo": r.lo, "hi": r.hi,
                                           "n": r.n, "enough": r.enough, "source": r.source}

        def method(m: str, ivs: dict[str, Interval]) -> dict[str, Any]:
            figs = {k: {"mean": iv.mean, "sd": iv.sd, "lo": iv.lo, "hi": iv.hi,
                        "unit": UNITS[k], "residual": res(iv.residual)}
                    for k, iv in ivs.items()}
            return {"regime": self.regimes[m],
                    "rate_regime": self.rate_regimes.get(m, self.regimes[m]), **figs}

        return {"config_hash": config_hash(self.scenario), "version": __version__,
                "nodes": self.scenario.nodes, "hosts": self.scenario.hosts,
                "bundle": self.bundle, "seeds": self.seeds, "coverage": self.coverage,
                "residuals": self.residual_meta,
                "state_hop_factor": self.state_hops[0], "state_hop_rule": self.state_hops[1],
                "methods": {m: method(m, ivs) for m, ivs in self.intervals.items()}}

    def write(self, out_dir: str | Path) -> tuple[Path, Path]:
        """Write ``results.csv`` and ``summary.json`` into ``out_dir``, all or none."""
        d = check_out_dir(out_dir)

        def tidy(fh: IO[str]) -> None:
            w = csv.DictWriter(fh, fieldnames=TIDY_COLUMNS)
            w.writeheader()
            w.writerows(self.rows())

        def summ(fh: IO[str]) -> None:
            fh.write(json.dumps(self.summary(), indent=2, sort_keys=True, default=float)
                     + "\n")

        csv_path, json_path = write_files(d, {"results.csv": tidy, "summary.json": summ})
        return csv_path, json_path


def _fmt(k: str, iv: Interval) -> str:
    if not math.isfinite(iv.mean):
        return "nan"
    if k == "missed_frac":
        return f"{100 * iv.mean:.1f} [{100 * iv.lo:.1f}, {100 * iv.hi:.1f}]"
    return f"{iv.mean:.3g} [{iv.lo:.3g}, {iv.hi:.3g}]"


def predict(cal: Scenario, report: dict[str, Any], sets: Sequence[str], *,
            bundle: bool = False, add_latency_s: float = 0.0, seeds: int = 1,
            methods: Sequence[str] | None = None, samples_dir: Path | None = None,
            residuals: str | Path | None = None,
            say: Callable[[str], None] | None = None) -> Prediction:
    """The calibration's prediction of a target (see the module doc).

    Args:
        cal: the calibrated scenario; report: its report.
        sets: the target's keys (``key=value``).
        bundle: bundled messages; add_latency_s: seconds added per host-link crossing.
        seeds: runs per method (1..:data:`MAX_SEEDS`).
        methods: the methods (default: the four).
        samples_dir: where shifted latency samples go (``--add-latency``).
        residuals: a ``residuals.toml`` (default: the shipped one).
        say: progress lines (None: quiet).

    Raises:
        ConfigError: bad input, named.
    """
    if not 1 <= seeds <= MAX_SEEDS:
        raise ConfigError("--seeds", f"must be in 1..{MAX_SEEDS}, got {seeds}")
    sc = prepare(cal, report, list(sets), bundle=bundle, add_latency_s=add_latency_s,
                 samples_dir=samples_dir)
    table, meta = load_residuals(residuals)
    cov = float(meta.get("coverage", COVERAGE))
    seed_list = [sc.seed + i for i in range(seeds)]
    window = sc.duration - sc.warmup
    frames = sc.f_trig * window  # the missed fraction's resolution
    pred = Prediction(sc, bundle, seed_list, coverage=cov, residual_meta=meta,
                      state_hops=state_hop_ratio(cal, report, sc))
    for m in methods or METHODS:
        runs = []
        for s in seed_list:
            if say is not None:
                say(f"predict: {m}, N = {sc.nodes} on {sc.hosts} hosts, seed {s} ...")
            runs.append(des_figures(replace(sc, seed=s), m))
        pred.runs[m] = runs
        util = _mean([r["machine_cpu_util_max"] for r in runs])
        missed = _mean([r["missed_frac"] for r in runs])
        pred.regimes[m] = reg = regime(bundle, util, missed)
        regs = dict.fromkeys(FIGURES, reg)
        regs[RATE_METRIC] = pred.rate_regimes[m] = rate_regime(
            reg, _mean([r[RATE_METRIC] for r in runs]), sc.f_trig)
        pred.intervals[m] = {k: interval(k, [r[k] for r in runs], lookup(table, k, regs[k]),
                                         cov, frames=frames, window=window,
                                         f_trig=sc.f_trig)
                             for k in FIGURES}
    return pred


def _mean(xs: list[float]) -> float:
    ok = [x for x in xs if math.isfinite(x)]
    return statistics.fmean(ok) if ok else math.nan
