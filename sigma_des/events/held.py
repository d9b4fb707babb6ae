"""Which command row each node's stepped trajectory has held, and since which frame.

A time-warp rollback of node ``i`` to frame ``c`` re-simulates frames ``c`` … latest
from the checkpoint of frame ``c − 1`` with one command row (:mod:`sigma_des.events.truth`).
The step of a frame is a pure function of the row's state, its command row, the frame's
``dt``, the frame and the node (the models with batched steps: a row's bits do not depend
on the batch). So if frames ``c`` … latest were all stepped with that very row, bit for
bit, from the same checkpoint, the re-simulation would write back exactly the rows the
ring holds, and the truth skips it: the rollback still counts, and still owes its
compute steps (that is the node's CPU, not the simulator's). A swarm far behind its
triggers (BiDES at N = 10 000) re-sends the same command rows stamped with old frames,
and most of its rollbacks are such.

:class:`HeldCommands` keeps, per node, the row its trajectory holds (``row``) and the
first frame of the run of frames stepped with it (``since``), updated where the truth
steps: every frame (:meth:`HeldCommands.stepped`) and every re-simulation
(:meth:`HeldCommands.resimulated`). Rows are compared by their bits (``-0.0`` and
``0.0``, or two NaNs of different payloads, count as different: never a wrong skip).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["NEVER", "HeldCommands"]

#: ``since`` of a node not stepped yet (no rollback is ever redundant then).
NEVER = np.iinfo(np.int64).max


def _bits(rows: NDArray[np.float64]) -> NDArray[np.int64]:
    """The rows' float64 bit patterns (for exact comparison)."""
    return np.ascontiguousarray(rows, dtype=np.float64).view(np.int64)


class HeldCommands:
    """The command row each node's trajectory holds, and since which frame.

    Args:
        n: number of nodes (rows).
        width: columns of a command row.

    Attributes:
        row: ``(n, width)`` the row of each node's latest stepped frames.
        since: ``(n,)`` the first frame of the run of frames, up to the latest, stepped
            with ``row`` (:data:`NEVER` before the first step).
    """

    def __init__(self, n: int, width: int) -> None:
        self.row = np.zeros((n, width))
        self.since = np.full(n, NEVER, dtype=np.int64)

    def stepped(self, k: int, cmd: NDArray[np.float64]) -> None:
        """Frame ``k`` was stepped with the command rows ``cmd`` (``(n, width)``)."""
        cmd = np.ascontiguousarray(cmd, dtype=np.float64)
        if cmd.shape != self.row.shape:
            raise ValueError(f"stepped: command rows of shape {self.row.shape} expected, "
                             f"got {cmd.shape}")
        _stepped_rows(int(k), _bits(cmd), self.row.view(np.int64), self.since)

    def redundant(
        self, nodes: NDArray[np.int64], first: NDArray[np.int64], rows: NDArray[np.float64]
    ) -> NDArray[np.bool_]:
        """Per rollback ``(nodes[j], first[j], rows[j])``: True if frames ``first[j]`` …
        latest of that node were all stepped with ``rows[j]`` (its re-simulation would
        change no bit)."""
        same = (_bits(rows) == _bits(self.row[nodes])).all(axis=1)
        return same & (self.since[nodes] <= first)

    def resimulated(
        self, nodes: NDArray[np.int64], first: NDArray[np.int64], rows: NDArray[np.float64]
    ) -> None:
        """Node ``nodes[j]`` was re-simulated from frame ``first[j]`` to the latest with
        ``rows[j]`` (one rollback per node)."""
        self.row[nodes] = rows
        self.since[nodes] = first


@njit(cache=True)
def _stepped_rows(k: int, cmd: np.ndarray, row: np.ndarray, since: np.ndarray) -> None:
    """:meth:`HeldCommands.stepped` over the rows' bit patterns (compiled): a row whose
    bits differ from the held ones, or a node never stepped, takes the new row and
    ``since = k``; the others are left as they are."""
    for i in range(cmd.shape[0]):
        changed = since[i] == NEVER
        if not changed:
            for c in range(cmd.shape[1]):
                if cmd[i, c] != row[i, c]:
                    changed = True
                    break
        if changed:
            for c in range(cmd.shape[1]):
                row[i, c] = cmd[i, c]
            since[i] = k
