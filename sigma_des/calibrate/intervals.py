"""How far to trust a prediction: intervals from the seed spread and the validation residuals.

A prediction's interval for one metric joins two parts:

* **the DES's seed-to-seed spread**: over ``R`` seeds the mean ``m`` and standard
  deviation ``s``; the half-width ``h = z * s`` with ``z`` the normal quantile of the
  stated coverage (``h = 0`` with one seed);
* **the residuals the last validation measured** for that metric and regime
  (:func:`regime`: per node or bundled, below or near capacity; a trigger rate the
  DES does not hold is read among the rates not held, :func:`rate_regime`), ``r = (DES
  - live) / live`` (percentage points ``100 * (DES - live)`` for the missed-frame fraction). Of
  ``n`` residuals the bounds ``[r_lo, r_hi]`` are the ``k``-th smallest and largest,
  ``k = floor((n + 1) * (1 - coverage) / 2)`` (:func:`residual_bounds`): for a new
  cell exchangeable with the validated ones, live's value then lies inside with
  probability at least ``coverage`` (split conformal, per tail). With too few residuals
  for that (``k < 1``) the bounds are their minimum and maximum, and the interval says so.

For a relative metric, live = DES / (1 + r), so the interval is
``[(m - h) / (1 + r_hi), (m + h) / (1 + r_lo)]``; for the missed-frame fraction
``[m - h - r_hi / 100, m + h - r_lo / 100]``, at least one frame of the target's window
(``1 / frames``) either side of ``m`` (:func:`interval`), clipped to 0..1; a trigger
rate's reaches at least one trigger of the window either side and stops at ``f_trig``.
The residuals come from ``residuals.toml`` (shipped with the package,
:func:`load_residuals`): either the residual values (what the validation suite writes)
or, where only a published summary of a validation exists, its bounds ``lo``, ``hi``
with their source.
"""

from __future__ import annotations

import math
import statistics
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["COVERAGE", "NEAR_MISSED", "NEAR_UTIL", "PP_METRICS", "RATE_HELD", "RATE_METRIC",
           "Interval", "Residual", "interval", "load_residuals", "lookup", "rate_regime",
           "regime", "residual_bounds", "residuals_toml"]

#: The coverage the intervals are built for: above the 80 % a validation checks they
#: reach, because a regime has only 13-26 validated residuals and the measured share of
#: intervals built for exactly 80 % falls below 80 % about as often as above it.
COVERAGE = 0.85
#: A DES machine CPU utilisation at or above this puts a prediction near capacity.
NEAR_UTIL = 0.70
#: So does a predicted missed-frame fraction at or above this.
NEAR_MISSED = 0.01
#: Metrics whose residuals are differences in percentage points.
PP_METRICS = ("missed_frac",)
#: A method holds its trigger rate when it achieves at least this share of the nominal.
RATE_HELD = 0.95
#: The trigger rate's figure (Hz).
RATE_METRIC = "trigger_rate_hz"


def regime(bundle: bool, util: float, missed: float) -> str:
    """``node-below``, ``node-near``, ``bundle-below`` or ``bundle-near``: the message
    mode, and near capacity when the DES's machine utilisation is at least
    :data:`NEAR_UTIL` or its missed-frame fraction at least :data:`NEAR_MISSED` (NaN
    figures count as below)."""
    near = (math.isfinite(util) and util >= NEAR_UTIL) or (
        math.isfinite(missed) and missed >= NEAR_MISSED)
    return f"{'bundle' if bundle else 'node'}-{'near' if near else 'below'}"


def rate_regime(reg: str, rate: float, f_trig: float) -> str:
    """The regime a trigger-rate figure is read in: ``<mode>-limited`` when the DES's
    ``rate`` is below :data:`RATE_HELD` of the nominal ``f_trig`` (the method's
    alignment sets it: a barrier waiting for the slowest node, a re-request under loss),
    else ``reg``. A held rate's residuals are nearly all 0, which says nothing of how far
    a rate the alignment sets may be off."""
    if math.isfinite(rate) and rate < RATE_HELD * f_trig:
        return f"{reg.split('-')[0]}-limited"
    return reg


def residual_bounds(values: Sequence[float], coverage: float = COVERAGE
                    ) -> tuple[float, float, bool]:
    """``(r_lo, r_hi, enough)`` of ``values`` at ``coverage`` (see the module doc);
    ``enough`` is False when there were too few for it (then the minimum and maximum).

    Raises:
        ValueError: no finite value, or a coverage outside (0, 1).
    """
    if not 0.0 < coverage < 1.0:
        raise ValueError(f"coverage must be in (0, 1), got {coverage}")
    xs = sorted(v for v in values if math.isfinite(v))
    if not xs:
        raise ValueError("residual_bounds() needs at least one finite value")
    n = len(xs)
    k = math.floor((n + 1) * (1.0 - coverage) / 2.0 + 1e-9)  # 1 - 0.8 is 0.1999…
    if k < 1:
        return xs[0], xs[-1], False
    return xs[k - 1], xs[n - k], True


@dataclass(frozen=True)
class Residual:
    """The residuals of one metric in one regime.

    Attributes:
        metric: the metric.
        regime: a :func:`regime` name, ``node-any``/``bundle-any`` or ``any``.
        lo: lower bound of the residual at the file's coverage.
        hi: upper bound.
        n: how many validated cells they come from (0: not known).
        enough: False when ``n`` was too small for the coverage (the range instead).
        source: where the numbers come from.
    """

    metric: str
    regime: str
    lo: float
    hi: float
    n: int
    enough: bool
    source: str


def _entry(e: dict[str, Any], coverage: float, default_source: str) -> Residual:
    metric, reg = str(e.get("metric", "")), str(e.get("regime", ""))
    if not metric or not reg:
        raise ConfigError("residuals", f"an entry without metric or regime: {e}")
    src = str(e.get("source", default_source))
    if "values" in e:
        vals = [float(v) for v in e["values"]]
        lo, hi, enough = residual_bounds(vals, coverage)
        return Residual(metric, reg, lo, hi, len(vals), enough, src)
    if "lo" in e and "hi" in e and float(e["lo"]) <= float(e["hi"]):
        return Residual(metric, reg, float(e["lo"]), float(e["hi"]), int(e.get("n", 0)),
                        bool(e.get("enough", True)), src)
    raise ConfigError("residuals", f"{metric}/{reg}: needs values, or lo <= hi")


def _read(path: str | Path | None) -> dict[str, Any]:
    """A ``residuals.toml``'s tables (None: the shipped file)."""
    try:
        if path is None:
            text = (resources.files("sigma_des.calibrate") / "residuals.toml").read_text()
        else:
            text = Path(path).read_text()
        return tomllib.loads(text)
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ConfigError("residuals", f"cannot read {path or 'the shipped file'}: {e}"
                          ) from None


def load_residuals(path: str | Path | None = None) -> tuple[dict[tuple[str, str], Residual],
                                                             dict[str, Any]]:
    """The residuals per ``(metric, regime)`` and the file's ``[meta]`` table.

    Args:
        path: a ``residuals.toml`` (default: the one shipped with the package).

    Raises:
        ConfigError: (``residuals``) an unreadable or malformed file.
    """
    data = _read(path)
    meta = dict(data.get("meta", {}))
    cov = float(meta.get("coverage", COVERAGE))
    src = str(meta.get("source", ""))
    table = {}
    for entry in data.get("residual", []):
        r = _entry(entry, cov, src)
        table[(r.metric, r.regime)] = r
    return table, meta


def lookup(table: dict[tuple[str, str], Residual], metric: str, reg: str) -> Residual | None:
    """The residuals of ``metric`` in regime ``reg``, else of its message mode
    (``node-any``), else of every regime (``any``); None if none."""
    mode = reg.split("-")[0]
    for key in (reg, f"{mode}-any", "any"):
        if (metric, key) in table:
            return table[(metric, key)]
    return None


@dataclass(frozen=True)
class Interval:
    """A predicted metric: the seeds' mean, their spread and the interval for live."""

    mean: float
    sd: float
    lo: float
    hi: float
    residual: Residual | None


def interval(metric: str, values: Sequence[float], res: Residual | None,
             coverage: float = COVERAGE, frames: float = 0.0, window: float = 0.0,
             f_trig: float = math.inf) -> Interval:
    """The interval of ``metric`` from the seeds' ``values`` and the residuals ``res``
    (None: the seed spread alone); see the module doc. NaN values are left out; none
    finite gives NaN throughout.

    ``frames`` (the target's trigger rate times its metrics window; 0: not known) sets
    the missed-frame fraction's resolution: its interval reaches at least ``1 / frames``
    either side of the DES's value. A stall of the live machine now and then drops a
    whole frame's states, which the DES has no cause for; most validated cells below
    capacity miss nothing in either, so their residuals alone give an interval
    narrower than one frame, which a single stall would leave. ``window`` (the target's
    metrics window, s; 0: not known) does the same for the trigger rate: its interval
    reaches at least one trigger of the window, ``1 / window`` Hz, either side (a held
    rate's residuals are all but zero, and a live stall moves one trigger across the
    window's end); ``f_trig`` (the nominal trigger rate) caps it: no method triggers
    faster than that.
    """
    xs = [v for v in values if math.isfinite(v)]
    if not xs:
        return Interval(math.nan, math.nan, math.nan, math.nan, res)
    m = statistics.fmean(xs)
    s = statistics.stdev(xs) if len(xs) > 1 else 0.0
    h = statistics.NormalDist().inv_cdf(0.5 + coverage / 2.0) * s
    r_lo, r_hi = (res.lo, res.hi) if res is not None else (0.0, 0.0)
    if metric in PP_METRICS:
        step = 1.0 / frames if frames > 0.0 else 0.0
        lo = min(1.0, max(0.0, min(m - h - r_hi / 100.0, m - step)))
        hi = min(1.0, max(0.0, max(m + h - r_lo / 100.0, m + step)))
    else:
        lo = max(0.0, m - h) / (1.0 + r_hi)
        hi = (m + h) / (1.0 + r_lo) if r_lo > -1.0 else math.inf
        if metric == RATE_METRIC:
            if window > 0.0:
                lo, hi = max(0.0, min(lo, m - 1.0 / window)), max(hi, m + 1.0 / window)
            hi = min(hi, max(f_trig, m))
    return Interval(m, s, lo, hi, res)


def residuals_toml(values: dict[tuple[str, str], list[float]], meta: dict[str, Any]) -> str:
    """A ``residuals.toml`` holding ``values`` per ``(metric, regime)`` and ``meta``
    (strings and numbers), as the validation suite writes it."""
    def lit(v: Any) -> str:
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        return repr(float(v)) if isinstance(v, float) else str(v)

    lines = ["[meta]"] + [f"{k} = {lit(v)}" for k, v in meta.items()]
    for (metric, reg), vals in sorted(values.items()):
        finite = [v for v in vals if math.isfinite(v)]
        if not finite:
            continue
        lines += ["", "[[residual]]", f'metric = "{metric}"', f'regime = "{reg}"',
                  "values = [" + ", ".join(f"{v:.6g}" for v in finite) + "]"]
    return "\n".join(lines) + "\n"


def pooled_residuals(paths: Sequence[str | Path]) -> str:
    """One ``residuals.toml`` holding the residuals of several validations (each
    ``(metric, regime)``'s values joined, in the order given): a user's own validations
    pooled, or pooled with the shipped file, for ``predict --residuals``.

    Why: one validation's residuals hold its cells' errors under one calibration; a
    calibration made another day moves the predictions by more than that. A pooled file
    may be pooled again: its ``validations`` count adds up, and so does the
    ``cross_pairs`` count of a file that holds cross-session residuals (the shipped
    one).

    Raises:
        ConfigError: (``residuals``) an unreadable file, an entry given as bounds only
            (``lo``/``hi``: nothing to pool), a ``validations`` count that is not an
            integer >= 1, or files built for different coverages.
    """
    values: dict[tuple[str, str], list[float]] = {}
    covs, sources = set(), []
    count = 0  # validations pooled: a pooled file counts its own
    pairs = 0  # ordered pairs of validations whose cross residuals are in the files
    for path in paths:
        data = _read(path)
        meta = dict(data.get("meta", {}))
        n = meta.get("validations", 1)
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise ConfigError("residuals", f"{path}: meta.validations must be an integer "
                              f">= 1, got {n!r}")
        count += n
        pairs += int(meta.get("cross_pairs", 0))
        covs.add(float(meta.get("coverage", COVERAGE)))
        sources.append(str(meta.get("source", path)))
        for entry in data.get("residual", []):
            key = (str(entry.get("metric", "")), str(entry.get("regime", "")))
            if "values" not in entry:
                raise ConfigError("residuals", f"{path}: {key[0]}/{key[1]} has bounds but "
                                  "no values to pool")
            values.setdefault(key, []).extend(float(v) for v in entry["values"])
    if len(covs) > 1:
        raise ConfigError("residuals", f"files built for different coverages: {sorted(covs)}")
    cov = covs.pop() if covs else COVERAGE
    kind = f"per-cell residuals of held-out cells, {count} validations"
    meta_out: dict[str, Any] = {"coverage": cov, "kind": kind, "validations": count}
    if pairs:
        meta_out["kind"] = f"{kind} and {pairs} cross-session pairs"
        meta_out["cross_pairs"] = pairs
    meta_out["source"] = "; ".join(dict.fromkeys(sources))
    return residuals_toml(values, meta_out)
