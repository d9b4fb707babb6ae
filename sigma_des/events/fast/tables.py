"""Tables of the compiled message core, filled by Python: draws, links, clocks.

The compiled loop never draws a random number. For every random source of the
message model (latency and loss per link class and direction, broker service,
compute) and message kind, a row of the tables holds the values of all subjects
for one message index; Python fills it, from the very same
:class:`~sigma_des.core.draws.DrawCache` sampler the per-message engine reads,
before the messages of that index can need it. Draws are a pure function of their
key, so a table row can be refilled at any time and results never change.

The link and clock tables (:func:`link_tables`, :func:`clock_tables`) are built
once per run from the very objects the per-message engine reads: the
Gilbert–Elliott chain state per link, direction and slot, the degrade windows and
dropped keys, and the NTP residual per node and sync instant.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawBlock, DrawCache
from sigma_des.core.filled import filled
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast.codes import (
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
from sigma_des.events.fast.memo import IdentityMemo
from sigma_des.events.fast.primitives import lat_source
from sigma_des.events.fast.support import CohortFallback, ge_slots, ntp_syncs
from sigma_des.events.jobs import STEP_DRAW
from sigma_des.events.spec import RunSpec
from sigma_des.net.clocks import NodeClocks
from sigma_des.net.network import Network

__all__ = [
    "DEPLOYMENT_FIELDS",
    "DrawTables",
    "Fill",
    "clock_tables",
    "deployment_tables",
    "fill_rows",
    "link_tables",
    "lossy_classes",
    "network_sources",
]

#: (table, cache, kind the cache is sampled with): one table filled from one cache
Fill = tuple[int, DrawCache, int]
#: (draw source, message kind, cache) of one random source of the core
Source = tuple[int, int, DrawCache]


def network_sources(net: Network, lossy: tuple[bool, bool]) -> list[Source]:
    """The network's random sources: link latency and loss, broker service.

    Args:
        net: the per-message network (owner of the draw caches).
        lossy: whether the host and server links can lose a packet (else: no loss
            draws; see :func:`lossy_classes`).
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
                if lossy[cls]:
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
        self.draw_map = filled((N_SOURCES, N_KINDS), -1, np.int64)
        self.draw_const = np.zeros(N_SOURCES)
        self._fills: dict[int, list[Fill]] = {k: [] for k in range(N_KINDS)}
        #: per kind: (table, the block of draws it is filled from), made at its first
        #: :meth:`fill` (the trigger, state, command and compute rows of a compiled run
        #: are filled a frame at a time by ``FrameDraws``, never here)
        self._blocks: dict[int, list[tuple[int, DrawBlock]]] = {}
        tables = 0
        for src, k, cache in sources:
            if cache.constant is not None:
                self.draw_const[src] = cache.constant
                continue
            self.draw_map[src, k] = tables
            sampler_kind = STEP_DRAW if src == STEP else k
            self._fills[k].append((tables, cache, sampler_kind))
            tables += 1
        self.tables = max(tables, 1)
        self.values = np.zeros((self.tables, history, subjects))
        self.tags = filled((self.tables, history), -1, np.int64)

    def fills_of(self, kind: int) -> list[Fill]:
        """The tables of ``kind``, each with its cache and sampling kind."""
        return list(self._fills[kind])

    def fill(self, kind: int, index: int) -> None:
        """Make the rows of ``(kind, index)`` present (a pure function of the key).

        :func:`fill_rows`' rule, the draws taken from a :class:`~sigma_des.core.draws.DrawBlock`
        per table (consecutive indices drawn in one sampler call, the same bits).
        """
        row = index % self.tags.shape[1]
        values, tags = self.values, self.tags
        blocks = self._blocks.get(kind)
        if blocks is None:  # (a block starts empty: made now or earlier, the same rows)
            blocks = self._blocks[kind] = [(c, DrawBlock(cache, sampler_kind))
                                           for c, cache, sampler_kind in self._fills[kind]]
        for c, block in blocks:
            if tags[c, row] != index:
                v = block.row(index)
                values[c, row, : v.size] = v
                tags[c, row] = index


def fill_rows(
    values: NDArray[np.float64],
    tags: NDArray[np.int64],
    fills: Sequence[Fill],
    row: int,
    key: int,
    index: int,
    attempt: int = 0,
) -> None:
    """Make row ``row`` of every table of ``fills`` hold the draws of ``key``.

    A row whose tag is ``key`` already is left alone; any other is overwritten with
    ``cache.vector(kind, index, attempt)`` (a short vector fills the row's head) and
    tagged ``key``. Draws are a pure function of their key, so a row taken by another
    key can be refilled at any time without changing results.

    Args:
        values: the tables' values ``[table, row, subject]``.
        tags: the key each row holds ``[table, row]`` (-1: none).
        fills: the tables to fill, each with its cache and sampling kind.
        row: the row of every table to fill.
        key: what the row holds once filled (the message index, or a key of index
            and attempt).
        index: the message index the draws are keyed by.
        attempt: the attempt the draws are keyed by (0: the first transmission).
    """
    for c, cache, kind in fills:
        if tags[c, row] != key:
            v = cache.vector(kind, index, attempt)
            values[c, row, : v.size] = v
            tags[c, row] = key


# ---------------------------------------------------------------- link and clock tables


def lossy_classes(spec: RunSpec) -> tuple[bool, bool]:
    """Whether a packet can be lost on the host links and on the server's link
    (Bernoulli ``p``, a Gilbert–Elliott state's loss, or a lossy degrade window)."""
    net = spec.net.net
    hosts = spec.hosts
    out = []
    for cls, link in ((0, net.host_link), (1, net.server_link)):
        loss = link.loss
        ge = loss.model == "gilbert_elliott" and max(loss.loss_good, loss.loss_bad) > 0.0
        deg = any((d.host == hosts) == (cls == 1) and d.extra_loss > 0.0
                  for d in spec.net.degrades)
        out.append(loss.p > 0.0 or ge or deg)
    return out[0], out[1]


def link_tables(net: Network, spec: RunSpec) -> dict[str, NDArray[Any]]:
    """The core's link tables: Gilbert–Elliott chains, degrade windows, dropped keys.

    The chain states come from the network's own loss processes
    (:meth:`~sigma_des.net.links.Links.loss_process`), the windows in fault order per
    link (the order :meth:`~sigma_des.net.links.Links._loss_at` combines them).
    """
    setup = spec.net
    links = setup.net
    hosts = spec.hosts
    slots = ge_slots(spec)
    dyn = np.zeros(4, dtype=np.int64)
    par = np.zeros((2, 3))
    bad = np.zeros((2, hosts + 1, slots), dtype=np.uint8)
    for cls, link in ((0, links.host_link), (1, links.server_link)):
        loss = link.loss
        par[cls] = (loss.slot, loss.loss_good, loss.loss_bad)
        if loss.model != "gilbert_elliott":
            continue
        dyn[cls] = 1
        # the middle of each slot: floor(t / slot) is the slot itself, exactly
        t = (np.arange(slots, dtype=np.float64) + 0.5) * loss.slot
        if not np.array_equal(np.floor(t / loss.slot), np.arange(slots)):
            raise CohortFallback("Gilbert-Elliott slot times are not exact")
        for k in range(hosts + 1):
            if (k == hosts) == (cls == 1):
                for up in (0, 1):
                    bad[up, k] = net.loss_process(cls == 1, up == 1, k).bad_state(t)
    ptr = np.zeros(hosts + 2, dtype=np.int64)
    rows: list[tuple[float, float, float, float]] = []
    for k in range(hosts + 1):
        rows.extend((d.start, d.end, d.extra_delay, d.extra_loss)
                    for d in setup.degrades if d.host == k)
        ptr[k + 1] = len(rows)
    dyn[2] = int(bool(rows))
    drops = sorted(setup.drops)
    dyn[3] = int(bool(drops))
    return {
        "link_dyn": dyn, "ge_par": par, "ge_bad": bad, "deg_ptr": ptr,
        "deg": np.array(rows if rows else [(0.0, 0.0, 0.0, 0.0)], dtype=np.float64),
        "drops": np.array(drops if drops else [(-1, -1, -1)], dtype=np.int64),
    }


def clock_tables(clocks: NodeClocks, spec: RunSpec) -> dict[str, NDArray[Any]]:
    """The core's NTP table: residual ``e_ij`` of node ``i`` after sync ``j``, drawn by
    ``(node, 2, j)`` from the clocks' own stream, times ``ntp_residual_std``."""
    cs = clocks.spec
    n = clocks.n
    cols = ntp_syncs(spec)
    res = np.zeros((n, cols))
    if cs.ntp_period > 0.0:
        ids = np.arange(n, dtype=np.int64)[:, None]
        js = np.arange(cols, dtype=np.int64)[None, :]
        res = np.ascontiguousarray(cs.ntp_residual_std * clocks.stream.normal(ids, 2, js))
    return {"ntp_period": np.array([cs.ntp_period]), "ntp_res": res}


def deployment_tables(net: Network, spec: RunSpec) -> dict[str, NDArray[Any]]:
    """Processes, machines and MQTT clients (what Network and Cpu hold), fresh arrays.

    A function of ``spec.net`` alone (the network ``net`` and its CPU stage are built
    from it and read before the run): the tables are kept per network setup
    (:mod:`~sigma_des.events.fast.memo`) and each run gets its own copies.
    """
    kept = _DEPLOYMENT.get((spec.net,), (), lambda: _deployment_tables(net, spec))
    return {k: v.copy() for k, v in kept.items()}


_DEPLOYMENT: IdentityMemo[dict[str, NDArray[Any]]] = IdentityMemo()
#: the fields :func:`deployment_tables` supplies
DEPLOYMENT_FIELDS = ("cpu_ip", "cpu_proc", "cpu_dem", "cpu_mach", "cpu_scale", "cpu_wake",
                     "cpu_side", "cpu_switch", "cpu_net", "cl_of", "cpu_runq", "cpu_grow",
                     "cpu_load", "bcast", "mem_ptr", "mem")


def _deployment_tables(net: Network, spec: RunSpec) -> dict[str, NDArray[Any]]:
    """:func:`deployment_tables`, computed."""
    dep = spec.net.deployment
    topo = spec.net.topology
    n = topo.nodes
    cpu = net.cpu
    H = topo.hosts
    ip = np.zeros(CO.CP_LEN, dtype=np.int64)
    proc = np.full(n + 1, -1, dtype=np.int64)
    demand = np.zeros(n + 1)
    mach = np.zeros(H + 2, dtype=np.int64)
    scale = np.ones(H + 2)
    wake = np.zeros(H + 2)
    side = np.zeros(H + 2)
    net_cpu = np.zeros((H + 2, 2))
    switch = np.zeros(H + 2)
    runq = np.zeros(H + 2)
    grow = np.zeros(H + 2)
    load = np.zeros((len(cpu.machines) if cpu is not None else 1, CO.ML_LEN))
    if cpu is not None:
        for m, x in enumerate(cpu.machines):
            load[m] = (float(x.growth), x.bg, x.w_end, x.w_busy, x.q)
        # process p is cpu.processes[p]: broker, server, host h at P_HOST0 + h
        assert cpu.processes == [cpu.broker, cpu.server, *cpu.hosts]
        for p, pr in enumerate(cpu.processes):
            mach[p] = next(m for m, x in enumerate(cpu.machines) if x is pr.machine)
            scale[p] = pr.scale
            wake[p] = pr.wake
            side[p] = pr.side
            net_cpu[p] = (pr.net_msg, pr.net_wake)
            runq[p] = pr.runq
            grow[p] = float(pr.grow)
            switch[p] = dep.lock_switch if p != CO.P_BROKER else 0.0
        ip[CO.CP_BROKER] = CO.P_BROKER if net.broker.process is not None else -1
        for i in range(n + 1):  # Network._proc: no burst for a zero demand
            d = dep.host_demand if i < n else dep.server_demand
            if d > 0.0:
                proc[i] = CO.P_HOST0 + topo.host_of[i] if i < n else CO.P_SERVER
                demand[i] = d
    else:
        ip[CO.CP_BROKER] = -1
    ip[CO.CP_HOSTS] = int(net.host_clients)
    ip[CO.CP_APP] = int(net.host_clients or bool((proc >= 0).any()))
    cl_of = np.array(net.client_of, dtype=np.int64)
    subs = list(dict.fromkeys(net.client_of[:n]))  # a broadcast's subscribers, in order
    ip[CO.CP_NSUB] = len(subs)
    ip[CO.CP_MAXMEM] = max(len(m) for m in net.members.values()) if net.host_clients else 1
    ip[CO.CP_SWITCH] = int(cpu is not None and dep.lock_switch > 0.0)
    bcast = np.full(n + 1, -1, dtype=np.int64)
    bcast[: len(subs)] = subs
    ptr = np.zeros(n + 2, dtype=np.int64)
    mem: list[int] = []
    for c in range(n + 1):
        mem.extend(net.members.get(c, ()) if net.host_clients else ([c] if c < n else []))
        ptr[c + 1] = len(mem)
    return {"cpu_ip": ip, "cpu_proc": proc, "cpu_dem": demand, "cpu_mach": mach,
            "cpu_scale": scale, "cpu_wake": wake, "cpu_side": side, "cpu_switch": switch,
            "cpu_net": net_cpu,
            "cl_of": cl_of, "cpu_runq": runq, "cpu_grow": grow, "cpu_load": load,
            "bcast": bcast, "mem_ptr": ptr,
            "mem": np.array(mem, dtype=np.int64)}
