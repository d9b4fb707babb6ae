"""Draw tables of the compiled message core: counter-based draws, filled by Python.

The compiled loop never draws a random number. For every random source of the
message model (latency and loss per link class and direction, broker service,
compute) and message kind, a row of the tables holds the values of all subjects
for one message index; Python fills it, from the very same
:class:`~sigma_des.core.draws.DrawCache` sampler the per-message engine reads,
before the messages of that index can need it. Draws are a pure function of their
key, so a table row can be refilled at any time and results never change.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.events.fast.layout import (
    K_COMMAND,
    K_REPUB,
    K_REREQ,
    K_STATE,
    K_TRIGGER,
    N_KINDS,
    N_SOURCES,
    STEP,
    SVC_DEL,
    SVC_PUB,
    U_OFFSET,
)
from sigma_des.events.fast.primitives import lat_source
from sigma_des.events.jobs import STEP_DRAW
from sigma_des.net.network import Network

__all__ = ["DrawTables", "network_sources"]

_Sampler = Callable[[int], NDArray[np.float64]]
#: (draw source, message kind, cache) of one random source of the core
Source = tuple[int, int, DrawCache]


def network_sources(net: Network, p_loss: tuple[float, float]) -> list[Source]:
    """The network's random sources: link latency and loss, broker service.

    Args:
        net: the per-message network (owner of the draw caches).
        p_loss: loss probability of the host and server links (0: no loss draws).
    """
    out: list[Source] = []
    for cls, is_server in ((0, False), (1, True)):
        # server → broker: trigger, command, re-request; node → broker: (re)published
        # state; the downlinks carry them on to their receivers
        from_server = (K_TRIGGER, K_COMMAND, K_REREQ)
        from_nodes = (K_STATE, K_REPUB)
        kinds_up = from_server if is_server else from_nodes
        kinds_down = from_nodes if is_server else from_server
        for up, kinds in ((1, kinds_up), (0, kinds_down)):
            src = lat_source(cls, up)
            lat = net.latency_draws(is_server, bool(up))
            for k in kinds:
                out.append((src, k, lat))
                if p_loss[cls] > 0.0:
                    out.append((U_OFFSET + src, k, net.loss_draws(is_server, bool(up))))
    for k in (K_TRIGGER, K_STATE, K_COMMAND, K_REREQ, K_REPUB):
        out.append((SVC_PUB, k, net.broker.publish_draws))
        out.append((SVC_DEL, k, net.broker.delivery_draws))
    return out


class DrawTables:
    """Which (source, kind) pairs need table rows, and the Python that fills them.

    Args:
        sources: every random source, the compute stream's (``STEP``, kind 0) included.
        history: rows per table (a message index maps to row ``index % history``).
        subjects: values per row (nodes and the server).

    Attributes:
        draw_map: (source, kind) -> table, -1 for a constant source.
        draw_const: the constant value of each constant source.
        values: the tables' values ``[table, row, subject]``.
        tags: the message index each row holds (-1: none yet).
    """

    def __init__(self, sources: list[Source], history: int, subjects: int) -> None:
        self.draw_map = np.full((N_SOURCES, N_KINDS), -1, dtype=np.int64)
        self.draw_const = np.zeros(N_SOURCES)
        self._fills: dict[int, list[tuple[int, _Sampler]]] = {k: [] for k in range(N_KINDS)}
        tables = 0
        for src, k, cache in sources:
            if cache.constant is not None:
                self.draw_const[src] = cache.constant
                continue
            self.draw_map[src, k] = tables
            sampler_kind = STEP_DRAW if src == STEP else k
            self._fills[k].append((tables, _vector_of(cache, sampler_kind)))
            tables += 1
        self.tables = max(tables, 1)
        self.values = np.zeros((self.tables, history, subjects))
        self.tags = np.full((self.tables, history), -1, dtype=np.int64)

    def fill(self, kind: int, index: int) -> None:
        """Make the rows of ``(kind, index)`` present (a pure function of the key)."""
        tags = self.tags
        r = index % tags.shape[1]
        for c, sample in self._fills[kind]:
            if tags[c, r] != index:
                v = sample(index)
                self.values[c, r, : v.size] = v
                tags[c, r] = index


def _vector_of(cache: DrawCache, kind: int) -> _Sampler:
    def sample(index: int) -> NDArray[np.float64]:
        return cache.vector(kind, index, 0)

    return sample
