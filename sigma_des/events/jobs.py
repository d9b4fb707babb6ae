"""The cost of a node's compute job: one computation for both engines.

A job steps a node from its newest computed frame to the requested ``target``:
one ``step_time`` draw per frame (keyed ``(STEP_DRAW, node, frame, 0)``), plus one
draw per re-simulated step after a time-warp rollback (keyed
``(ROLLBACK_DRAW, node, target, j)``), scaled by every slow fault active at the
start (docs/MODEL.md, "Physics nodes"). The per-message engine and the compiled
core's driver both compute :func:`job_cost` (the driver through :class:`JobCosts`,
the same sum with a target's rollback draws fetched as one block); the compiled
loop sums the same draws in the same order for jobs with no rollback steps.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.core.rng import Stream
from sigma_des.net.latency import Dist

__all__ = ["ROLLBACK_DRAW", "STEP_DRAW", "JobCosts", "job_cost", "step_draws"]

#: Draw kinds of the compute stream: a frame's step, a rollback's re-simulated step.
STEP_DRAW = 0
ROLLBACK_DRAW = 1


def step_draws(step: Dist, stream: Stream, n: int) -> DrawCache:
    """The step-time draws of ``n`` nodes from the compute stream (both engines, live too).

    Args:
        step: the ``compute.step_time`` distribution.
        stream: the ``compute`` stream of the run's root seed.
        n: number of nodes (all of the run's, whatever part a live host serves).
    """
    return DrawCache(
        n,
        lambda s, k, i, a: step.sample(stream, k, s, i, a),
        constant=step.value if step.dist == "constant" else None,
    )


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
    resim_draws = (step_time.get(ROLLBACK_DRAW, node, target, j) for j in range(resim))
    return _summed(step_time, slow, node, first, target, resim_draws, now)


def _summed(
    step_time: DrawCache,
    slow: Iterable[tuple[float, float, float]],
    node: int,
    first: int,
    target: int,
    resim_draws: Iterable[float],
    now: float,
) -> float:
    """The job cost's sum, in its one order: the step draws of ``first..target``, then
    the rollback draws, then every slow factor active at ``now``."""
    cost = 0.0
    for f in range(first, target + 1):
        cost += step_time.get(STEP_DRAW, node, f, 0)
    for v in resim_draws:
        cost += v
    for a, b, factor in slow:
        if a <= now < b:
            cost *= factor
    return cost


class JobCosts:
    """:func:`job_cost`, with the rollback draws of a target kept as one block.

    After a time-warp command many nodes roll back at once and their jobs share a
    target, so the draws ``(ROLLBACK_DRAW, ·, target, j)`` for ``j < J`` are kept as
    a ``(J, n)`` block per target (grown on demand; counter-based draws, so the
    values are the cache's) and a job reads its column instead of making ``resim``
    cache look-ups. The cost is the same sum in the same order: the same float.

    Args:
        step_time: the compute stream's draws.
        targets: blocks kept (least recently made evicted).
    """

    def __init__(self, step_time: DrawCache, targets: int = 8) -> None:
        self.step_time = step_time
        self.targets = targets
        self._blocks: OrderedDict[int, NDArray[np.float64]] = OrderedDict()

    def rollback_draws(self, node: int, target: int, resim: int) -> list[float]:
        """The draws ``(ROLLBACK_DRAW, node, target, j)``, ``j = 0 .. resim-1``."""
        block = self._blocks.get(target)
        if block is None or block.shape[0] < resim:
            have = 0 if block is None else block.shape[0]
            rows = max(resim, 2 * have)
            new = np.stack([self.step_time.vector(ROLLBACK_DRAW, target, j)
                            for j in range(have, rows)])
            block = new if block is None else np.concatenate([block, new])
            self._blocks[target] = block
            if len(self._blocks) > self.targets:
                self._blocks.popitem(last=False)
        return block[:resim, node].tolist()  # type: ignore[no-any-return]

    def cost(
        self,
        slow: Iterable[tuple[float, float, float]],
        node: int,
        first: int,
        target: int,
        resim: int,
        now: float,
    ) -> float:
        """:func:`job_cost` ``(step_time, slow, node, first, target, resim, now)``, exactly."""
        st = self.step_time
        if st.constant is not None or resim == 0:
            return job_cost(st, slow, node, first, target, resim, now)
        return _summed(st, slow, node, first, target, self.rollback_draws(node, target, resim),
                       now)
