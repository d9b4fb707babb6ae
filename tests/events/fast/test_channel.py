"""Channels take a direction's hops in exactly the specification's order.

Hand-computed cases on a small state (hops over FIFO links into the up channel and a
plain event when one arrives out of order; the queue's order with a token going back
in place while plain events fall between; a full ring; a token that had to join the
pending buffer moving into a run of its own), and whole runs with channels on and off
that run the same events and stay bit-identical to the per-message engine.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from sigma_des.api import run_method
from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import channel
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.channel import arrive, hop, requeue, take
from sigma_des.events.fast.primitives import address, push, release
from sigma_des.events.fast.queue import peek
from sigma_des.events.fast.queue import take as take_head
from sigma_des.events.fast.tally import CLASSES, breakdown
from sigma_des.factory import make_behaviour, make_dynamics
from tests.conftest import tiny
from tests.events.fast.test_layout import DIMS
from tests.events.test_cohort import run_both

Out = list[tuple[float, int, int]]
CAP = 32


def _state(bat: int = 16, arena: int = 40) -> tuple[Any, ...]:
    """A small state: clients 0 and 1 on links 0 and 1 (up: 0.01 s a byte), a state is
    10 bytes on the wire, up-link latency 0.5 s, no loss, window [0, 100)."""
    dims = {**DIMS, "n": 2, "clients": 3, "clients_1": 4, "cap": CAP, "arena": arena,
            "bat": bat}
    given = {f.name: np.zeros(L.shape_of(f, dims), dtype=f.dtype)
             for f in L.FIELDS if f.fill is None}
    S = L.allocate(dims, given)
    S[L.FREE][:] = np.arange(CAP)[::-1]
    S[L.INTS][CO.I_FREE] = CAP
    S[L.POOL_FREE][:] = np.arange(4)[::-1]
    S[L.INTS][CO.I_PFREE] = 4
    S[L.FPARAMS][:] = (0.0, 100.0)
    S[L.IPARAMS][CO.Q_N] = 2
    S[L.IPARAMS][CO.Q_CHAN] = 1
    S[L.DRAW_MAP][:] = -1  # every draw a constant
    S[L.DRAW_CONST][CO.LAT_HU] = 0.5
    S[L.LINK_OF][:] = (0, 1, 2)
    S[L.LINK_SPB][1, :] = 0.01
    S[L.WIRE_BYTES][CO.K_STATE] = 10
    return S


def _alloc(S: tuple[Any, ...], who: int) -> int:
    """A free event slot, taken off the free list, its receiver ``who`` (a label)."""
    iv = S[L.INTS]
    iv[CO.I_FREE] -= 1
    s = int(S[L.FREE][iv[CO.I_FREE]])
    S[L.EV_INT][s, CO.E_TYPE] = CO.EV_CLIENT
    S[L.EV_INT][s, CO.E_WHO] = who
    return s


def _drain(S: tuple[Any, ...]) -> Out:
    """Take every event as the loop does (a token: its channel's head, then back in the
    queue); return (time, sequence number, receiver) in the order taken."""
    out: Out = []
    qi = S[L.Q_INT]
    evi = S[L.EV_INT]
    while True:
        t = peek(S)
        if not qi[CO.QI_HAS]:
            return out
        c = int(qi[CO.QI_CUR])
        p = int(S[L.RUN_POS][c])
        key = int(S[L.RUN_K][p])
        s = int(take_head(S))
        if evi[s, CO.E_TYPE] == CO.EV_CHAN:
            e = int(take(S, s))
            out.append((float(t), key >> CO.SLOT_BITS, int(evi[e, CO.E_WHO])))
            release(S, e)
            if not requeue(S, s, c, p):
                release(S, s)
        else:
            out.append((float(t), key >> CO.SLOT_BITS, int(evi[s, CO.E_WHO])))
            release(S, s)


def test_hops_over_fifo_links_join_the_up_channel_unless_out_of_order() -> None:
    """Three states leave at t = 0: two from client 0 (its link serializes them: done at
    0.1 and 0.2, arrivals 0.6 and 0.7, sequence 0 and 1), one from client 1 (its own
    link: done 0.1, arrival 0.6, sequence 2). The first makes the channel's token, the
    second joins the ring, the third is earlier than the ring's last: a plain event.
    Hand-computed order: 0.6 by sequence (0, then 2), then 0.7."""
    S = _state()
    slots = []
    for client in (0, 0, 1):
        s = _alloc(S, 0)
        address(S, s, CO.EV_BROKER, client, CO.K_STATE, client, 7)
        slots.append(s)
        assert hop(S, s, 0.0) == (pytest.approx(0.6 + 0.1 * (len(slots) == 2)), False)
    ci = S[L.CH_INT][1]
    assert (ci[CO.CH_USED], ci[CO.CH_OOO], ci[CO.CH_FULL]) == (2, 1, 0)
    assert S[L.CH_T][1, :2].tolist() == [0.1 + 0.5, 0.2 + 0.5]
    assert (S[L.CH_K][1, :2] & CO.SLOT_MASK).tolist() == slots[:2]
    assert S[L.CH_INT][0, CO.CH_USED] == 0  # nothing went down
    assert S[L.INTS][CO.I_EID] == S[L.INTS][CO.I_NEV] == 3
    order = _drain(S)
    assert [(round(t, 12), e) for t, e, _ in order] == [(0.6, 0), (0.6, 2), (0.7, 1)]
    assert S[L.LINK_BUSY][1, :2].tolist() == [0.2, 0.1]
    assert ci[CO.CH_RUN] == 2 and ci[CO.CH_TOKEN] == -1
    assert S[L.INTS][CO.I_FREE] == CAP  # every slot back, the token's too


def test_a_token_goes_back_in_place_while_plain_events_fall_between() -> None:
    """Channel 0 gets arrivals 1.0, 2.0, 2.0, 3.0 (sequence 0, 1, 2, 5) and one at 1.8
    after them (sequence 6: out of order, a plain event); plain events at 1.5 (3) and
    2.5 (4). Taken by (time, sequence): 1.0, 1.5, 1.8, 2.0 (1), 2.0 (2), 2.5, 3.0; the
    token, in a run of its own, goes back in place every time (never moved)."""
    S = _state()
    for t, who in ((1.0, 10), (2.0, 11), (2.0, 12)):
        arrive(S, 0, t, _alloc(S, who))
    push(S, 1.5, _alloc(S, 13))
    push(S, 2.5, _alloc(S, 14))
    arrive(S, 0, 3.0, _alloc(S, 15))
    arrive(S, 0, 1.8, _alloc(S, 16))
    ci = S[L.CH_INT][0]
    assert (ci[CO.CH_USED], ci[CO.CH_OOO]) == (4, 1)
    qi = S[L.Q_INT]
    assert (qi[CO.QI_NRUN], qi[CO.QI_HEAP], qi[CO.QI_PN]) == (1, 1, 3)  # token's run; 3 plain
    assert _drain(S) == [(1.0, 0, 10), (1.5, 3, 13), (1.8, 6, 16), (2.0, 1, 11),
                         (2.0, 2, 12), (2.5, 4, 14), (3.0, 5, 15)]
    assert (ci[CO.CH_RUN], ci[CO.CH_MOVE], ci[CO.CH_USED]) == (4, 0, 0)
    assert S[L.INTS][CO.I_FREE] == CAP


def test_a_full_ring_queues_plain_events() -> None:
    """A ring of 2: arrivals 1, 2 fill it, 3 and 4 are plain events (in order, but no
    room); the order is the specification's all the same."""
    S = _state(bat=2)
    for t in (1.0, 2.0, 3.0, 4.0):
        arrive(S, 0, t, _alloc(S, int(t)))
    ci = S[L.CH_INT][0]
    assert (ci[CO.CH_USED], ci[CO.CH_FULL], ci[CO.CH_OOO]) == (2, 2, 0)
    assert _drain(S) == [(1.0, 0, 1), (2.0, 1, 2), (3.0, 2, 3), (4.0, 3, 4)]
    arrive(S, 0, 5.0, _alloc(S, 5))  # the ring wraps: its head is back at row 0
    assert (ci[CO.CH_HEAD], ci[CO.CH_USED]) == (0, 1)
    assert _drain(S) == [(5.0, 4, 5)]


def test_a_token_in_the_pending_buffer_moves_into_a_run_of_its_own() -> None:
    """No room at the arena's top: the new token joins the pending buffer and is sealed
    with the plain events (1.0 token, 1.5 plain, 3.0 plain). After 1.0 its next element,
    2.0, is behind the run's 1.5: it moves into a run of its own (once), then goes back
    in place."""
    S = _state(arena=40)
    S[L.Q_INT][CO.QI_ATOP] = 40
    arrive(S, 0, 1.0, _alloc(S, 10))
    assert S[L.Q_INT][CO.QI_PN] == 1  # the token, pending
    push(S, 1.5, _alloc(S, 11))
    push(S, 3.0, _alloc(S, 12))
    arrive(S, 0, 2.0, _alloc(S, 13))
    arrive(S, 0, 2.5, _alloc(S, 14))
    assert _drain(S) == [(1.0, 0, 10), (1.5, 1, 11), (2.0, 3, 13), (2.5, 4, 14),
                         (3.0, 2, 12)]
    assert S[L.CH_INT][0, CO.CH_MOVE] == 1


def _tally(sc: Any, method: str) -> tuple[dict[str, int], dict[str, float]]:
    run = MethodRun(replace(sc, engine="cohort").run_spec(), method, make_dynamics(sc),
                    make_behaviour(sc), compiled=True)
    out = run.run()
    return breakdown(run.core.S), out["metrics"]  # type: ignore[attr-defined]


def _events(b: dict[str, int]) -> dict[str, int]:
    """The events run, by class (batched or not)."""
    return {k: v for k, v in b.items() if k in CLASSES}


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Equal metric dicts, bit for bit (NaN equal to NaN)."""
    return a.keys() == b.keys() and all(
        a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]) for k in a)


@pytest.mark.parametrize("method", ["bides", "lockstep"])
def test_channels_on_or_off_run_the_same_events_and_results(
    method: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Commands on, constant latencies (hosts' links 1 ms, the server's 0.5 ms): with
    channels most state, command and re-request deliveries and broker arrivals run from a
    channel, the others one by one because they arrived out of order; switched off, the
    same events run one by one, with the same metrics bit for bit."""
    sc = tiny(nodes=6, hosts=2, duration=1.0, **{"commands.enabled": True})
    on, m_on = _tally(sc, method)
    assert on["chan_on"] == 1 and on["total"] > 1000
    for cls in ("state_deliv", "command_deliv", "broker_arrival"):
        assert on[cls + "_batched"] > 0.5 * on[cls], cls
    # a hop run one by one was queued so (out of order, or a full ring); some queued so
    # may still be in flight at the end
    down = sum(on[c] - on[c + "_batched"] for c in ("state_deliv", "command_deliv",
                                                    "rereq_deliv"))
    assert 0 < down <= on["down_out_of_order"] + on["down_full"]
    up = on["broker_arrival"] - on["broker_arrival_batched"]
    assert up <= on["up_out_of_order"] + on["up_full"]
    assert on["job_end_batched"] == 0
    monkeypatch.setattr(channel, "ENABLED", False)
    off, m_off = _tally(sc, method)
    assert off["chan_on"] == 0
    assert _events(on) == _events(off)  # the same events, by class
    assert off["batched"] == off["bcast_deliv_batched"]  # only the fan-out's
    assert _same(m_on, m_off)


def test_lossy_jittered_hops_through_channels_identical() -> None:
    """Loss, a jitter wider than the broker's delivery service and a degraded host
    (datagram, QoS 0): hops lost (no sequence number), out of order (plain events) and
    in channels, bit-identical to the per-message engine."""
    sc = tiny(nodes=12, hosts=3, placement="round_robin", duration=1.0, **{
        "net.transport": "datagram", "net.qos": 0, "net.host_link.loss": {"p": 0.1},
        "net.host_link.latency": {"dist": "uniform", "low": 0.0002, "high": 0.0003},
        "broker.delivery_service": 0.00005, "commands.enabled": True,
        "faults": [{"kind": "degrade", "host": 1, "start": 0.3, "end": 0.6,
                    "extra_delay": 0.002, "extra_loss": 0.2}]})
    for method in ("bides", "lockstep"):
        _ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"
        b, _m = _tally(sc, method)
        assert b["chan_on"] == 1
        assert b["up_out_of_order"] > 0 and b["down_out_of_order"] > 0
        assert b["broker_arrival_batched"] > 0 and b["state_deliv_batched"] > 0


def test_default_comparison_metrics_do_not_depend_on_channels(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The default scenario at 20 nodes, 0.5 s: each method's metrics with channels on
    and off are equal."""
    sc = replace(tiny(nodes=20, hosts=1, duration=0.5, warmup=0.1), engine="cohort")
    on = {m: run_method(sc, m)["metrics"] for m in ("none", "hlc")}
    monkeypatch.setattr(channel, "ENABLED", False)
    off = {m: run_method(sc, m)["metrics"] for m in ("none", "hlc")}
    assert all(_same(on[m], off[m]) for m in on)
