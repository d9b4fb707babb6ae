"""Which message core a run uses: the engine choice and its fallback.

``sc.engine = "events"`` runs every message as a SimPy event (the executable
specification, :mod:`sigma_des.events.engine`); ``"cohort"`` composes the
compiled message core (:mod:`sigma_des.events.fast.driver`) into the same
engine. Features whose per-message behaviour the core does not reproduce are
listed by :func:`~sigma_des.events.fast.support.unsupported`; for them the run
falls back to the per-message engine for the whole run and says why
(docs/concepts/engines.md).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sigma_des.core.models import Behaviour, DynamicsModel
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast.spare import Spare
from sigma_des.events.fast.support import CohortFallback, unsupported
from sigma_des.events.spec import RunSpec
from sigma_des.events.tap import Tap

__all__ = ["execute", "make_run"]


def make_run(
    sc: RunSpec, method: str, dynamics: DynamicsModel, behaviour: Behaviour | None,
    metrics: bool = True, spare: Spare | None = None,
) -> tuple[MethodRun, str]:
    """The run object for ``sc.engine`` and the fallback reason ("" if none);
    ``metrics=False``: a run that collects no measurements; ``spare``: what a retired compiled
    core handed back, for the compiled core to refill (both ``MethodRun``'s)."""
    if sc.engine == "cohort":
        why = unsupported(sc, method)
        if why is None:
            return MethodRun(sc, method, dynamics, behaviour, compiled=True,
                             metrics=metrics, spare=spare), ""
        return MethodRun(sc, method, dynamics, behaviour, metrics=metrics), why
    return MethodRun(sc, method, dynamics, behaviour, metrics=metrics), ""


def execute(
    sc: RunSpec,
    method: str,
    dynamics: Callable[[], DynamicsModel],
    behaviour: Callable[[], Behaviour | None],
    progress: Callable[[float], None] | None = None,
    tap: Callable[[], Tap] | None = None,
) -> tuple[MethodRun, dict[str, Any], dict[str, str]]:
    """Run ``method`` on the engine ``sc.engine`` asks for, falling back when needed.

    Args:
        sc: the run spec (``Scenario.run_spec()``).
        method: alignment method.
        dynamics: makes the dynamics model (called again for a mid-run fallback).
        behaviour: makes a fresh behaviour (behaviours may keep state).
        progress: called with the simulated time after every simulated second.
        tap: makes a fresh recording tap for each attempt (a mid-run fallback starts
            the recording again); the tap is closed when its attempt ends.

    Returns:
        The finished run, its result dict and ``{"requested", "used", "fallback"}``.
    """
    run, why = make_run(sc, method, dynamics(), behaviour())
    try:
        out = _attempt(run, progress, tap)
    except CohortFallback as exc:  # met mid-run: redo the whole run per message
        why = str(exc) or "CohortFallback"
        run = MethodRun(sc, method, dynamics(), behaviour())
        out = _attempt(run, progress, tap)
    used = "events" if why or sc.engine == "events" else "cohort"
    return run, out, {"requested": sc.engine, "used": used, "fallback": why}


def _attempt(
    run: MethodRun, progress: Callable[[float], None] | None, tap: Callable[[], Tap] | None
) -> dict[str, Any]:
    """One run attempt, recorded through a fresh tap when ``tap`` is given."""
    if tap is not None:
        run.record(tap())
    try:
        return run.run(progress)
    finally:
        run.tap.close()
