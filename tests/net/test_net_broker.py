"""The broker room: FIFO service times, PUBACK timing and the metrics window, by hand."""

from __future__ import annotations

from sigma_des.core.rng import RandomStreams
from sigma_des.net.broker import Broker
from sigma_des.net.latency import Dist
from sigma_des.net.spec import BrokerSpec


def _broker(warmup: float = 1.0, end: float = 3.0) -> Broker:
    # dyadic service times: every sum below is exact in binary floating point
    spec = BrokerSpec(
        publish_service=Dist(dist="constant", value=0.5),
        delivery_service=Dist(dist="constant", value=0.25),
    )
    return Broker(spec, RandomStreams(1), clients=4, warmup=warmup, end=end)


def test_publish_then_deliveries_in_service_order() -> None:
    b = _broker()
    t_ack, departs = b.serve_publish(0.5, 1, 3, 0, 0, [0, 1, 2])
    # PUBACK after the publish part; delivery j after the publish part and j+1 deliveries
    assert t_ack == 1.0
    assert departs == [1.25, 1.5, 1.75]
    assert b.busy == 1.75  # free when the last delivery leaves
    # arrived before the window: its wait is not counted; its work only from warmup on
    assert b.max_wait == 0.0
    assert b.work == 0.75


def test_fifo_wait_redelivery_and_window_end() -> None:
    b = _broker()
    b.serve_publish(0.5, 1, 3, 0, 0, [0, 1])  # busy until 1.5, work 0.5 in the window
    t_ack, departs = b.serve_publish(1.0, 2, 0, 0, 0, [3])  # waits 0.5 for the server
    assert (t_ack, departs, b.max_wait) == (2.0, [2.25], 0.5)
    assert b.serve_delivery(2.0, 2, 0, 0, 1) == 2.5  # a QoS 1 resend queues behind
    t_ack, departs = b.serve_publish(2.75, 1, 3, 1, 0, [])  # no subscribers
    assert (t_ack, departs, b.busy) == (3.25, [], 3.25)
    # work: 0.5 + 0.75 + 0.25 + (3.0 - 2.75): nothing after the window's end
    assert b.work == 1.75


def test_service_draws_are_keyed_not_ordered() -> None:
    spec = BrokerSpec(
        publish_service=Dist(dist="exponential", mean=1e-4),
        delivery_service=Dist(dist="exponential", mean=1e-4),
    )
    a = Broker(spec, RandomStreams(7), clients=3, warmup=0.0, end=10.0)
    b = Broker(spec, RandomStreams(7), clients=3, warmup=0.0, end=10.0)
    first = a.delivery_draws.get(2, 1, 5, 0)
    b.delivery_draws.get(2, 0, 9, 0)  # another draw first changes nothing
    assert b.delivery_draws.get(2, 1, 5, 0) == first
    assert a.delivery_draws.get(2, 1, 5, 1) != first  # the attempt is part of the key
