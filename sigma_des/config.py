"""The scenario: one validated, frozen configuration for a whole run (DESIGN §1–3).

Every default lives here (or in the net-layer spec classes it embeds). A scenario
is loaded from TOML and/or ``--set key=value`` overrides through :func:`load`;
an unknown key, a wrong type or an out-of-range value raises
:class:`~sigma_des.errors.ConfigError` naming the dotted key and what is
allowed. :func:`to_toml` prints the full resolved scenario.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from sigma_des.errors import ConfigError
from sigma_des.net.clocks import ClockSpec
from sigma_des.net.latency import Dist
from sigma_des.net.loss import LossSpec

__all__ = [
    "BidesSpec",
    "BrokerSpec",
    "CommandSpec",
    "ComputeSpec",
    "FaultSpec",
    "FidelitySpec",
    "HLCSpec",
    "LinkSpec",
    "LockstepSpec",
    "METHODS",
    "NetSpec",
    "Scenario",
    "config_hash",
    "from_dict",
    "load",
    "parse_set",
    "to_dict",
    "to_toml",
]

#: Alignment methods, in their canonical order.
METHODS: tuple[str, ...] = ("none", "lockstep", "hlc", "bides")
DYNAMICS_BUILTIN: tuple[str, ...] = ("pointmass", "quadrotor", "fixedwing")


def _check(cond: bool, key: str, reason: str) -> None:
    if not cond:
        raise ConfigError(key, reason)


def _positive(obj: Any, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        _check(v > 0 and math.isfinite(v), n, f"must be a finite number > 0, got {v}")


def _nonneg(obj: Any, *names: str) -> None:
    for n in names:
        v = getattr(obj, n)
        _check(v >= 0, n, f"must be >= 0, got {v}")


@dataclass(frozen=True)
class LinkSpec:
    """A host's access link to the broker (both directions alike).

    Attributes:
        latency: base one-way latency distribution of a packet on this link (s).
        bandwidth_mbps: link rate; serialization = wire bits / rate, FIFO per direction.
        loss: packet loss model of this link.
    """

    latency: Dist = field(default_factory=lambda: Dist(dist="constant", value=0.00025))
    bandwidth_mbps: float = 1000.0
    loss: LossSpec = field(default_factory=LossSpec)

    def __post_init__(self) -> None:
        _positive(self, "bandwidth_mbps")


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
        max_retries: resends of one packet before giving up (stream and QoS 1).
        tcpip_bytes: TCP/IP header bytes per packet.
        ethernet_bytes: Ethernet framing bytes per packet (header, FCS, preamble, gap).
        topic_bytes: MQTT topic length in bytes.
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

    def __post_init__(self) -> None:
        _check(
            self.transport in ("datagram", "stream"),
            "transport",
            f"must be 'datagram' or 'stream', got {self.transport!r}",
        )
        _check(self.qos in (0, 1), "qos", f"must be 0 or 1, got {self.qos}")
        _positive(self, "rto", "qos1_timeout")
        _nonneg(self, "max_retries", "tcpip_bytes", "ethernet_bytes")
        _check(
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
class ComputeSpec:
    """Per-node computation: one physics step's CPU time, contending for host cores."""

    step_time: Dist = field(default_factory=lambda: Dist(dist="lognormal", mean=0.0008, std=0.0002))


@dataclass(frozen=True)
class LockstepSpec:
    """Lock-Step barrier parameters.

    Attributes:
        retry_timeout: after this long without a node's state of frame k, re-request it (s).
        eviction_timeout: evict a node missing this long after trigger k (s); 0 = never.
    """

    retry_timeout: float = 0.05
    eviction_timeout: float = 0.0

    def __post_init__(self) -> None:
        _positive(self, "retry_timeout")
        _nonneg(self, "eviction_timeout")


@dataclass(frozen=True)
class HLCSpec:
    """HLC consumer: a node silent this long is treated as dead (0 = never)."""

    liveness_timeout: float = 0.5

    def __post_init__(self) -> None:
        _nonneg(self, "liveness_timeout")


@dataclass(frozen=True)
class BidesSpec:
    """BiDES parts and parameters (each part can be switched off).

    Attributes:
        ring_size: K, states kept per node by the alignment server.
        hole_fill: fill a frame missing from a node's buffer from neighbouring frames.
        lag_exclusion: leave out of the minimum nodes lagging more than ``theta_lag``.
        theta_lag: Θ_lag in frames.
        adaptation: adapt ``f_trig`` to the alignment lag.
        lag_high: lower ``f_trig`` when (latest trigger − aligned frame) > this for
            ``hold_down`` consecutive alignment ticks.
        lag_low: raise it again when the lag < this for ``hold_up`` consecutive ticks.
        rate_down: factor applied when lowering (0 < x < 1).
        rate_up: factor applied when raising (> 1), capped at the nominal ``f_trig``.
        f_trig_min: lowest trigger rate (Hz).
        hold_down: consecutive ticks over ``lag_high`` before lowering.
        hold_up: consecutive ticks under ``lag_low`` before raising.
        time_warp: roll a node back when a command is more than ``theta_warp`` behind.
        theta_warp: Θ_warp in frames.
    """

    ring_size: int = 30
    hole_fill: bool = True
    lag_exclusion: bool = True
    theta_lag: int = 3
    adaptation: bool = True
    lag_high: int = 10
    lag_low: int = 4
    rate_down: float = 0.8
    rate_up: float = 1.1
    f_trig_min: float = 10.0
    hold_down: int = 3
    hold_up: int = 30
    time_warp: bool = True
    theta_warp: int = 10

    def __post_init__(self) -> None:
        _check(
            2 <= self.ring_size <= 100_000,
            "ring_size",
            f"must be in 2..100000, got {self.ring_size}",
        )
        _check(self.theta_lag >= 1, "theta_lag", f"must be >= 1 frame, got {self.theta_lag}")
        _check(self.lag_high >= 1, "lag_high", f"must be >= 1 frame, got {self.lag_high}")
        _check(
            0 <= self.lag_low <= self.lag_high,
            "lag_low",
            f"must be in 0..lag_high ({self.lag_high}), got {self.lag_low}",
        )
        _check(0 < self.rate_down < 1, "rate_down", f"must be in (0, 1), got {self.rate_down}")
        _check(
            self.rate_up > 1 and math.isfinite(self.rate_up),
            "rate_up",
            f"must be > 1, got {self.rate_up}",
        )
        _positive(self, "f_trig_min")
        _check(self.hold_down >= 1, "hold_down", f"must be >= 1, got {self.hold_down}")
        _check(self.hold_up >= 1, "hold_up", f"must be >= 1, got {self.hold_up}")
        _check(self.theta_warp >= 0, "theta_warp", f"must be >= 0, got {self.theta_warp}")


@dataclass(frozen=True)
class CommandSpec:
    """Behaviour commands sent from the server back to the physics nodes.

    Attributes:
        enabled: send commands at all.
        behaviour: behaviour name (see ``sigma_des.agents`` registry).
        every: send at every ``every``-th alignment tick.
        payload_bits: command payload size.
    """

    enabled: bool = True
    behaviour: str = "formation"
    every: int = 3
    payload_bits: int = 96

    def __post_init__(self) -> None:
        _check(self.every >= 1, "every", f"must be >= 1, got {self.every}")
        _check(self.payload_bits >= 0, "payload_bits", f"must be >= 0, got {self.payload_bits}")


@dataclass(frozen=True)
class FidelitySpec:
    """Swarm fidelity against an ideal run (zero latency, perfect alignment).

    Attributes:
        enabled: fly the ideal run and compute formation error and DTW.
        log_rate: trajectory sampling rate (Hz of physics time; the paper: 30 Hz).
        dtw_nodes: DTW is averaged over at most this many evenly spread nodes.
    """

    enabled: bool = True
    log_rate: float = 30.0
    dtw_nodes: int = 50

    def __post_init__(self) -> None:
        _positive(self, "log_rate")
        _check(self.dtw_nodes >= 1, "dtw_nodes", f"must be >= 1, got {self.dtw_nodes}")


FAULT_KINDS = ("crash", "slow", "degrade", "drop")
DROP_MESSAGES = ("trigger", "state", "command")


@dataclass(frozen=True)
class FaultSpec:
    """An injected fault.

    Attributes:
        kind: ``crash`` (node stops for good at ``start``), ``slow`` (node's steps take
            ``factor`` times longer in [start, end)), ``degrade`` (host link gets
            ``extra_delay`` seconds and ``extra_loss`` probability in [start, end)),
            ``drop`` (the first transmission of one message on its broker-to-receiver
            hop is lost: ``message`` of ``node`` for ``frame``; for commands ``frame``
            is the alignment tick number).
        node: target node of crash/slow/drop.
        host: target host of degrade.
        start: start time (s).
        end: end time (s); inf = until the end.
        factor: slow-down factor (>= 1).
        extra_delay: extra one-way delay (s).
        extra_loss: extra loss probability in [0, 1).
        message: ``drop``: ``trigger``, ``state`` or ``command``.
        frame: ``drop``: frame (or command tick) of the dropped message.
    """

    kind: str = "crash"
    node: int = -1
    host: int = -1
    start: float = 0.0
    end: float = math.inf
    factor: float = 1.0
    extra_delay: float = 0.0
    extra_loss: float = 0.0
    message: str = "state"
    frame: int = -1

    def __post_init__(self) -> None:
        _check(self.kind in FAULT_KINDS, "kind", f"must be one of {FAULT_KINDS}, got {self.kind!r}")
        _check(self.start >= 0, "start", f"must be >= 0 s, got {self.start}")
        _check(self.end > self.start, "end", f"must be > start ({self.start}), got {self.end}")
        _check(self.factor >= 1, "factor", f"must be >= 1, got {self.factor}")
        _nonneg(self, "extra_delay")
        _check(0 <= self.extra_loss < 1, "extra_loss", f"must be in [0, 1), got {self.extra_loss}")
        _check(
            self.message in DROP_MESSAGES,
            "message",
            f"must be one of {DROP_MESSAGES}, got {self.message!r}",
        )
        if self.kind == "drop":
            _check(self.frame >= 0, "frame", f"a drop fault needs frame >= 0, got {self.frame}")
        if self.kind in ("crash", "slow", "drop"):
            _check(self.node >= 0, "node", f"a {self.kind} fault needs node >= 0")
        else:
            _check(self.host >= 0, "host", "a degrade fault needs host >= 0")


@dataclass(frozen=True)
class Scenario:
    """A whole run: the swarm, the rates, the network and every method's parameters.

    Attributes:
        seed: root seed of all random streams.
        nodes: number of physics nodes (aircraft).
        hosts: number of physics hosts; nodes are placed on them by ``placement``.
        cores_per_host: CPU cores per host shared by its nodes.
        placement: ``block`` (consecutive nodes share a host) or ``round_robin``.
        f_trig: nominal trigger frequency (Hz); the physics step is ``1/f_trig``.
        f_align: alignment ticks per second at the server.
        f_render: render ticks per second; AoI and consistency are sampled here.
        duration: simulated time (s).
        warmup: metrics ignore everything before this time (s).
        payload_bits: state payload size (the paper: 150 bits).
        trigger_payload_bits: trigger payload size.
        dynamics: ``pointmass``, ``quadrotor``, ``fixedwing`` or ``jsbsim:<model>``.
        engine: ``events`` (per-message SimPy engine).
        methods: alignment methods to run side by side.
        history_frames: true states kept per node for consistency metrics.
        stall_threshold: a gap between new aligned snapshots longer than this is a stall (s).
    """

    seed: int = 1
    nodes: int = 200
    hosts: int = 10
    cores_per_host: int = 8
    placement: str = "block"
    f_trig: float = 100.0
    f_align: float = 60.0
    f_render: float = 60.0
    duration: float = 10.0
    warmup: float = 1.0
    payload_bits: int = 150
    trigger_payload_bits: int = 64
    dynamics: str = "quadrotor"
    engine: str = "events"
    methods: tuple[str, ...] = METHODS
    history_frames: int = 512
    stall_threshold: float = 0.1
    net: NetSpec = field(default_factory=NetSpec)
    broker: BrokerSpec = field(default_factory=BrokerSpec)
    compute: ComputeSpec = field(default_factory=ComputeSpec)
    clocks: ClockSpec = field(default_factory=ClockSpec)
    lockstep: LockstepSpec = field(default_factory=LockstepSpec)
    hlc: HLCSpec = field(default_factory=HLCSpec)
    bides: BidesSpec = field(default_factory=BidesSpec)
    commands: CommandSpec = field(default_factory=CommandSpec)
    fidelity: FidelitySpec = field(default_factory=FidelitySpec)
    faults: tuple[FaultSpec, ...] = ()

    def __post_init__(self) -> None:
        _check(0 <= self.seed < 2**63, "seed", f"must be in 0..2^63-1, got {self.seed}")
        _check(1 <= self.nodes <= 1_000_000, "nodes", f"must be in 1..1000000, got {self.nodes}")
        _check(
            1 <= self.hosts <= self.nodes,
            "hosts",
            f"must be in 1..nodes ({self.nodes}), got {self.hosts}",
        )
        _check(
            self.cores_per_host >= 1, "cores_per_host", f"must be >= 1, got {self.cores_per_host}"
        )
        _check(
            self.placement in ("block", "round_robin"),
            "placement",
            f"must be 'block' or 'round_robin', got {self.placement!r}",
        )
        _positive(self, "f_trig", "f_align", "f_render", "duration", "stall_threshold")
        _check(
            0 <= self.warmup < self.duration,
            "warmup",
            f"must be in [0, duration={self.duration}), got {self.warmup}",
        )
        _check(self.payload_bits >= 1, "payload_bits", f"must be >= 1, got {self.payload_bits}")
        _check(
            self.trigger_payload_bits >= 0,
            "trigger_payload_bits",
            f"must be >= 0, got {self.trigger_payload_bits}",
        )
        _check(
            self.dynamics in DYNAMICS_BUILTIN or self.dynamics.startswith("jsbsim:"),
            "dynamics",
            f"must be one of {DYNAMICS_BUILTIN} or 'jsbsim:<model>', got {self.dynamics!r}",
        )
        _check(self.engine in ("events",), "engine", f"must be 'events', got {self.engine!r}")
        _check(len(self.methods) > 0, "methods", f"must name at least one of {METHODS}")
        for m in self.methods:
            _check(m in METHODS, "methods", f"unknown method {m!r}; allowed: {METHODS}")
        _check(len(set(self.methods)) == len(self.methods), "methods", "lists a method twice")
        _check(
            self.history_frames >= 16, "history_frames", f"must be >= 16, got {self.history_frames}"
        )
        _check(
            self.bides.f_trig_min <= self.f_trig,
            "bides.f_trig_min",
            f"must be <= f_trig ({self.f_trig}), got {self.bides.f_trig_min}",
        )
        for i, f in enumerate(self.faults):
            if f.kind in ("crash", "slow", "drop"):
                _check(
                    f.node < self.nodes,
                    f"faults[{i}].node",
                    f"must be in 0..{self.nodes - 1}, got {f.node}",
                )
            else:
                _check(
                    f.host < self.hosts,
                    f"faults[{i}].host",
                    f"must be in 0..{self.hosts - 1}, got {f.host}",
                )

    @property
    def host_of(self) -> list[int]:
        """Host index of every node."""
        if self.placement == "block":
            per = math.ceil(self.nodes / self.hosts)
            return [i // per for i in range(self.nodes)]
        return [i % self.hosts for i in range(self.nodes)]


# ---------------------------------------------------------------- loading


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(value: Any, tp: Any, key: str) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if tp is Dist and isinstance(value, int | float) and not isinstance(value, bool):
            value = {"dist": "constant", "value": float(value)}
        if not isinstance(value, dict):
            raise ConfigError(key, f"must be a table ({_type_name(tp)}), got {value!r}")
        return from_dict(typing.cast(type[Any], tp), value, key)
    if origin is tuple:
        (elem, _ellipsis) = typing.get_args(tp)
        if isinstance(value, str) and elem is str:
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, list | tuple):
            raise ConfigError(key, f"must be a list, got {value!r}")
        return tuple(_convert(v, elem, f"{key}[{i}]") for i, v in enumerate(value))
    if origin in (typing.Union, types.UnionType):
        raise ConfigError(key, "internal: union types are not supported")
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(key, f"must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(key, f"must be an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(key, f"must be a number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(key, f"must be a string, got {value!r}")
        return value
    raise ConfigError(key, f"internal: unsupported type {tp!r}")


def from_dict(cls: type[Any], data: dict[str, Any], prefix: str = "") -> Any:
    """Build dataclass ``cls`` from nested dict ``data``, strictly.

    Raises:
        ConfigError: on an unknown key, a wrong type or an out-of-range value; the
            error's key is the full dotted path.
    """
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs: dict[str, Any] = {}
    for k, v in data.items():
        key = f"{prefix}.{k}" if prefix else k
        if k not in names:
            raise ConfigError(key, f"unknown key; allowed keys here: {', '.join(names)}")
        kwargs[k] = _convert(v, hints[k], key)
    try:
        return cls(**kwargs)
    except ConfigError as e:
        raise e.under(prefix) if prefix else e from None


def _plain(v: Any) -> Any:
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    return v


def to_dict(s: Scenario) -> dict[str, Any]:
    """The scenario as plain nested dicts and lists."""
    return dict(_plain(s))


def to_toml(s: Scenario) -> str:
    """The full resolved scenario as TOML (loadable by :func:`load`)."""
    d = to_dict(s)
    faults = d.pop("faults")
    text = tomli_w.dumps(d)
    if faults:
        text += "\n" + tomli_w.dumps({"faults": faults})
    else:
        text = "faults = []\n" + text
    return text


def config_hash(s: Scenario) -> str:
    """Stable 12-hex-digit hash of everything but the seed and the method list."""
    d = to_dict(s)
    d.pop("seed")
    d.pop("methods")
    blob = json.dumps(d, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]


def parse_set(item: str) -> tuple[str, Any]:
    """Parse one ``key=value`` override; the value is read as TOML, else as a string."""
    if "=" not in item:
        raise ConfigError(item, "an override must look like key=value")
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ConfigError(item, "empty key in override")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key, value


def _apply(data: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    cur = data
    for i, p in enumerate(parts[:-1]):
        nxt = cur.setdefault(p, {})
        if not isinstance(nxt, dict):
            raise ConfigError(".".join(parts[: i + 1]), "is not a table; cannot set a sub-key")
        cur = nxt
    cur[parts[-1]] = value


def load(
    path: str | Path | None = None, overrides: typing.Iterable[str] = (), **values: Any
) -> Scenario:
    """Load a scenario from an optional TOML file, then apply overrides.

    Args:
        path: TOML file (None = defaults).
        overrides: ``key=value`` strings (dotted keys), applied in order.
        **values: further top-level values (Python objects), applied last.

    Raises:
        ConfigError: bad file, unknown key, wrong type or out-of-range value.
    """
    data: dict[str, Any] = {}
    if path is not None:
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text())
        except FileNotFoundError:
            raise ConfigError(str(p), "scenario file not found") from None
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(str(p), f"not valid TOML: {e}") from None
    for item in overrides:
        k, v = parse_set(item)
        _apply(data, k, v)
    for k, v in values.items():
        _apply(data, k, v)
    return from_dict(Scenario, data)
