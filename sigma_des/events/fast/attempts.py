"""Draw tables of PUBACKs and resends for the compiled message core, and its transport state.

The main draw tables (:mod:`sigma_des.events.fast.tables`) hold the first
transmission of every message. QoS 1 over datagram also draws, keyed by
``kind + ACK``, for every PUBACK (attempt 0 and on), and for every resend of a
PUBLISH or a delivery (attempts 1 .. ``max_retries``): latency and loss on the
links, broker service; a stream with hold-back draws latency and loss for every
retry of a lost segment. The PUBACK draws of attempt 0 are needed for every
message: they are filled with the message's own rows, one row per message index
(``index % history``). Draws of later attempts are needed only after a loss: the
loop asks for them before the event that needs them
(:func:`sigma_des.events.fast.resend.missing`) and :meth:`AttemptTables.fill`
fills one row, keyed ``index * (max_retries + 1) + attempt``. Every value comes
from the very :class:`~sigma_des.core.draws.DrawCache` the per-message network
reads, so the tables change speed, never results.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.core.filled import filled
from sigma_des.events.fast.codes import (
    K_COMMAND,
    K_REPUB,
    K_REREQ,
    K_STATE,
    K_TRIGGER,
    N_KINDS,
    N_SOURCES,
    SVC_DEL,
    SVC_PUB,
    T_DUPALL,
    T_QLEN,
    T_QOS1D,
    T_RETRIES,
    T_STREAM,
    T_XROWS,
    TF_LEN,
    TF_RTO,
    TF_TIMEOUT,
    U_OFFSET,
)
from sigma_des.events.fast.primitives import lat_source
from sigma_des.events.fast.tables import Fill, fill_rows
from sigma_des.net.kinds import ACK
from sigma_des.net.network import Network

__all__ = ["X_ROWS", "AttemptTables"]

#: Rows of the attempt tables (a message's later attempts share them; a row taken by
#: another key is refilled on demand, so this changes speed only).
X_ROWS = 64


class AttemptTables:
    """The PUBACK and resend draws of one run, and the Python that fills them.

    Args:
        net: the per-message network (owner of the draw caches and QoS settings).
        lossy: whether a packet can be lost on the host links and the server's link
            (:func:`~sigma_des.events.fast.tables.lossy_classes`; else no loss draws).
        history: rows of the PUBACK tables (as the main tables).
        subjects: values per row (nodes and the server).
        lockstep: whether re-requests and republished states are sent.

    Attributes:
        qos1d: whether the run uses QoS 1 over datagram.
        stream: per link class (host, server), whether it is a stream with hold-back
            (loss or random latency: ``Links.transmit``'s in-order bookkeeping).
        active: whether anything is resent (else the tables are empty).
    """

    def __init__(
        self, net: Network, lossy: tuple[bool, bool], history: int, subjects: int,
        lockstep: bool,
    ) -> None:
        self.qos1d = net.qos1 and net.datagram
        setup = net.setup
        specs = (setup.net.host_link, setup.net.server_link)
        self.stream = tuple(
            not net.datagram and not (
                s.latency.dist == "constant" and s.loss.model == "bernoulli" and s.loss.p == 0.0
                and not setup.degrades and not setup.drops)
            for s in specs
        )
        self.active = self.qos1d or any(self.stream)
        self.retries = net.max_retries
        self.timeout = net.timeout
        self.rto = net.rto
        self.conn = np.zeros((5, 2, subjects), dtype=np.int64)
        self.conn[2:4] = -1  # pending lists: no head, no tail
        self.rows = X_ROWS if self.active else 1
        # -1: a constant source, -2: none registered (reading it stops the compiled run)
        self.ack_map = filled((N_SOURCES, N_KINDS), -2, np.int64)
        self.x_map = filled((N_SOURCES, 2 * N_KINDS), -2, np.int64)
        self.x_const = np.zeros(N_SOURCES)
        self.x_first = filled(N_KINDS, -1, np.int64)
        self._ack: dict[int, list[Fill]] = {k: [] for k in range(N_KINDS)}
        self._x: dict[int, list[Fill]] = {k: [] for k in range(N_KINDS)}
        self._n_ack = self._n_x = 0  # the PUBACK and resend tables registered
        kinds = [K_TRIGGER, K_STATE, K_COMMAND] + ([K_REREQ, K_REPUB] if lockstep else [])
        for k in kinds:
            if self.qos1d:
                self._register(net, lossy, k)
            elif self.active:
                self._register_stream(net, lossy, k)
        n_ack, n_x = self._n_ack, self._n_x
        #: whether any PUBACK of attempt 0 is drawn (else :meth:`fill_ack` fills nothing)
        self.acks = n_ack > 0
        self.ack_val = np.zeros((max(n_ack, 1), history, subjects))
        self.ack_tag = filled((max(n_ack, 1), history), -1, np.int64)
        self.x_val = np.zeros((max(n_x, 1), self.rows, subjects))
        self.x_tag = filled((max(n_x, 1), self.rows), -1, np.int64)

    def _register(self, net: Network, lossy: tuple[bool, bool], k: int) -> None:
        """The sources of kind ``k``: its PUBLISH legs, their PUBACKs, broker service."""
        pub = 1 if k in (K_TRIGGER, K_COMMAND, K_REREQ) else 0  # publisher's link class
        # (link class, up, PUBACK?): publish up and its PUBACK down on the publisher's
        # link; delivery down and its PUBACK up on the subscriber's
        legs = ((pub, 1, False), (pub, 0, True), (1 - pub, 0, False), (1 - pub, 1, True))
        for cls, up, ack in legs:
            src = lat_source(cls, up)
            self._add(src, k, ack, net.latency_draws(cls == 1, bool(up)))
            if lossy[cls]:
                self._add(U_OFFSET + src, k, ack, net.loss_draws(cls == 1, bool(up)))
        self._add(SVC_PUB, k, False, net.broker.publish_draws)
        self._add(SVC_DEL, k, False, net.broker.delivery_draws)

    def _register_stream(self, net: Network, lossy: tuple[bool, bool], k: int) -> None:
        """The retry sources of kind ``k``: its legs on streams with hold-back (a
        segment lost, or dropped by a fault, is retried)."""
        pub = 1 if k in (K_TRIGGER, K_COMMAND, K_REREQ) else 0
        for cls, up in ((pub, 1), (1 - pub, 0)):
            if self.stream[cls]:
                src = lat_source(cls, up)
                self._add(src, k, False, net.latency_draws(cls == 1, bool(up)))
                if lossy[cls]:
                    self._add(U_OFFSET + src, k, False, net.loss_draws(cls == 1, bool(up)))

    def _add(self, src: int, k: int, ack: bool, cache: DrawCache) -> None:
        if cache.constant is not None:
            self.x_const[src] = cache.constant
            self.x_map[src, k + N_KINDS if ack else k] = -1
            if ack:
                self.ack_map[src, k] = -1
            return
        c = self._n_x  # the tables registered so far
        self._n_x += 1
        self.x_map[src, k + N_KINDS if ack else k] = c
        if self.x_first[k] < 0:
            self.x_first[k] = c
        self._x[k].append((c, cache, k + ACK if ack else k))
        if ack:
            a = self._n_ack
            self._n_ack += 1
            self.ack_map[src, k] = a
            self._ack[k].append((a, cache, k + ACK))

    def dims(self) -> dict[str, int]:
        """The sizes of the dimensions of the tables (for the state's layout)."""
        return {"ack_tables": self.ack_tag.shape[0], "x_tables": self.x_tag.shape[0],
                "x_rows": self.rows}

    def given(self) -> dict[str, NDArray[Any]]:
        """The state arrays of the transport (parameters and tables)."""
        tp = np.zeros(T_QLEN, dtype=np.int64)
        tp[T_QOS1D] = int(self.qos1d)
        tp[T_DUPALL] = int(self.qos1d)
        tp[T_RETRIES] = self.retries
        tp[T_XROWS] = self.rows
        tp[T_STREAM : T_STREAM + 2] = self.stream
        tf = np.zeros(TF_LEN)
        tf[TF_TIMEOUT] = self.timeout
        tf[TF_RTO] = self.rto
        return {"tr_params": tp, "tr_fparams": tf, "ack_map": self.ack_map,
                "ack_val": self.ack_val, "ack_tag": self.ack_tag, "x_map": self.x_map,
                "x_const": self.x_const, "x_first": self.x_first, "x_val": self.x_val,
                "x_tag": self.x_tag, "conn": self.conn}

    def fill_ack(self, kind: int, index: int) -> None:
        """Make the PUBACK rows of attempt 0 of ``(kind, index)`` present."""
        row = index % self.ack_tag.shape[1]
        fill_rows(self.ack_val, self.ack_tag, self._ack[kind], row, index, index)

    def fill(self, kind: int, index: int, attempt: int) -> None:
        """Make the rows of attempt ``attempt >= 1`` of ``(kind, index)`` present."""
        key = index * (self.retries + 1) + attempt
        fill_rows(self.x_val, self.x_tag, self._x[kind], key % self.rows, key, index, attempt)
