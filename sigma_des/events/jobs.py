"""The cost of a node's compute job: one computation for both engines.

A job steps a node from its newest computed frame to the requested ``target``:
one ``step_time`` draw per frame (keyed ``(STEP_DRAW, node, frame, 0)``), plus one
draw per re-simulated step after a time-warp rollback (keyed
``(ROLLBACK_DRAW, node, target, j)``) — independent per node, or tied within a host by
``compute.host_share`` (:func:`step_draws`) — scaled by every slow fault active at the
start (docs/concepts/model.md, "Physics nodes"). The per-message engine computes
:func:`job_cost`; the compiled core's loop sums the same draws in the same order
(:mod:`sigma_des.events.fast.job`), the rollback draws from a table of whole
``(ROLLBACK_DRAW, ·, target, j)`` vectors (:mod:`sigma_des.events.fast.rollbacks`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.core.rng import RandomStreams
from sigma_des.events.spec import ComputeSpec

__all__ = ["ROLLBACK_DRAW", "STEP_DRAW", "job_cost", "step_draws"]

#: Draw kinds of the compute stream: a frame's step, a rollback's re-simulated step.
STEP_DRAW = 0
ROLLBACK_DRAW = 1


#: Largest ``u`` a copula draw is clipped to: the largest float below 1 (``ndtr`` of a
#: normal beyond ~8.3 rounds to 1.0, whose quantile would be infinite).
_U_MAX = float(np.nextafter(1.0, 0.0))
#: Smallest ``u`` (a uniform of the streams is never below this).
_U_MIN = 2.0**-54


def step_draws(compute: ComputeSpec, streams: RandomStreams,
               host_of: Sequence[int]) -> DrawCache:
    """The step-time draws of every node (both engines, live too).

    With ``compute.host_share`` ρ = 0 each draw is ``step_time`` sampled from the
    ``compute`` stream at ``(kind, node, index, attempt)``, independently per node. With
    ρ > 0 a Gaussian copula ties the nodes of one host: ``z = √ρ·z_host + √(1−ρ)·z_node``
    with ``z_host`` the standard normal of stream ``compute.host`` at ``(kind, host,
    index, attempt)`` (one per host and frame; per host, rollback target and step for
    the re-simulated steps) and ``z_node`` that of stream ``compute`` at ``(kind, node,
    index, attempt)``; the draw is ``step_time``'s quantile at ``Φ(z)``. Each draw keeps
    the ``step_time`` distribution; two nodes of one host have normal scores correlated
    ρ, nodes of different hosts none.

    Args:
        compute: the scenario's ``compute`` section.
        streams: the run's root-seed streams.
        host_of: host of every node (all of the run's, whatever part a live host serves).
    """
    step = compute.step_time
    stream = streams.stream("compute")
    n = len(host_of)
    constant = step.value if step.dist == "constant" else None
    rho = compute.host_share
    if rho == 0.0:  # today's draws, bit for bit
        return DrawCache(n, lambda s, k, i, a: step.sample(stream, k, s, i, a), constant=constant,
                         blockable=True, uniforms=(stream.key, step.quantile))
    from scipy.special import ndtr

    hosts_of = np.asarray(host_of, dtype=np.int64)
    hosts = np.arange(int(hosts_of.max()) + 1, dtype=np.int64)
    host_stream = streams.stream("compute.host")
    a_host, a_node = math.sqrt(rho), math.sqrt(1.0 - rho)

    def sampler(s: NDArray[np.int64], k: int, i: int, a: int) -> NDArray[np.float64]:
        z_host = host_stream.normal(k, hosts, i, a)[hosts_of[s]]
        z = a_host * z_host + a_node * stream.normal(k, s, i, a)
        return step.quantile(np.clip(ndtr(z), _U_MIN, _U_MAX))

    return DrawCache(n, sampler, constant=constant)


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
