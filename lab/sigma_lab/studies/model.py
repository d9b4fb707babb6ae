"""What a paper study ran: method labels, one record per run, the study as a whole.

A *method label* is usually an alignment method name; a label may also be a
method run with scenario overrides (e.g. ``lockstep_evict`` = ``lockstep`` with
``lockstep.eviction_timeout`` set), see :class:`MethodSpec`.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sigma_des.api import Results
from sigma_des.config import Scenario

__all__ = ["MethodSpec", "RunRecord", "Study"]


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
