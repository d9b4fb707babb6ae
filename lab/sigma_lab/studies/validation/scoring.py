"""How a prediction is scored: errors, the live noise floor, the bands, the knee, the targets.

Pure functions of numbers (no runs, no files), so each rule is tested by hand:

* **error** (:func:`error`): relative, ``(DES - live) / live``; for the missed-frame
  fraction the difference in **percentage points** (live often misses none).
* **noise floor** (:func:`noise_floor`): the spread of live against itself, from the
  repeats of the calibration setting: ``(max - min) / mean`` (percentage points
  ``max - min`` for the missed-frame fraction), per method and metric.
* **verdict** of one cell and metric (:func:`judge`): mean AoI and mean state
  latency within 15 %, or — where live does not reproduce itself within 10 % (noise
  floor > 10 %) — the DES inside the range of the cell's **own** live runs, ``min <=
  DES <= max`` of at least two (a held-out cell run more than once, the live value
  being their mean; the calibration setting's repeats). A cell that ran once is
  judged by the band alone: a floor borrowed from the calibration setting is no
  licence. The headline share is the strict one (``within_band``: inside the band of
  the mean of the cell's runs); p99 AoI within 15 %; the achieved trigger rate
  within 5 % wherever live holds its rate
  (``>= 95 %`` of the nominal ``f_trig``; elsewhere not scored); the missed-frame
  fraction within 10 percentage points. A live value without a DES one (no state
  reached the DES's server in the window) is a miss.
* **the calibration's primary run** (:func:`~sigma_des.calibrate.primary.central`, as
  ``calibrate`` picks it): of the calibration setting's repeats, the most typical one,
  whose mean AoI and mean state latency (every method) lie closest to the repeats'
  medians: one slow outlier run does not set the step time and the scenario's keys; the
  per-message CPU is the repeats' mean.
* **knee** (:func:`knee_of`): on a grid of N, ``sigma-des capacity``'s predicate
  (:func:`~sigma_des.calibrate.capacity.holds`: rate held, at most 5 % of frames
  missed): the first N that does not hold (the knee) and the one before it;
  :func:`knee_verdict` compares the DES's knee with live's (within ±25 %).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from sigma_des.calibrate.intervals import RATE_HELD
from sigma_des.calibrate.primary import CENTRAL_METRICS, central

__all__ = ["BAND", "CENTRAL_METRICS", "KNEE_MISSED", "KNEE_TOL", "METRICS", "NOISY", "PP_BAND",
           "RATE_BAND", "RATE_HELD", "TARGETS", "Verdict", "central", "error", "judge", "knee",
           "knee_of", "knee_verdict", "live_repeats", "noise_floor", "share"]

#: Metrics compared, in table order.
METRICS = ("aoi_mean", "aoi_p99", "latency_state_mean", "trigger_rate_hz", "missed_frac")
#: The relative band of the AoI and latency metrics.
BAND = 0.15
#: The trigger rate's band, where live holds its rate.
RATE_BAND = 0.05
#: The missed-frame fraction's band, percentage points.
PP_BAND = 10.0
#: A live noise floor above this marks a cell where live does not reproduce itself.
NOISY = 0.10
#: The knee: the smallest N missing more than this share of frames.
KNEE_MISSED = 0.05
#: The knee target's tolerance (relative to the live knee).
KNEE_TOL = 0.25
#: The issue's share targets: metric -> least share of held-out cells passing.
TARGETS = {"aoi_mean": 0.80, "latency_state_mean": 0.80, "aoi_p99": 0.80,
           "trigger_rate_hz": 1.0, "missed_frac": 1.0}
#: Metrics whose noisy cells may pass inside the live range (the issue's rule).
_RANGE_RULE = ("aoi_mean", "latency_state_mean")


def _finite(*xs: float) -> bool:
    return all(isinstance(x, int | float) and math.isfinite(x) for x in xs)


def error(metric: str, live: float, des: float) -> float:
    """``(des - live) / live``; for ``missed_frac`` ``100 * (des - live)`` (pp).

    Returns:
        NaN when either value is not finite or (relative) live is 0.
    """
    if not _finite(live, des):
        return math.nan
    if metric == "missed_frac":
        return 100.0 * (des - live)
    return (des - live) / live if live != 0 else math.nan


def noise_floor(metric: str, repeats: Iterable[float]) -> float:
    """Spread of live against itself: ``(max - min) / mean`` of the repeats (pp for
    ``missed_frac``). NaN with fewer than two finite repeats or a zero mean."""
    xs = [x for x in repeats if _finite(x)]
    if len(xs) < 2:
        return math.nan
    if metric == "missed_frac":
        return 100.0 * (max(xs) - min(xs))
    mean = sum(xs) / len(xs)
    return (max(xs) - min(xs)) / mean if mean != 0 else math.nan


@dataclass(frozen=True)
class Verdict:
    """One cell's and metric's score.

    Attributes:
        scored: counted towards the target (False: no finite error, or a trigger rate
            live did not hold).
        ok: passed (False when not scored).
        within_band: inside the plain band (15 %, 5 %, 10 pp), whatever the noise.
        rule: how it was decided: ``band``, ``live range`` (a noisy cell), ``rate not
            held``, ``no DES value`` (live has one, the DES none: a miss) or ``n/a``
            (no live value, or a relative error of a zero live value).
    """

    scored: bool
    ok: bool
    within_band: bool
    rule: str


def live_repeats(row: dict[str, Any]) -> list[float]:
    """A ``cells.csv`` row's live runs, as numbers (the row keeps them space-joined in
    ``live_runs``)."""
    return [float(x) for x in str(row["live_runs"]).split()]


def judge(metric: str, live: float, des: float, floor: float = math.nan,
          f_trig: float = 100.0, repeats: Sequence[float] = ()) -> Verdict:
    """Score one cell's ``metric`` (see the module doc).

    Args:
        metric: one of :data:`METRICS`.
        live: the live value.
        des: the DES's prediction.
        floor: the live noise floor of this method and metric (:func:`noise_floor`).
        f_trig: the nominal trigger rate (Hz), for ``trigger_rate_hz``.
        repeats: the live runs of this cell (its copies, or the calibration setting's
            repeats); with two or more, a noisy cell passes inside their range (with
            fewer, only the band counts).
    """
    e = error(metric, live, des)
    if _finite(live) and not _finite(des):  # e.g. no state reached the DES's server
        return Verdict(True, False, False, "no DES value")
    if not math.isfinite(e):
        return Verdict(False, False, False, "n/a")
    if metric == "trigger_rate_hz":
        if live < RATE_HELD * f_trig:
            return Verdict(False, False, abs(e) <= RATE_BAND, "rate not held")
        ok = abs(e) <= RATE_BAND
        return Verdict(True, ok, ok, "band")
    if metric == "missed_frac":
        ok = abs(e) <= PP_BAND
        return Verdict(True, ok, ok, "band")
    inside = abs(e) <= BAND
    if inside or metric not in _RANGE_RULE or not (_finite(floor) and floor > NOISY):
        return Verdict(True, inside, inside, "band")
    xs = [x for x in repeats if _finite(x)]
    if len(xs) < 2:  # no runs of its own to range over: the band alone
        return Verdict(True, False, False, "band")
    return Verdict(True, min(xs) <= des <= max(xs), False, "live range")


def share(verdicts: Iterable[Verdict]) -> tuple[int, int, int]:
    """``(scored, passed, within the plain band)`` counts of scored verdicts."""
    vs = [v for v in verdicts if v.scored]
    return len(vs), sum(v.ok for v in vs), sum(v.within_band for v in vs)


def knee(nodes: Sequence[int], missed: Sequence[float], threshold: float = KNEE_MISSED
         ) -> int | None:
    """The smallest N whose missed-frame fraction exceeds ``threshold``.

    Args:
        nodes: the N of each run.
        missed: their missed-frame fractions (NaN: that run failed; skipped).
        threshold: the knee's missed-frame share.

    Returns:
        The knee, or None if no run exceeds the threshold.
    """
    for n, m in sorted(zip(nodes, missed, strict=True)):
        if _finite(m) and m > threshold:
            return int(n)
    return None


def knee_of(nodes: Sequence[int], figures: Sequence[dict[str, float]], f_trig: float,
            max_missed: float = KNEE_MISSED) -> tuple[int | None, int | None]:
    """``(capacity, knee)`` on the grid ``nodes`` by ``sigma-des capacity``'s predicate
    (see the module doc): the knee the first N that does not hold, the capacity the
    N before it. Every grid point is known here, so the grid is scanned in order (the
    bisection of :func:`~sigma_des.calibrate.capacity.search` assumes a monotone
    predicate; a live grid need not be). ``figures[i]`` has ``trigger_rate_hz`` and
    ``missed_frac`` of ``nodes[i]``."""
    from sigma_des.calibrate.capacity import holds

    cap = None
    for n, f in sorted(zip(nodes, figures, strict=True), key=lambda p: p[0]):
        if not holds(float(f.get("trigger_rate_hz", math.nan)),
                     float(f.get("missed_frac", math.nan)), math.nan, f_trig, max_missed,
                     None):
            return cap, int(n)
        cap = int(n)
    return cap, None


def knee_verdict(live: int | None, des: int | None, grid_max: int, tol: float = KNEE_TOL
                 ) -> str:
    """``met`` or ``missed``: is the DES's knee within ``tol`` of live's?

    A live knee beyond the live grid (None: live kept up to ``grid_max``) is met by
    a DES knee beyond it too (None or above ``grid_max``), and missed by one inside.
    """
    if live is None:
        return "met" if des is None or des > grid_max else "missed"
    if des is None:
        return "missed"
    return "met" if abs(des - live) <= tol * live else "missed"
