"""Parameters of the peer simulators' architectures: DDS/RTPS middleware and AirSim-style RPC.

Two frozen, validated spec classes embedded in :class:`~sigma_des.config.Scenario`
as ``[dds]`` (used when ``net.middleware = "dds"``) and ``[rpc]`` (used by the
``rpc`` method). Every default names its source; where no published figure
exists the value is an estimate and says so (docs/MODEL.md, "Peer architectures").

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
    [AIRSIM] AirSim docs/API (msgpack-rpc over TCP, port 41451; the Python client
            ``msgpackrpc.Client.call`` blocks until the response).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sigma_des.core.validate import require, require_nonneg, require_positive
from sigma_des.net.latency import Dist

__all__ = ["DdsSpec", "MIDDLEWARES"]

#: ``net.middleware`` choices: an MQTT broker, or brokerless DDS/RTPS.
MIDDLEWARES: tuple[str, ...] = ("mqtt", "dds")


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
