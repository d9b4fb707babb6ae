"""The message record: a resend and a broker's copy are new records, never edits."""

from __future__ import annotations

from sigma_des.net.kinds import TRIGGER
from sigma_des.net.message import Msg


def _msg() -> Msg:
    return Msg(5, TRIGGER, 5, 12, ("payload",), 96, (0, 1, 2), 0, 0.25, 0.25)


def test_resent_is_the_next_try_of_the_same_hop() -> None:
    m = _msg()
    r = m.resent()
    assert r is not m and m.attempt == 0  # the record in flight is untouched
    assert (r.client, r.kind, r.subject, r.index, r.bits, r.subs, r.attempt, r.t_pub) == (
        5, TRIGGER, 5, 12, 96, (0, 1, 2), 1, 0.25)
    assert r.payload is m.payload
    assert r.resent().attempt == 2


def test_to_is_the_brokers_first_try_towards_one_subscriber() -> None:
    m = _msg().resent()  # a resent PUBLISH: its deliveries still start at attempt 0
    d = m.to(2, 2, 0.75)
    assert (d.client, d.kind, d.subject, d.index, d.subs, d.attempt, d.t_pub, d.t_sent) == (
        2, TRIGGER, 2, 12, (), 0, 0.25, 0.75)
    assert "client=2" in repr(d) and "attempt=0" in repr(d)
