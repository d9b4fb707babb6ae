"""Plug-in protocols of the simulation: dynamics models, behaviours and the swarm view.

They live on the ground floor so that the engine (``sigma_des.events``) steps
physics and asks for commands through them without knowing any aircraft; the
agents layer (``sigma_des.agents``) implements them.

The engine steps physics through :class:`DynamicsModel`, a *pure, vectorised*
interface: the whole swarm's state is one ``(n, state_dim)`` float array, a step
returns a new array and never mutates its input, and rows are independent (row
``i`` of a batched step equals a step of row ``i`` alone, bit for bit). That
makes checkpoints plain array copies and time-warp rollback a re-run of ``step``.

Commands are opaque ``(n, command_dim)`` float arrays whose meaning the dynamics
model (its autopilot) and the behaviours agree on; the engine only stores and
delivers them. Layers import downwards: this module imports nothing of sigma_des.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["OBS_FIELDS", "DynamicsModel", "Behaviour", "SwarmView"]

#: Columns of the published state (docs/concepts/aircraft.md): body velocities, Euler angles,
#: body rates, north/east position and altitude (up), all SI units and radians.
OBS_FIELDS: tuple[str, ...] = ("u", "v", "w", "phi", "theta", "psi", "p", "q", "r", "x", "y", "h")


@runtime_checkable
class DynamicsModel(Protocol):
    """A vectorised aircraft (or point-mass) model with its autopilot inside."""

    name: str
    state_dim: int
    command_dim: int

    def initial_state(self, n: int) -> NDArray[np.float64]:
        """Initial ``(n, state_dim)`` state of a swarm of ``n`` aircraft."""
        ...

    def default_command(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The command each aircraft follows before any behaviour command arrives."""
        ...

    def step(
        self,
        state: NDArray[np.float64],
        command: NDArray[np.float64],
        dt: float,
        frame: int,
        nodes: NDArray[np.int64],
    ) -> NDArray[np.float64]:
        """Advance ``state`` by ``dt`` seconds to frame ``frame``.

        ``nodes`` are the global node ids of the rows (for counter-based noise
        keyed by node and frame). Returns a new array; rows are independent.
        """
        ...

    def observe(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The published ``(n, 12)`` state, columns :data:`OBS_FIELDS`."""
        ...


@dataclass(frozen=True)
class SwarmView:
    """What a behaviour sees: the swarm snapshot delivered by an alignment method.

    Attributes:
        obs: ``(n, 12)`` published states (columns :data:`OBS_FIELDS`); rows of
            nodes never seen are NaN.
        frame: ``(n,)`` frame index of each shown state (-1 if none).
        valid: ``(n,)`` True where a state is shown.
        aligned_frame: the frame the method calls "now" (-1 before any).
    """

    obs: NDArray[np.float64]
    frame: NDArray[np.int64]
    valid: NDArray[np.bool_]
    aligned_frame: int


class Behaviour(Protocol):
    """Turns an aligned swarm view into one command row per node."""

    name: str

    def commands(self, view: SwarmView, dynamics: DynamicsModel) -> NDArray[np.float64]:
        """``(n, dynamics.command_dim)`` commands; NaN rows mean "no new command"."""
        ...
