"""The cost of a node's compute job: one computation for both engines.

A job steps a node from its newest computed frame to the requested ``target``:
one ``step_time`` draw per frame (keyed ``(STEP_DRAW, node, frame, 0)``), plus one
draw per re-simulated step after a time-warp rollback (keyed
``(ROLLBACK_DRAW, node, target, j)``), scaled by every slow fault active at the
start (docs/MODEL.md, "Physics nodes"). The per-message engine and the compiled
core's driver both call :func:`job_cost`; the compiled loop sums the same draws in
the same order for jobs with no rollback steps.
"""

from __future__ import annotations

from collections.abc import Iterable

from sigma_des.core.draws import DrawCache

__all__ = ["ROLLBACK_DRAW", "STEP_DRAW", "job_cost"]

#: Draw kinds of the compute stream: a frame's step, a rollback's re-simulated step.
STEP_DRAW = 0
ROLLBACK_DRAW = 1


def job_cost(
    step_time: DrawCache,
    slow: Iterable[tuple[float, float, float]],
    node: int,
    first: int,
    target: int,
    resim: int,
    now: float,
) -> float:
    """Seconds of compute for ``node`` to step frames ``first..target`` at ``now``.

    Args:
        step_time: the compute stream's draws.
        slow: the node's slow-fault windows ``(start, end, factor)``.
        node: the node.
        first: the first frame to step.
        target: the last frame to step.
        resim: re-simulated steps owed to rollbacks (0: none).
        now: the job's start time (slow faults active then apply).

    Returns:
        The job's cost.
    """
    cost = 0.0
    for f in range(first, target + 1):
        cost += step_time.get(STEP_DRAW, node, f, 0)
    for j in range(resim):
        cost += step_time.get(ROLLBACK_DRAW, node, target, j)
    for a, b, factor in slow:
        if a <= now < b:
            cost *= factor
    return cost
