"""The cohort core reproduces the transports exactly (docs/concepts/engines.md).

MQTT QoS 1 over datagram: resends after a lost or late PUBLISH, lost or late PUBACKs
(a resend only while the sender's timer still runs), redeliveries by the broker,
give-ups after ``max_retries`` and the duplicates they make. The stream transport on
a link with loss or random latency: in-order hold-back, RTO retries, give-ups. Each
case runs on both engines, whose whole results must be identical, and checks that it
really exercises those paths.
"""

from __future__ import annotations

from typing import Any

import pytest

import sigma_des.events.fast.attempts as attempts
from sigma_des.events.fast.support import unsupported
from tests.conftest import tiny
from tests.events.test_cohort import run_both

#: QoS 1 over datagram with heavy loss and a timeout inside the latency's range, so
#: PUBLISHes and PUBACKs are lost and late both.
_LOSSY: dict[str, Any] = {
    "nodes": 6,
    "net.transport": "datagram",
    "net.qos": 1,
    "net.host_link.loss": {"p": 0.2},
    "net.server_link.loss": {"p": 0.1},
    "net.host_link.latency": {"dist": "uniform", "low": 0.0002, "high": 0.004},
    "net.qos1_timeout": 0.003,
    "net.max_retries": 2,
    "commands.enabled": True,
}


@pytest.mark.parametrize("method", ["none", "lockstep", "hlc", "bides"])
def test_qos1_datagram_resends_and_give_ups_identical(method: str) -> None:
    sc = tiny(**_LOSSY)
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    assert m["retransmissions"] > 0 and m["gave_up"] > 0 and m["duplicates"] > 0


def test_qos1_datagram_late_not_lost_identical() -> None:
    """No loss, but every PUBLISH arrives after the timeout: resent until given up."""
    sc = tiny(**{**_LOSSY, "net.host_link.loss": {"p": 0.0}, "net.server_link.loss": {"p": 0.0},
                 "net.host_link.latency": 0.004, "net.qos1_timeout": 0.002})
    ev, co = run_both(sc, "bides")
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    assert m["retransmissions"] > 0 and m["gave_up"] > 0 and m["duplicates"] > 0


def test_qos1_datagram_without_retries_only_gives_up() -> None:
    sc = tiny(**{**_LOSSY, "net.max_retries": 0})
    ev, co = run_both(sc, "none")
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    assert m["retransmissions"] == 0 and m["gave_up"] > 0 and m["duplicates"] == 0


def test_attempt_draws_refilled_on_demand(monkeypatch: pytest.MonkeyPatch) -> None:
    """One row for all later attempts: every resend's draws are refilled before use."""
    monkeypatch.setattr(attempts, "X_ROWS", 1)
    ev, co = run_both(tiny(**{**_LOSSY, "nodes": 4, "duration": 0.6}), "hlc")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] > 0


#: A stream on lossy links with random latency: reordered arrivals are held back, lost
#: segments retried after the doubling RTO or given up.
_STREAM: dict[str, Any] = {
    **_LOSSY,
    "net.transport": "stream",
    "net.rto": 0.003,
    "net.server_link.latency": {"dist": "exponential", "mean": 0.001},
}


@pytest.mark.parametrize(("method", "qos"), [("none", 0), ("lockstep", 1), ("hlc", 0),
                                             ("bides", 1)])
def test_stream_with_loss_retries_and_give_ups_identical(method: str, qos: int) -> None:
    sc = tiny(**{**_STREAM, "net.qos": qos})
    assert unsupported(sc.run_spec(), method) is None
    ev, co = run_both(sc, method)
    assert co["engine"]["used"] == "cohort"
    m = ev["metrics"]
    assert m["retransmissions"] > 0 and m["gave_up"] > 0
    assert m["duplicates"] == 0  # a stream delivers a segment once, or never


def test_stream_with_random_latency_only_identical() -> None:
    """No loss: nothing is retried, but reordered segments are held back."""
    sc = tiny(**{**_STREAM, "net.host_link.loss": {"p": 0.0}, "net.server_link.loss": {"p": 0.0}})
    ev, co = run_both(sc, "bides")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] == 0 and ev["metrics"]["gave_up"] == 0


#: Link features of the core on top: a Gilbert–Elliott server link, a lossy degrade
#: window and a dropped state (its first transmission), on both transports.
_LINK_FAULTS: dict[str, Any] = {
    "net.server_link.loss": {"model": "gilbert_elliott", "p_gb": 0.1, "p_bg": 0.4,
                             "loss_good": 0.01, "loss_bad": 0.6, "slot": 0.004},
    "faults": [{"kind": "degrade", "host": 1, "start": 0.2, "end": 0.6, "extra_delay": 0.002,
                "extra_loss": 0.3},
               {"kind": "drop", "node": 1, "frame": 30, "message": "state"}],
}


@pytest.mark.parametrize("base", [_LOSSY, _STREAM], ids=["qos1-datagram", "stream"])
def test_transports_with_link_faults_identical(base: dict[str, Any]) -> None:
    sc = tiny(**{**base, **_LINK_FAULTS})
    assert unsupported(sc.run_spec(), "bides") is None
    ev, co = run_both(sc, "bides")
    assert co["engine"]["used"] == "cohort"
    assert ev["metrics"]["retransmissions"] > 0 and ev["metrics"]["gave_up"] > 0
