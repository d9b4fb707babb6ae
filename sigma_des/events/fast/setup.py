"""The compiled core's state arrays of one run, built from the engine's objects.

:func:`dims` sizes every dimension of the state's declaration
(:data:`~sigma_des.events.fast.layout.FIELDS`), :func:`given` supplies the arrays the
driver owns or shares with the engine (parameters, draw and link tables, the truth's
ring of published rows, the command rows): what the per-message engine holds per node,
link and kind, in the core's arrays.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.align.base import OBS_WIDTH
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast.support import ge_slots, ntp_syncs
from sigma_des.events.fast.tables import (
    DEPLOYMENT_FIELDS,
    clock_tables,
    deployment_tables,
    link_tables,
)
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER

if TYPE_CHECKING:
    from sigma_des.events.fast.driver import CompiledCore

__all__ = ["SEED_FREE", "dims", "given", "seed_free"]


def dims(core: CompiledCore, slack: int, arena: float) -> dict[str, int]:
    """The size of every dimension of the core's state.

    Args:
        core: the core being built (its host, draw, attempt, rollback and delivery tables).
        slack: spare event slots beyond what one frame needs.
        arena: the queue's arena rows per event slot.
    """
    h = core.host
    n, spec = h.n, h.spec
    M = int(h.nodes.cmd.shape[1])
    dup_all = core.attempts.qos1d
    seen = h.method == "lockstep" or dup_all
    cpu = h.net.cpu
    cap = 4 * (n + 1) + slack
    return {
        "cap": cap, "arena": int(arena * cap), "pool": cap, "n": n, "clients": n + 1,
        "bat": 2 * cap,  # fan-out elements: a few broadcasts in flight (else per message)
        "links": spec.hosts + 1,
        "hosts": spec.hosts, "cores": spec.cores_per_host, "tables": core.tables.tables,
        "H": h.truth.H, "W": OBS_WIDTH, "M": M, "pay_w": max(OBS_WIDTH, M),
        "out": 2 * (n + 1) + slack, "out_w": 3 + OBS_WIDTH,
        "last_w": 2 + OBS_WIDTH, "slow": max(1, sum(len(w) for w in h.nodes.slow.values())),
        # duplicate check of re-requests and republished states (Lock-Step), or of
        # every kind (QoS 1 over datagram: row = kind)
        "seen_k": CO.N_KINDS if dup_all else 2, "seen_n": n + 1 if seen else 1,
        "seen_h": spec.history_frames if seen else 1, **core.attempts.dims(),
        # link and clock tables (Gilbert–Elliott, degrade, drop, NTP)
        "links_1": spec.hosts + 2, "ge_slots": ge_slots(spec),
        "deg": max(1, len(spec.net.degrades)), "drops": max(1, len(spec.net.drops)),
        "ntp_j": ntp_syncs(spec),
        # deployment: processes (broker, server, hosts), machines, their cores
        "procs": spec.hosts + 2, "clients_1": n + 2,
        "machines": len(cpu.machines) if cpu is not None else 1,
        "cpu_cores": cpu.cores if cpu is not None else 1, **core.rollbacks.dims(),
        **core.deliveries.dims(),
    }


def params(core: CompiledCore) -> NDArray[np.int64]:
    """The loop's integer parameters (``codes.Q_*``)."""
    h = core.host
    spec, net = h.spec, h.net
    q = np.zeros(CO.Q_LEN, dtype=np.int64)
    q[CO.Q_N] = h.n
    q[CO.Q_H] = h.truth.H
    q[CO.Q_HLC] = int(h.method == "hlc")
    q[CO.Q_WARP] = int(h.method == "bides" and spec.time_warp)
    q[CO.Q_THETA] = spec.theta_warp
    q[CO.Q_QOS1S] = int(net.qos1 and not net.datagram)
    q[CO.Q_ACK] = net.ack_bytes
    q[CO.Q_W] = OBS_WIDTH
    q[CO.Q_M] = int(h.nodes.cmd.shape[1])
    q[CO.Q_LOCK] = int(h.method == "lockstep")
    q[CO.Q_BATCH] = int(h.truth.batched)
    core.deliveries.params(q)
    return q


def links(core: CompiledCore) -> dict[str, NDArray[Any]]:
    """Access links and message sizes (what Network holds per link and kind)."""
    h = core.host
    spec, net = h.spec, h.net
    spb = np.zeros((2, spec.hosts + 1))
    for k in range(spec.hosts + 1):
        spb[1, k] = net.up[k].sec_per_byte
        spb[0, k] = net.down[k].sec_per_byte
    wb = np.zeros(CO.N_KINDS, dtype=np.int64)
    bits = {TRIGGER: spec.trigger_payload_bits, STATE: spec.payload_bits,
            COMMAND: spec.commands.payload_bits, REREQUEST: spec.trigger_payload_bits,
            REPUBLISH: spec.payload_bits}
    for kind, b in bits.items():
        wb[kind] = net.wire_bytes(b)
    return {"link_spb": spb, "link_of": np.array(net.link_of, dtype=np.int64),
            "wire_bytes": wb}


def nodes(core: CompiledCore) -> dict[str, NDArray[Any]]:
    """Node rows, hosts and faults (:func:`clocks`: the nodes' clocks)."""
    h = core.host.nodes
    n = core.host.n
    nd = np.zeros((CO.N_ROWS, n), dtype=np.int64)
    nd[[CO.N_FRAME, CO.N_REQ, CO.N_TARGET, CO.N_CSTAMP]] = -1
    ptr = np.zeros(n + 1, dtype=np.int64)
    rows: list[tuple[float, float, float]] = []
    for i in range(n):
        rows.extend(h.slow.get(i, ()))
        ptr[i + 1] = len(rows)
    last_i = np.zeros((n, 2), dtype=np.int64)
    last_i[:, 0] = -1
    return {
        "node": nd, "host_of": np.array(h.host_of, dtype=np.int64),
        "crash": np.array(h.crash_at, dtype=np.float64), "slow_ptr": ptr,
        "slow": np.array(rows if rows else [(0.0, 0.0, 1.0)], dtype=np.float64),
        "last_int": last_i,
    }


def clocks(core: CompiledCore) -> dict[str, NDArray[Any]]:
    """The nodes' clock offsets and drifts (drawn from the run's seed)."""
    c = core.host.nodes.clocks
    drift = (c.drift_ppm * 1e-6).tolist()  # the engine's arithmetic, exactly
    return {"clock_off": np.array(c.offset.tolist(), dtype=np.float64),
            "clock_drift": np.array(drift, dtype=np.float64)}


def given(core: CompiledCore, p_loss: tuple[float, float], slack: int,
          kept: Mapping[str, NDArray[Any]] | None = None) -> dict[str, NDArray[Any]]:
    """The arrays of the fields without a fill: parameters, tables, shared arrays.

    Args:
        core: the core being built.
        p_loss: the Bernoulli loss of the host links and of the server's link.
        slack: spare event slots beyond what one frame needs (as :func:`dims`).
        kept: the arrays of the fields :func:`seed_free` named for a run whose spec
            differs from this one's in the seed at most (same method and dynamics):
            not made again (the caller supplies copies of them).
    """
    h = core.host
    spec = h.spec
    tb = core.tables
    out = {
        "draw_map": tb.draw_map, "draw_const": tb.draw_const, "draw_val": tb.values,
        "draw_tag": tb.tags,
        "slot_frame": h.truth.slot_frame, "obs_hist": h.truth.obs_hist, "cmd": h.nodes.cmd,
        **clocks(core), **core.attempts.given(), **core.deliveries.given(),
    }
    if kept is None:
        cap = 4 * (h.n + 1) + slack
        out.update({
            "free": np.arange(cap, dtype=np.int64)[::-1].copy(),
            "pool_free": np.arange(cap, dtype=np.int32)[::-1].copy(),
            "iparams": params(core), "fparams": np.array([spec.warmup, spec.duration]),
            "p_loss": np.array(p_loss), **links(core), **nodes(core),
            **deployment_tables(h.net, spec), **core.rollbacks.given(),
        })
    if kept is None or "link_dyn" not in kept:
        out.update(link_tables(h.net, spec))
    if kept is None or "ntp_res" not in kept:
        out.update(clock_tables(h.nodes.clocks, spec))
    return out


#: The fields of :func:`given` whose arrays are a function of the spec without its seed,
#: the method and the dynamics model, and which the core alone holds: the same for every
#: episode of a learning env's scenes (:func:`seed_free` adds the link and clock tables
#: where they hold no draw).
SEED_FREE = ("free", "pool_free", "iparams", "fparams", "p_loss", "link_spb", "link_of",
             "wire_bytes", "node", "host_of", "crash", "slow_ptr", "slow", "last_int",
             *DEPLOYMENT_FIELDS, "rb_val", "rb_tag")
LINK_FIELDS = ("link_dyn", "ge_par", "ge_bad", "deg_ptr", "deg", "drops")


def seed_free(given: Mapping[str, NDArray[Any]]) -> tuple[str, ...]:
    """The fields of ``given`` (:func:`given`'s full answer) that hold no random draw:
    :data:`SEED_FREE`, the link tables unless a link is Gilbert–Elliott (its chain
    states are drawn), and the NTP table unless the clocks synchronise (its residuals
    are drawn)."""
    names: tuple[str, ...] = SEED_FREE
    if not given["link_dyn"][:2].any():
        names += LINK_FIELDS
    if given["ntp_period"][0] <= 0.0:
        names += ("ntp_period", "ntp_res")
    return names
