"""Typed results: what each component of a run reports to the collector at the end.

Every component hands over its own small frozen dataclass through one hook
(``report()`` on the aligner, :meth:`NetReport.of` for the network's public
counters, the engine's :class:`RunReport`); :meth:`~sigma_des.metrics.collector.
Collector.finish` turns them into the tidy result rows (docs/concepts/metrics.md).
Nothing here knows which engine, aligner or network produced them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol

__all__ = ["AlignerReport", "LinkCount", "MethodReport", "NetCounters", "NetReport",
           "RunReport"]


@dataclass(frozen=True)
class AlignerReport:
    """What the alignment server's method reports.

    Attributes:
        peak_bytes: most bytes of state it buffered at an alignment tick.
        evicted: nodes evicted from a barrier (Lock-Step; 0 otherwise).
        rejoined: evicted nodes that rejoined (Lock-Step; 0 otherwise).
        rerequests: states re-requested (Lock-Step; 0 otherwise).
    """

    peak_bytes: int
    evicted: int = 0
    rejoined: int = 0
    rerequests: int = 0


class LinkCount(NamedTuple):
    """One link direction's counts, as a network reports them (:meth:`NetCounters.links`).

    Attributes:
        name: ``<link>.<up|down>``.
        bytes: wire bytes.
        packets: packets.
    """

    name: str
    bytes: int
    packets: int


class NetCounters(Protocol):
    """The public counters a network (simulated or live) exposes."""

    @property
    def retransmissions(self) -> int:
        """Packets sent again after a loss."""
        ...

    @property
    def gave_up(self) -> int:
        """Packets given up after the last retry."""
        ...

    @property
    def broker_work(self) -> float:
        """The broker's busy time (s)."""
        ...

    @property
    def broker_max_wait(self) -> float:
        """The longest wait of a PUBLISH before its broker service (s)."""
        ...

    def links(self) -> Sequence[Any]:
        """Every link's counters: objects with ``name``, ``bytes`` and ``packets``."""
        ...


@dataclass(frozen=True)
class NetReport:
    """The network's counters at the end of a run.

    Attributes:
        links: ``(name, bytes, packets)`` per link, in the network's order.
        retransmissions: packets sent again after a loss.
        gave_up: packets given up after the last retry.
        broker_work: broker service seconds in the metrics window (NaN: not observable).
        broker_max_wait: longest queueing delay at the broker (s; NaN: not observable).
    """

    links: tuple[tuple[str, float, float], ...]
    retransmissions: int
    gave_up: int
    broker_work: float
    broker_max_wait: float

    @classmethod
    def of(cls, net: NetCounters) -> NetReport:
        """Read a network's public counters."""
        return cls(
            links=tuple((ld.name, ld.bytes, ld.packets) for ld in net.links()),
            retransmissions=net.retransmissions,
            gave_up=net.gave_up,
            broker_work=net.broker_work,
            broker_max_wait=net.broker_max_wait,
        )


@dataclass(frozen=True)
class RunReport:
    """What the engine (or the live server) reports about the run itself.

    Attributes:
        f_trig: trigger rate in force at the end (Hz).
        rollbacks: time-warp rollbacks.
        resim_steps: physics steps re-simulated by rollbacks.
        history_misses: rollbacks whose checkpoint had left the history.
        wall_seconds: wall-clock time of the run (s).
        events: events the scheduler handled.
    """

    f_trig: float
    rollbacks: int
    resim_steps: int
    history_misses: int
    wall_seconds: float
    events: int


@dataclass(frozen=True)
class MethodReport:
    """One method's finished run, as a front end (``compare``, live mode) files it.

    Attributes:
        metrics: the deterministic metrics (``METRIC_UNITS``; fidelity and live
            counters included where they were measured).
        wall: the run's own cost (``WALL_METRICS``).
        links_mbps: wire Mbps of every link direction.
        timeseries: per-render-tick arrays (``t``, ``aoi_mean``, ``f_trig``, ...).
        engine: the engine ``requested`` and ``used`` and why it fell back (``fallback``).
        fidelity: formation error per logged sample (``t``, ``formation_err``); empty
            when not measured.
    """

    metrics: dict[str, float]
    wall: dict[str, float]
    links_mbps: dict[str, float]
    timeseries: dict[str, Any]
    engine: dict[str, str]
    fidelity: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, out: Mapping[str, Any], engine: Mapping[str, str] | None = None) -> MethodReport:
        """From a run's result dict (``run_method``'s, or the live runner's).

        Args:
            out: the result dict (``metrics``, ``wall``, ``links_mbps``, ``timeseries``,
                and ``engine`` and ``fidelity`` where present).
            engine: the engine entry, when ``out`` has none.
        """
        eng = engine if engine is not None else out["engine"]
        return cls(out["metrics"], out["wall"], out["links_mbps"], out["timeseries"],
                   dict(eng), out.get("fidelity", {}))
