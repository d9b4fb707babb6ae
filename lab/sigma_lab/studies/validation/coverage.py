"""The prediction intervals' coverage on the held-out cells, and the residuals file.

``sigma-des predict`` states each figure with an interval built from the residuals of
the last validation (:mod:`sigma_des.calibrate.intervals`). The suite measures how
often such intervals hold live's value, on its own held-out cells, without letting a
cell's residual into its own interval (leave one out):

* each held-out row with a residual (:func:`residual_rows`: a cell, method and metric
  of ``cells.csv`` the suite scored, or a trigger rate live did not hold) has a regime,
  :func:`~sigma_des.calibrate.intervals.regime` of its DES figures (the same rule as
  ``predict``, with :func:`~sigma_des.calibrate.intervals.rate_regime` for the trigger
  rate), and a residual: ``rel_error`` (percentage points for missed frames);
* its interval is the DES value (one seed) widened by the bounds of the **other**
  rows' residuals of that metric and regime (those of every regime when fewer than
  :data:`MIN_OTHERS` other rows share it), a missed-frame interval by at least one
  frame of the cell's window and a trigger rate's by one trigger, as ``predict``
  builds it;
* covered when ``lo <= live <= hi``; per metric the share covered and the median
  width (relative to live; pp for missed frames).

:func:`residual_values` gives every scored held-out residual by metric and regime
(and pooled as ``any``), which the suite writes as ``residuals.toml``: the file
``predict`` reads once it is copied into the package.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence
from typing import Any

from sigma_des.calibrate.intervals import (
    COVERAGE,
    PP_METRICS,
    RATE_METRIC,
    Residual,
    interval,
    residual_bounds,
)

__all__ = ["MIN_OTHERS", "TARGET", "coverage_rows", "residual_rows", "residual_values"]

#: Fewest other rows of a regime whose residuals make an interval (else every regime's).
MIN_OTHERS = 4
#: The share of held-out live values the intervals must hold (they are built for
#: :data:`~sigma_des.calibrate.intervals.COVERAGE`).
TARGET = 0.80


def residual_rows(rows: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The held-out rows with a finite residual and live value that the suite scored,
    and its trigger-rate rows left unscored because live did not hold its rate: a
    prediction of a rate the alignment sets needs those residuals (in the regime their
    ``cells.csv`` row gives)."""
    return [r for r in rows if r["held_out"]
            and (r["passed"] != "" or (r["metric"] == RATE_METRIC
                                       and r["rule"] == "rate not held"))
            and math.isfinite(float(r["rel_error"])) and math.isfinite(float(r["live"]))]


def residual_values(rows: Sequence[dict[str, Any]]) -> dict[tuple[str, str], list[float]]:
    """Scored held-out residuals per ``(metric, regime)`` and per ``(metric, "any")``."""
    out: dict[tuple[str, str], list[float]] = {}
    for r in residual_rows(rows):
        e = float(r["rel_error"])
        out.setdefault((r["metric"], r["regime"]), []).append(e)
        out.setdefault((r["metric"], "any"), []).append(e)
    return out


def coverage_rows(rows: Sequence[dict[str, Any]], metrics: Sequence[str],
                  coverage: float = COVERAGE, frames: float = 0.0, window: float = 0.0,
                  f_trig: float = math.inf) -> list[dict[str, Any]]:
    """Per metric: rows scored, covered, the share and the median width (see the
    module doc); ``frames``, the cells' frames per metrics window, and ``window``, that
    window (s), set the missed-frame and trigger-rate intervals' least reach, and
    ``f_trig`` caps the trigger rate's, as ``predict`` sets them."""
    scored = residual_rows(rows)
    out = []
    for k in metrics:
        sel = [r for r in scored if r["metric"] == k]
        hits, widths = 0, []
        for i, r in enumerate(sel):
            same = [float(o["rel_error"]) for j, o in enumerate(sel)
                    if j != i and o["regime"] == r["regime"]]
            others = same if len(same) >= MIN_OTHERS else [
                float(o["rel_error"]) for j, o in enumerate(sel) if j != i]
            if not others:
                continue
            lo, hi, enough = residual_bounds(others, coverage)
            iv = interval(k, [float(r["des"])], Residual(k, r["regime"], lo, hi, len(others),
                                                         enough, "leave one out"), coverage,
                          frames=frames, window=window, f_trig=f_trig)
            live = float(r["live"])
            hits += iv.lo <= live <= iv.hi
            widths.append(100.0 * (iv.hi - iv.lo) if k in PP_METRICS
                          else (iv.hi - iv.lo) / live if live else math.nan)
        n = len(widths)
        ok = [w for w in widths if math.isfinite(w)]
        out.append({"metric": k, "cells": n, "covered": hits,
                    "share": hits / n if n else math.nan,
                    "median_width": statistics.median(ok) if ok else math.nan,
                    "width_unit": "pp" if k in PP_METRICS else "rel", "built_for": coverage,
                    "target": TARGET})
    return out
