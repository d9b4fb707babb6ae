"""The message core: what carries a run's messages, behind one small interface.

:class:`~sigma_des.events.engine.MethodRun` keeps the frame-level and control
events (trigger issue, alignment and render ticks) and hands every message to a
:class:`MessageCore` (docs/concepts/engines.md):

* :class:`EventCore` (``engine = "events"``): every message is a SimPy event on
  the run's :class:`~sigma_des.net.network.Network` — the executable
  specification;
* :class:`~sigma_des.events.fast.driver.CompiledCore` (``engine = "cohort"``):
  the messages run in a compiled loop outside SimPy, with identical results.

The engine's run loop asks the core to bring its messages up to the next control
event (:meth:`MessageCore.advance_to`: messages come first at equal times) and,
at the end, to hand its counters to the components that report them
(:meth:`MessageCore.write_back`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.net.kinds import COMMAND, REREQUEST, TRIGGER, rerequest_index
from sigma_des.net.network import Network

__all__ = ["EventCore", "MessageCore"]


class MessageCore(Protocol):
    """What the engine asks of the part that carries its messages."""

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """The server publishes trigger ``k`` to every node, now."""
        ...

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """The server publishes ``cmds[i]`` (stamped ``stamp``) to each node ``i`` of
        ``nodes``, in order, now."""
        ...

    def publish_rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: the server re-requests ``node``'s state of ``frame``, now."""
        ...

    def server_tick(self, t: float) -> None:
        """An alignment tick at ``t`` spends the server process's CPU (a
        ``deployment.server_tick`` burst; nothing without a CPU stage)."""
        ...

    def server_free(self, t: float) -> float:
        """When the server process's loop thread has served the bursts queued on it by
        ``t`` (every message at or before ``t`` run): ``t`` if it is idle or there is no
        CPU stage."""
        ...

    def advance_to(self, bound: float, strict: bool) -> bool:
        """Run the messages the core holds up to ``bound`` (``< bound`` if ``strict``).

        Returns:
            True if it stopped early because a Lock-Step barrier completed (the next
            trigger may now come before ``bound``).
        """
        ...

    def write_back(self) -> None:
        """The run ended: hand the core's counters to the components that report them."""
        ...

    def close(self) -> None:
        """The run is over (after :meth:`write_back`): let go of the messages still in
        flight, which no result reads; the core carries no more messages."""
        ...


class EventCore:
    """Every message a SimPy event on the run's network (the specification).

    Args:
        net: the run's network (its kernel runs the messages with the control events).
        server: the server's client id.
        nodes: number of physics nodes (clients ``0..nodes-1``).
        trigger_bits: payload bits of a trigger and of a re-request.
        command_bits: payload bits of a command.
    """

    def __init__(
        self, net: Network, server: int, nodes: int, trigger_bits: int, command_bits: int
    ) -> None:
        self.net = net
        self.server = server
        self.all_nodes = list(range(nodes))
        self.trigger_bits = trigger_bits
        self.command_bits = command_bits

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """One PUBLISH of trigger ``k`` (payload ``(k, stamp)``), fanned out to every node."""
        s = self.server
        self.net.publish(s, TRIGGER, s, k, (k, stamp), self.trigger_bits, self.all_nodes)

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """One PUBLISH per node (payload ``(stamp, row)``, index ``tick``)."""
        bits = self.command_bits
        for i in nodes.tolist():
            self.net.publish(self.server, COMMAND, i, tick, (stamp, cmds[i].copy()), bits, (i,))

    def publish_rerequest(self, node: int, frame: int, retry: int) -> None:
        """One PUBLISH to ``node`` (payload ``frame``, index :func:`rerequest_index`)."""
        self.net.publish(self.server, REREQUEST, node, rerequest_index(frame, retry), frame,
                         self.trigger_bits, (node,))

    def server_tick(self, t: float) -> None:
        """The network's CPU stage takes the tick's burst."""
        self.net.server_tick(t)

    def server_free(self, t: float) -> float:
        """The network's CPU stage knows."""
        return self.net.server_free(t)

    def advance_to(self, bound: float, strict: bool) -> bool:
        """Nothing to run: the messages are events of the engine's own kernel."""
        return False

    def write_back(self) -> None:
        """Nothing to hand over: the components counted every message themselves."""

    def close(self) -> None:
        """Nothing to let go of: the messages in flight are events of the run's kernel."""
