"""The network layer's own specs: links, MQTT transport, broker, DDS, and the topology.

Frozen, validated dataclasses. :class:`~sigma_des.config.Scenario` embeds the first
four as its ``[net]`` (with ``host_link`` / ``server_link``), ``[broker]`` and
``[dds]`` tables and builds a :class:`NetSetup` (``Scenario.net_setup``) for a
run: the net takes that setup, never the scenario. Validation happens on
construction and raises :class:`~sigma_des.errors.ConfigError` with the local
field name (the scenario loader prefixes the dotted path).

DDS defaults name their source (docs/concepts/peers.md):

Sources:
    [RTPS]  OMG DDS Interoperability Wire Protocol (DDSI-RTPS) 2.5, §8.3 (message
            structure), §9.4 (submessage layouts), §8.4 (reliable behaviour), §8.5
            (SPDP/SEDP discovery).
    [FDDS]  eProsima Fast DDS API reference: ``WriterTimes`` (heartbeat_period 3 s,
            nack_response_delay 5 ms), ``ReaderTimes`` (heartbeat_response_delay 5 ms),
            ``DiscoverySettings`` (leaseDuration_announcementperiod 3 s),
            ``InitialAnnouncementConfig`` (count 5, period 100 ms); Fast DDS docs
            "SIMPLE discovery settings" (SPDP over multicast, user data unicast).
    [ROS2]  ``rmw_qos_profile_default``: RELIABLE, KEEP_LAST, depth 10, VOLATILE.
    [EXEC]  ROS Discourse, "SingleThreadedExecutor creates a high CPU overhead in
            ROS 2" (2019): with many messages ``get_next_ready_executable`` (a scan
            over the executor's entities) takes up to ~30 % of a core at 10 000
            messages/s, i.e. ~30 µs per message; rclcpp's later executors avoid
            rebuilding the entity list, but the default one scans it per dispatch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sigma_des.core.validate import require, require_in, require_nonneg, require_positive
from sigma_des.net.deployment import CLIENTS, PRESETS, DeploymentSpec
from sigma_des.net.latency import Dist
from sigma_des.net.loss import LossSpec

__all__ = [
    "BrokerSpec",
    "CLIENTS",
    "DdsSpec",
    "DeploymentSpec",
    "LinkDegrade",
    "LinkSpec",
    "MAX_RETRIES",
    "MIDDLEWARES",
    "NetSetup",
    "NetSpec",
    "PRESETS",
    "Topology",
]

#: Largest ``net.max_retries``.
MAX_RETRIES = 100
#: ``net.middleware`` choices: an MQTT broker, or brokerless DDS/RTPS.
MIDDLEWARES: tuple[str, ...] = ("mqtt", "dds")


@dataclass(frozen=True)
class LinkSpec:
    """A host's access link to the broker (both directions alike unless ``latency_down``).

    Attributes:
        latency: base one-way latency distribution of a packet on this link (s), in
            both directions unless ``latency_down`` is given.
        bandwidth_mbps: link rate; serialization = wire bits / rate, FIFO per direction.
        loss: packet loss model of this link.
        latency_down: base latency of the down direction only (broker -> this link's
            clients); absent (None): ``latency``. ``sigma-des calibrate`` sets it, since
            live triggers and states do not take the same time.
    """

    latency: Dist = field(default_factory=lambda: Dist(dist="constant", value=0.00025))
    bandwidth_mbps: float = 1000.0
    loss: LossSpec = field(default_factory=LossSpec)
    latency_down: Dist | None = None

    def __post_init__(self) -> None:
        require_positive(self, "bandwidth_mbps")
        down = self.latency_down
        if down is not None:
            lossless = self.loss.model == "bernoulli" and self.loss.p == 0.0
            # the compiled core decides per link (from `latency`), not per direction,
            # whether a lossless stream can reorder: a random down direction behind a
            # constant `latency` would be delivered out of order there
            require(
                not (lossless and self.latency.dist == "constant"
                     and down.dist != "constant"),
                "latency_down",
                f"a random down latency ({down.dist!r}) on a lossless link needs a random "
                "`latency` too (give the up direction as a distribution, e.g. uniform with "
                "low = high)",
            )

    def latency_of(self, up: bool) -> Dist:
        """The base latency of one direction (``up``: client -> broker)."""
        return self.latency if up or self.latency_down is None else self.latency_down


@dataclass(frozen=True)
class NetSpec:
    """Network: per-link impairments, transport, MQTT QoS and framing overheads.

    Attributes:
        host_link: links of the physics hosts.
        server_link: link of the server host (interface + alignment server + renderer).
        transport: ``datagram`` (a lost packet is gone) or ``stream`` (TCP-like).
        qos: MQTT QoS, 0 or 1.
        rto: stream transport: retransmission timeout of a lost segment (s).
        qos1_timeout: datagram + QoS 1: resend with DUP if no PUBACK after this (s).
        max_retries: resends of one packet before giving up (stream and QoS 1),
            0..``MAX_RETRIES`` (100).
        tcpip_bytes: TCP/IP header bytes per packet.
        ethernet_bytes: Ethernet framing bytes per packet (header, FCS, preamble, gap).
        topic_bytes: MQTT topic length in bytes.
        middleware: ``mqtt`` (a broker relays every message) or ``dds`` (brokerless
            DDS/RTPS over UDP, parameters in ``[dds]``; needs ``transport =
            "datagram"`` and ``qos = 0``: RTPS brings its own reliability).
    """

    host_link: LinkSpec = field(default_factory=LinkSpec)
    server_link: LinkSpec = field(default_factory=LinkSpec)
    transport: str = "stream"
    qos: int = 1
    rto: float = 0.2
    qos1_timeout: float = 0.1
    max_retries: int = 5
    tcpip_bytes: int = 40
    ethernet_bytes: int = 38
    topic_bytes: int = 8
    middleware: str = "mqtt"

    def __post_init__(self) -> None:
        require(
            self.middleware in ("mqtt", "dds"),
            "middleware",
            f"must be 'mqtt' or 'dds', got {self.middleware!r}",
        )
        if self.middleware == "dds":
            require(
                self.transport == "datagram",
                "transport",
                "middleware 'dds' runs RTPS over UDP: must be 'datagram', got "
                f"{self.transport!r}",
            )
            require(
                self.qos == 0, "qos", f"is MQTT's: with middleware 'dds' must be 0, got {self.qos}"
            )
        require(
            self.transport in ("datagram", "stream"),
            "transport",
            f"must be 'datagram' or 'stream', got {self.transport!r}",
        )
        require(self.qos in (0, 1), "qos", f"must be 0 or 1, got {self.qos}")
        require_positive(self, "rto", "qos1_timeout")
        require_nonneg(self, "tcpip_bytes", "ethernet_bytes")
        # every resend is an event: beyond a few dozen a packet is long given up in practice
        require_in(self, "max_retries", 0, MAX_RETRIES)
        require(
            1 <= self.topic_bytes <= 65535,
            "topic_bytes",
            f"must be in 1..65535, got {self.topic_bytes}",
        )


@dataclass(frozen=True)
class BrokerSpec:
    """Single-threaded MQTT broker: service time per inbound PUBLISH and per delivery."""

    publish_service: Dist = field(default_factory=lambda: Dist(dist="constant", value=4e-6))
    delivery_service: Dist = field(default_factory=lambda: Dist(dist="constant", value=3e-6))



@dataclass(frozen=True)
class DdsSpec:
    """DDS/RTPS middleware (Fast DDS defaults under ROS 2, see the module's sources).

    Every participant (each physics node, and the server) has one middleware thread
    that serves, first come first served, every send and receive of that
    participant; its CPU costs are the ``*_cost`` fields.

    Attributes:
        writer_cost: CPU per DATA sent, per destination (serialize + one UDP send);
            estimate of the order of Fast DDS's small-message send path (s).
        reader_cost: CPU per DATA received (receive, deserialize, add to the reader
            history, hand to the callback); estimate (s).
        meta_cost: CPU per metatraffic submessage handled (HEARTBEAT, ACKNACK, one
            SPDP announcement, one SEDP endpoint record); estimate (s).
        executor_per_entity: CPU per message dispatch per executor entity of the
            receiving participant (the wait-set scan of rclcpp's default executor,
            [EXEC]: ~30 µs per message over ~20 entities ≈ 1.5 µs; we take 1 µs) (s).
        endpoints: DDS endpoints (and executor entities) every ROS 2 node has besides
            the simulation's topics: 6 parameter services × request/response = 12,
            /parameter_events pub + sub, /rosout pub, ros_discovery_info = 16.
        multicast: user data to several readers as one multicast send (default False:
            Fast DDS sends user data unicast, one send per matched reader [FDDS]).
        reliable: RELIABLE reliability [ROS2]; False = BEST_EFFORT (no heartbeats).
        history_depth: KEEP_LAST depth of every writer's history [ROS2]: a sample
            NACKed after ``history_depth`` newer ones were written cannot be resent
            (the reader gets a GAP; counted in ``gave_up``).
        heartbeat_period: periodic HEARTBEAT of a reliable writer to each matched
            reader (s) [FDDS ``WriterTimes.heartbeat_period`` = 3 s].
        heartbeat_response_delay: reader's delay before its ACKNACK (s) [FDDS 5 ms].
        nack_response_delay: writer's delay before resending NACKed samples (s)
            [FDDS 5 ms].
        spdp_period: participant announcement period (s) [FDDS
            ``leaseDuration_announcementperiod`` = 3 s].
        spdp_initial_count: fast initial announcements [FDDS 5].
        spdp_initial_period: their period (s) [FDDS 100 ms].
        spdp_bytes: SPDP DATA(p) submessage with its parameter list (B); estimate of
            a Fast DDS participant announcement with a few locators.
        sedp_bytes: one SEDP DATA(w)/DATA(r) endpoint record (topic, type, QoS) (B);
            estimate.
        udpip_bytes: UDP + IPv4 headers per datagram (8 + 20).
    """

    writer_cost: Dist = field(default_factory=lambda: Dist(dist="constant", value=15e-6))
    reader_cost: Dist = field(default_factory=lambda: Dist(dist="constant", value=20e-6))
    meta_cost: float = 5e-6
    executor_per_entity: float = 1e-6
    endpoints: int = 16
    multicast: bool = False
    reliable: bool = True
    history_depth: int = 10
    heartbeat_period: float = 3.0
    heartbeat_response_delay: float = 0.005
    nack_response_delay: float = 0.005
    spdp_period: float = 3.0
    spdp_initial_count: int = 5
    spdp_initial_period: float = 0.1
    spdp_bytes: int = 300
    sedp_bytes: int = 200
    udpip_bytes: int = 28

    def __post_init__(self) -> None:
        require_nonneg(
            self, "meta_cost", "executor_per_entity", "endpoints", "spdp_initial_count",
            "udpip_bytes",
        )
        require(self.history_depth >= 1, "history_depth", f"must be >= 1, got {self.history_depth}")
        require_positive(
            self, "heartbeat_period", "spdp_period", "spdp_initial_period",
        )
        require_nonneg(self, "heartbeat_response_delay", "nack_response_delay")
        for name in ("spdp_bytes", "sedp_bytes"):
            v = getattr(self, name)
            require(1 <= v <= 65507, name, f"must be in 1..65507 (one UDP datagram), got {v}")


@dataclass(frozen=True)
class Topology:
    """Where the clients sit: ``nodes`` physics nodes on ``hosts`` hosts, plus the server.

    Clients ``0..nodes-1`` are the physics nodes; client ``nodes`` is the server
    (interface, alignment server, renderer) on a host of its own. Access link
    ``h < hosts`` is physics host ``h``'s; link ``hosts`` is the server's.

    Attributes:
        nodes: number of physics nodes, >= 1.
        hosts: number of physics hosts, 1..nodes.
        host_of: host index of every node (length ``nodes``, each in 0..hosts-1).
    """

    nodes: int
    hosts: int
    host_of: tuple[int, ...]

    def __post_init__(self) -> None:
        require(self.nodes >= 1, "nodes", f"must be >= 1, got {self.nodes}")
        require(
            1 <= self.hosts <= self.nodes,
            "hosts",
            f"must be in 1..nodes ({self.nodes}), got {self.hosts}",
        )
        require(
            len(self.host_of) == self.nodes,
            "host_of",
            f"must name a host for each of the {self.nodes} nodes, got {len(self.host_of)}",
        )
        for i, h in enumerate(self.host_of):
            require(
                0 <= h < self.hosts, f"host_of[{i}]", f"must be in 0..{self.hosts - 1}, got {h}"
            )

    @property
    def server(self) -> int:
        """Client index of the server (``nodes``)."""
        return self.nodes

    @property
    def link_of(self) -> list[int]:
        """Access link of every client: its host for a node, ``hosts`` for the server."""
        return [*self.host_of, self.hosts]


@dataclass(frozen=True)
class LinkDegrade:
    """A host link's extra delay and loss over ``[start, end)`` (a ``degrade`` fault).

    Attributes:
        host: the degraded link (a physics host index, or ``hosts`` for the server's).
        start: start time (s).
        end: end time (s).
        extra_delay: extra one-way delay (s), >= 0.
        extra_loss: extra loss probability in [0, 1).
    """

    host: int
    start: float
    end: float
    extra_delay: float = 0.0
    extra_loss: float = 0.0

    def __post_init__(self) -> None:
        require(self.end > self.start, "end", f"must be > start ({self.start}), got {self.end}")
        require_nonneg(self, "extra_delay")
        require(0 <= self.extra_loss < 1, "extra_loss", f"must be in [0, 1), got {self.extra_loss}")


@dataclass(frozen=True)
class NetSetup:
    """Everything the net layer takes from a run (built by ``Scenario.net_setup``).

    Attributes:
        net: links, transport, MQTT QoS and framing.
        broker: the MQTT broker's service times.
        dds: DDS/RTPS parameters (used with ``net.middleware = "dds"``).
        topology: nodes, hosts and the placement of nodes on hosts.
        warmup: traffic before this time is not counted (s).
        end: traffic leaving at or after this time is not counted (the run's end, s).
        degrades: link degradations (``degrade`` faults).
        drops: ``(kind, subject, index)`` of messages whose first transmission on the
            broker-to-receiver hop is lost (``drop`` faults).
        deployment: machines, CPU demands and MQTT clients (default: no CPU stage,
            one client per node).
    """

    net: NetSpec
    broker: BrokerSpec
    dds: DdsSpec
    topology: Topology
    warmup: float
    end: float
    degrades: tuple[LinkDegrade, ...] = ()
    drops: frozenset[tuple[int, int, int]] = frozenset()
    deployment: DeploymentSpec = field(default_factory=DeploymentSpec)

    def __post_init__(self) -> None:
        require(0 <= self.warmup, "warmup", f"must be >= 0 s, got {self.warmup}")
        require(self.end > 0, "end", f"must be > 0 s, got {self.end}")
        for i, d in enumerate(self.degrades):
            require(
                0 <= d.host <= self.topology.hosts,
                f"degrades[{i}].host",
                f"must be in 0..{self.topology.hosts}, got {d.host}",
            )
