"""One planned case of the engine benchmark (:func:`~sigma_lab.studies.engine_bench.plan`).

Its own module so that the benchmark (:mod:`~sigma_lab.studies.engine_bench`) and the
normalised figures (:mod:`~sigma_lab.studies.engine_norm`, whose targets are per case)
both import it without importing each other.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["Case"]


class Case(NamedTuple):
    """One planned run.

    Attributes:
        impl: ``cohort``, ``events`` or ``baseline``.
        method: alignment method.
        scenario: ``full`` or ``restricted``.
        sim_s: simulated seconds.
        role: ``main`` (a timed case of the tables) or ``twin`` (a cohort run at
            the capped duration of an ``events`` or ``baseline`` case, so that
            metrics are compared between runs of equal duration) or ``reference``
            (a baseline run only to normalise the figures: ``engine_norm``).
    """

    impl: str
    method: str
    scenario: str
    sim_s: float
    role: str = "main"
