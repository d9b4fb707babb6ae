"""Throughput metrics from the links' counters, by hand."""

from __future__ import annotations

from sigma_des.metrics.throughput import link_mbps, mbps, throughput

LINKS = [("host0.up", 250_000.0, 100.0), ("server.up", 125_000.0, 40.0),
         ("server.down", 0.0, 0.0)]


def test_throughput_of_a_two_second_window() -> None:
    # 375 kB over 2 s = 1.5 Mbit/s; the busiest link 250 kB = 1.0 Mbit/s; 140 packets
    assert throughput(LINKS, 2.0) == {
        "throughput_mbps": 1.5,
        "throughput_max_link_mbps": 1.0,
        "packets_per_s": 70.0,
    }
    assert link_mbps(LINKS, 2.0) == {"host0.up": 1.0, "server.up": 0.5, "server.down": 0.0}


def test_mbps_is_wire_bits_per_microsecond() -> None:
    assert mbps(1_000_000, 8.0) == 1.0
    assert mbps(84, 1e-6) == 672.0  # one minimum Ethernet frame per microsecond
