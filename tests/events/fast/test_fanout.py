"""Fan-out batches take a broadcast's deliveries in exactly the specification's order.

Hand-computed cases on a small state (the broker's fan-out into stretches, the queue's
order with a batch going back in place or into the pending buffer), and whole runs that
force every path (lost deliveries, out-of-order arrivals, single deliveries) and stay
bit-identical to the per-message engine.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import fanout
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.fanout import counts, fan_out, fits, head, requeue
from sigma_des.events.fast.primitives import push, push_key, release
from sigma_des.events.fast.queue import peek, take
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.fast.test_layout import DIMS
from tests.events.test_cohort import run_both

N = 7  # nodes (clients 0..6, the server is client 7)
INDEX = 3  # the broadcast's trigger index
Out = list[tuple[float, int, int]]


IN_ORDER = (0.5, 0.1, 0.5, 0.2, 0.3, 0.05)  # arrivals 1.5, 2.1, 3.5, 4.2, 5.3, 6.05
OUT_OF_ORDER = (0.5, 0.1, 2.5, 0.2, 3.0, 0.05)  # arrivals 1.5, 2.1, 5.5, 4.2, 8.0, 6.05


def _state(bat: int = 16, lat: tuple[float, ...] = IN_ORDER) -> tuple[Any, ...]:
    """A small state: 6 subscribers on one link (no serialization), delivery service 1.0,
    each subscriber's latency ``lat`` from a draw table row, a drop fault on subscriber 1."""
    dims = {**DIMS, "n": N, "clients": N + 1, "clients_1": N + 2, "cap": 32, "arena": 40,
            "pool": 8, "bat": bat}
    given = {f.name: np.zeros(L.shape_of(f, dims), dtype=f.dtype)
             for f in L.FIELDS if f.fill is None}
    S = L.allocate(dims, given)
    S[L.FREE][:] = np.arange(32)[::-1]
    S[L.INTS][CO.I_FREE] = 32
    S[L.POOL_FREE][:] = np.arange(8)[::-1]
    S[L.INTS][CO.I_PFREE] = 8
    S[L.FPARAMS][:] = (0.0, 100.0)
    S[L.IPARAMS][CO.Q_N] = N
    S[L.DRAW_MAP][:] = -1
    S[L.DRAW_CONST][CO.SVC_DEL] = 1.0
    S[L.DRAW_MAP][CO.LAT_HD, CO.K_TRIGGER] = 0  # host link, down: table 0
    S[L.DRAW_TAG][0, INDEX] = INDEX
    S[L.DRAW_VAL][0, INDEX, :6] = lat
    S[L.LINK_DYN][3] = 1  # drop faults on
    S[L.DROPS][0] = (CO.K_TRIGGER, 1, INDEX)
    S[L.CPU_IP][CO.CP_NSUB] = 6
    S[L.BCAST][:6] = np.arange(6)
    return S


def _source(S: tuple[Any, ...]) -> int:
    """The broadcast's PUBLISH in a slot of its own (a trigger: no payload)."""
    src = _alloc(S)
    evi = S[L.EV_INT]
    evi[src, CO.E_KIND], evi[src, CO.E_SUBJ], evi[src, CO.E_INDEX] = CO.K_TRIGGER, N, INDEX
    S[L.EV_FLOAT][src, CO.EF_TPUB] = 0.25
    return src


def _alloc(S: tuple[Any, ...]) -> int:
    """A free event slot, taken off the free list."""
    iv = S[L.INTS]
    iv[CO.I_FREE] -= 1
    return int(S[L.FREE][iv[CO.I_FREE]])


def _drain(S: tuple[Any, ...], after_first: Callable[[], None] | None = None) -> Out:
    """Take every event as the loop does (a batch: its head, then back in the queue);
    return (time, sequence number, receiver) in the order taken."""
    out: Out = []
    qi = S[L.Q_INT]
    while True:
        t = peek(S)
        if not qi[CO.QI_HAS]:
            return out
        c = int(qi[CO.QI_CUR])
        p = int(S[L.RUN_POS][c])
        key = int(S[L.RUN_K][p])
        s = int(take(S))
        evi = S[L.EV_INT]
        if evi[s, CO.E_TYPE] == CO.EV_BATCH:
            head(S, s)
            out.append((float(t), key >> CO.SLOT_BITS, int(evi[s, CO.E_WHO])))
            if not requeue(S, s, c, p):
                release(S, s)
        else:
            out.append((float(t), key >> CO.SLOT_BITS, int(evi[s, CO.E_WHO])))
            release(S, s)
        if after_first is not None:
            after_first()
            after_first = None


@pytest.mark.parametrize(("lat", "batches", "single"), [(IN_ORDER, 1, 0),
                                                     (OUT_OF_ORDER, 0, 5)])
def test_fan_out_takes_the_specification_s_keys_and_skips_the_lost(
    lat: tuple[float, ...], batches: int, single: int
) -> None:
    """Departures 1..6, subscriber 1's copy dropped: the other five take sequence numbers
    0-4 in subscriber order and come out by (arrival, sequence); one batch when the
    arrivals do not decrease, else one event each."""
    S = _state(lat=lat)
    src = _source(S)
    assert fits(S, src, 6)
    assert fan_out(S, src, CO.K_TRIGGER, INDEX, 0, False, 1.0, 0.0) == 6.0
    iv = S[L.INTS]
    assert (iv[CO.I_EID], iv[CO.I_NEV]) == (5, 5)
    assert S[L.LINK_COUNT][0, 1, 0] == 6  # every copy left on the link, the lost one too
    assert counts(S) == {"on": 0, "batched": 0, "batches": batches, "requeued": 0,
                         "single": single}
    assert (iv[CO.I_BHEAD], iv[CO.I_BUSED]) == (5, 5 * batches)  # singles: delivered rows
    out = _drain(S)
    spec = sorted((float(j + 1) + lat[j], e, j) for e, j in enumerate((0, 2, 3, 4, 5)))
    assert out == spec
    if batches:
        assert [o[0] for o in out] == [1.5, 3.0 + 0.5, 4.0 + 0.2, 5.0 + 0.3, 6.0 + 0.05]
    else:
        assert out == [(1.5, 0, 0), (4.0 + 0.2, 2, 3), (5.5, 1, 2), (6.0 + 0.05, 4, 5),
                       (8.0, 3, 4)]
    assert counts(S)["batched"] == 5 * batches
    assert (iv[CO.I_BTAIL], iv[CO.I_BUSED]) == (5, 0)
    assert iv[CO.I_FREE] == 31  # every slot but the source's is free


def test_a_batch_goes_back_in_place_or_through_the_pending_buffer() -> None:
    """A batch of elements at 1.0, 2.0, 2.0, 3.0 (sequence 0-3) sealed into one run with
    events at 1.5 (4), 2.0 (5) and 10.0 (6); one made at 2.5 (7) after the first is taken.
    Hand-computed: after 1.0 the batch's 2.0 is behind the run's 1.5 (pending buffer);
    after the first 2.0 its second precedes the run's 2.5 (in place); after that its 3.0
    is behind 2.5 again (pending buffer); ties at 2.0 go by sequence."""
    S = _state()
    bt, bk, bw = S[L.BAT_T], S[L.BAT_K], S[L.BAT_W]
    bt[:4] = (1.0, 2.0, 2.0, 3.0)
    bk[:4] = np.arange(4) << CO.SLOT_BITS
    bw[:4] = (1, 2, 3, 4)
    iv = S[L.INTS]
    iv[CO.I_BHEAD] = iv[CO.I_BUSED] = 4
    b, s1, s2, s3, s4 = (_alloc(S) for _ in range(5))
    S[L.EV_INT][b, CO.E_TYPE] = CO.EV_BATCH
    S[L.EV_INT][b, CO.E_SEQ] = 0
    S[L.EV_INT][b, CO.E_NEXT] = 4
    push_key(S, 1.0, (0 << CO.SLOT_BITS) | b)
    iv[CO.I_EID] = 4
    for t, s in ((1.5, s1), (2.0, s2), (10.0, s3)):
        S[L.EV_INT][s, CO.E_TYPE] = CO.EV_CLIENT
        S[L.EV_INT][s, CO.E_WHO] = 10 + s
        push(S, t, s)
    S[L.EV_INT][s4, CO.E_WHO] = 10 + s4
    out = _drain(S, lambda: push(S, 2.5, s4))
    assert out == [(1.0, 0, 1), (1.5, 4, 10 + s1), (2.0, 1, 2), (2.0, 2, 3), (2.0, 5, 10 + s2),
                   (2.5, 7, 10 + s4), (3.0, 3, 4), (10.0, 6, 10 + s3)]
    assert counts(S)["requeued"] == 2 and counts(S)["batched"] == 4
    assert (iv[CO.I_BTAIL], iv[CO.I_BUSED]) == (4, 0)
    assert iv[CO.I_FREE] == 32  # the batch's slot too, after its last element


def test_no_room_or_a_payload_means_per_message() -> None:
    S = _state(bat=16)
    src = _source(S)
    assert fits(S, src, 6)
    S[L.INTS][CO.I_BUSED] = 11  # 5 rows free, 6 subscribers
    assert not fits(S, src, 6)
    S[L.INTS][CO.I_BUSED] = 0
    S[L.EV_INT][src, CO.E_PAY] = 1
    assert not fits(S, src, 6)


def _counts(sc: Any, method: str) -> dict[str, int]:
    run = MethodRun(replace(sc, engine="cohort").run_spec(), method, make_dynamics(sc),
                    make_behaviour(sc), compiled=True)
    run.run()
    return counts(run.core.S)  # type: ignore[attr-defined]


def test_lossy_out_of_order_fan_out_identical() -> None:
    """Loss, a jitter below the broker's delivery service and a degraded host (datagram,
    QoS 0), hosts interleaved by round-robin placement: batches with lost deliveries, and
    broadcasts out of order (the degraded host's copies late) one event per delivery,
    bit-identical to the per-message engine."""
    sc = tiny(nodes=12, hosts=3, placement="round_robin", duration=1.0, **{
        "net.transport": "datagram", "net.qos": 0, "net.host_link.loss": {"p": 0.1},
        "net.host_link.latency": {"dist": "uniform", "low": 0.0002, "high": 0.00021},
        "broker.delivery_service": 0.0001, "commands.enabled": True,
        "faults": [{"kind": "degrade", "host": 1, "start": 0.3, "end": 0.6,
                    "extra_delay": 0.002, "extra_loss": 0.2}]})
    for method in ("bides", "lockstep"):
        _ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"
        c = _counts(sc, method)
        assert c["on"] == 1 and c["batches"] > 0 and c["single"] > 0


def test_in_order_fan_out_is_all_batched_and_switchable(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Constant latency, a delivery service longer than a trigger's serialization: every
    trigger delivery comes from one batch of all nodes per trigger (the last maybe cut
    by the run's end); without batches the results are the same."""
    sc = tiny(nodes=6, hosts=2, duration=1.0, **{"commands.enabled": True,
                                                  "broker.delivery_service": 0.0001})
    c = _counts(sc, "bides")
    assert c["on"] == 1 and c["single"] == c["requeued"] == 0 and c["batches"] > 50
    assert 6 * (c["batches"] - 1) <= c["batched"] <= 6 * c["batches"]
    on = _both_ways(sc, monkeypatch)
    assert on[0] == on[1]


def _both_ways(sc: Any, monkeypatch: pytest.MonkeyPatch) -> tuple[Any, Any]:
    from sigma_des.api import run_method

    co = replace(sc, engine="cohort")
    with_batches = run_method(co, "hlc")["metrics"]
    monkeypatch.setattr(fanout, "ENABLED", False)
    assert _counts(sc, "hlc")["on"] == 0
    return with_batches, run_method(co, "hlc")["metrics"]


@pytest.mark.parametrize("over", [
    {"net.transport": "datagram", "net.qos": 1},  # QoS 1 over datagram: resend timers
    {"deployment.preset": "colocated", "deployment.host_demand": 0.0003},  # CPU stage
])
def test_batches_off_where_a_delivery_is_more_than_one_hop(over: dict[str, Any]) -> None:
    assert _counts(tiny(**over), "none")["on"] == 0
