"""The newest state per node of a batch of deliveries, taken in one compiled pass.

:func:`take_rows` is the rule of :func:`sigma_des.events.align.base.newest_rows` written
as the loop that defines it: going through the rows in arrival order, a row replaces its
node's entry when its frame is greater than the entry's. What remains per node is the
first row of the node's highest frame in the batch, if that frame beats the entry it
had; the values are copied, never computed, so they are the batch's bits.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["take_rows"]


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def take_rows(frame: np.ndarray, gen: np.ndarray, obs: np.ndarray, nodes: np.ndarray,
              frames: np.ndarray, gens: np.ndarray, rows: np.ndarray,
              changed: np.ndarray) -> None:
    """Rows ``j`` in order: ``frame``, ``gen``, ``obs`` of node ``nodes[j]`` take row
    ``j`` (``frames[j]``, ``gens[j]``, ``rows[j]``) if ``frames[j]`` beats its frame;
    ``changed[node]`` is set for every node that took a row."""
    for j in range(nodes.shape[0]):
        node = nodes[j]
        if frames[j] > frame[node]:
            frame[node] = frames[j]
            gen[node] = gens[j]
            for c in range(obs.shape[1]):
                obs[node, c] = rows[j, c]
            changed[node] = True
