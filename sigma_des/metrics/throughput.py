"""Throughput: wire bits per second on the links, in the metrics window (docs/concepts/metrics.md).

Every packet on every link direction counts with all its overheads (headers,
framing), as the network counted it in :class:`~sigma_des.metrics.reports.NetReport`.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["link_mbps", "mbps", "throughput"]

#: ``(name, bytes, packets)`` of one link direction.
Link = tuple[str, float, float]


def mbps(nbytes: float, window: float) -> float:
    """``nbytes`` wire bytes over ``window`` seconds, in Mbit/s."""
    return nbytes * 8 / window / 1e6


def throughput(links: Sequence[Link], window: float) -> dict[str, float]:
    """The network's throughput metrics: all links, the busiest link, packets per second.

    Args:
        links: every link direction's counters.
        window: the metrics window (s).
    """
    return {
        "throughput_mbps": mbps(sum(nbytes for _name, nbytes, _p in links), window),
        "throughput_max_link_mbps": mbps(max(nbytes for _name, nbytes, _p in links), window),
        "packets_per_s": sum(packets for _name, _b, packets in links) / window,
    }


def link_mbps(links: Sequence[Link], window: float) -> dict[str, float]:
    """Mbit/s of every link direction, by name."""
    return {name: mbps(nbytes, window) for name, nbytes, _p in links}
