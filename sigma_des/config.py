"""The scenario: one validated, frozen configuration for a whole run (docs/concepts/model.md).

Every default lives here (or in the net-layer spec classes it embeds). A scenario is
loaded from TOML and/or ``--set key=value`` overrides through :func:`load`; an unknown
key, a wrong type or an out-of-range value raises :class:`~sigma_des.errors.ConfigError`
naming the dotted key and what is allowed (the text of overrides and scenario files is
read by :mod:`sigma_des.overrides`). :func:`to_toml` prints the resolved scenario.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from sigma_des.core.validate import require, require_positive
from sigma_des.errors import ConfigError
from sigma_des.events.align.spec import AlignParams, BidesSpec, HLCSpec, LockstepSpec, RpcSpec
from sigma_des.events.spec import CommandSpec, ComputeSpec, FaultSpec, RunSpec
from sigma_des.loading import from_dict, plain
from sigma_des.metrics.collector import CollectorSpec
from sigma_des.metrics.fidelity import FidelitySpec
from sigma_des.net.clocks import ClockSpec
from sigma_des.net.deployment import LATER_KEYS, DeploymentSpec
from sigma_des.net.kinds import COMMAND, STATE, TRIGGER
from sigma_des.net.spec import (
    BrokerSpec,
    DdsSpec,
    LinkDegrade,
    LinkSpec,
    NetSetup,
    NetSpec,
    Topology,
)
from sigma_des.overrides import parse_set, read_toml, set_key
from sigma_des.specs import RecordSpec

__all__ = [
    "BidesSpec",
    "BrokerSpec",
    "CommandSpec",
    "ComputeSpec",
    "DeploymentSpec",
    "FaultSpec",
    "FidelitySpec",
    "HLCSpec",
    "LinkSpec",
    "LockstepSpec",
    "ALL_METHODS",
    "METHODS",
    "NODES_PER_HOST",
    "WARMUP_FRACTION",
    "NetSpec",
    "RecordSpec",
    "Scenario",
    "config_hash",
    "load",
    "parse_set",
    "set_key",
    "to_dict",
    "to_toml",
    "with_overrides",
]

#: Nodes per host when ``hosts = 0`` (auto): the paper's 20 aircraft per PC.
NODES_PER_HOST = 20
#: ``warmup = -1`` (auto, the default) ignores this fraction of ``duration``: 1 s of 10.
WARMUP_FRACTION = 0.1
#: The ``warmup`` value meaning "automatic" (:data:`WARMUP_FRACTION` of the duration).
WARMUP_AUTO = -1.0
#: Largest trigger, alignment and render rate (Hz): a 0.1 ms physics step.
MAX_RATE_HZ = 10_000.0
#: Longest simulated duration (s): one day.
MAX_DURATION_S = 86_400.0
#: Largest ``history_frames``.
MAX_HISTORY_FRAMES = 100_000

#: Alignment methods, in their canonical order.
METHODS: tuple[str, ...] = ("none", "lockstep", "hlc", "bides")
#: Methods modelling the peer simulators' architectures (not run unless asked for).
PEER_METHODS: tuple[str, ...] = ("rpc",)
#: Every method a scenario may name.
ALL_METHODS: tuple[str, ...] = METHODS + PEER_METHODS
ENGINES: tuple[str, ...] = ("cohort", "events")
DYNAMICS_BUILTIN: tuple[str, ...] = ("pointmass", "quadrotor", "fixedwing")


@dataclass(frozen=True)
class Scenario:
    """A whole run: the swarm, the rates, the network and every method's parameters.

    Attributes:
        seed: root seed of all random streams.
        nodes: number of physics nodes (aircraft).
        hosts: number of physics hosts; nodes are placed on them by ``placement``.
            0 (the default) means ``ceil(nodes / NODES_PER_HOST)`` hosts, the paper's
            20 aircraft per PC, so any ``nodes`` works without setting ``hosts``.
        cores_per_host: CPU cores per host shared by its nodes.
        placement: ``block`` (consecutive nodes share a host) or ``round_robin``.
        f_trig: nominal trigger frequency (Hz), at most 10 kHz; the physics step is
            ``1/f_trig``. ``f_align`` and ``f_render`` have the same bound.
        f_align: alignment ticks per second at the server.
        f_render: render ticks per second; AoI and consistency are sampled here.
        align_phase: alignment tick j is at ``(j + align_phase) / f_align``: the
            server's loop runs on its own clock, not in step with the triggers. The
            default 0.1 puts the command ticks (every 3rd, 20 Hz) 1.67 ms after a
            trigger, while that frame's states are arriving; phase 0 would make every
            command tick coincide with a trigger instant (a tie, not a deployment).
        render_phase: render tick j is at ``(j + render_phase) / f_render``; the
            default 0.6 samples half an alignment period after each alignment tick,
            so ``aoi_mean`` is close to the time average (see docs/concepts/metrics.md).
        duration: simulated time (s), at most 86400 (one day).
        warmup: metrics ignore everything before this time (s), in ``[0, duration)``.
            -1 (the default) means ``WARMUP_FRACTION * duration`` (0.1: 1 s of the
            default 10 s), so any ``duration`` works without setting ``warmup``.
        payload_bits: state payload size (the paper: 150 bits).
        trigger_payload_bits: trigger payload size.
        dynamics: ``pointmass``, ``quadrotor``, ``fixedwing`` or ``jsbsim:<model>``.
        dynamics_params: fitted parameter file of ``sigma-des tune`` (TOML; see
            sigma_des/agents/fitted.py) applied to the ``quadrotor`` / ``fixedwing``
            preset; empty = the preset as shipped. The hash covers the path only.
        engine: ``cohort`` (messages in a compiled core; features it does not
            reproduce fall back to the per-message engine per method) or ``events``
            (the per-message SimPy engine, the executable specification). Both give
            identical results, so the engine is not part of the config hash.
        methods: alignment methods to run side by side (default: the four of
            :data:`METHODS`; ``rpc`` of :data:`PEER_METHODS` only when named).
        history_frames: true states kept per node for consistency metrics (16..100000).
        stall_threshold: a gap between new aligned snapshots longer than this is a stall (s).
        record: how ``--record`` stores runs (not part of the config hash).
        deployment: machines, CPU demands and MQTT clients
            (docs/concepts/deployment.md); all defaults is not written out nor part of
            the config hash.
    """

    seed: int = 1
    nodes: int = 200
    hosts: int = 0
    cores_per_host: int = 8
    placement: str = "block"
    f_trig: float = 100.0
    f_align: float = 60.0
    f_render: float = 60.0
    align_phase: float = 0.1
    render_phase: float = 0.6
    duration: float = 10.0
    warmup: float = WARMUP_AUTO
    payload_bits: int = 150
    trigger_payload_bits: int = 64
    dynamics: str = "quadrotor"
    dynamics_params: str = ""
    engine: str = "cohort"
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
    dds: DdsSpec = field(default_factory=DdsSpec)
    rpc: RpcSpec = field(default_factory=RpcSpec)
    record: RecordSpec = field(default_factory=RecordSpec)
    faults: tuple[FaultSpec, ...] = ()
    deployment: DeploymentSpec = field(default_factory=DeploymentSpec)

    def __post_init__(self) -> None:
        require(0 <= self.seed < 2**63, "seed", f"must be in 0..2^63-1, got {self.seed}")
        require(1 <= self.nodes <= 1_000_000, "nodes", f"must be in 1..1000000, got {self.nodes}")
        # auto placement: the paper's 20 nodes per host; ``hosts_auto`` (not a field)
        # remembers it, so a sweep point that changes ``nodes`` places them anew
        object.__setattr__(self, "hosts_auto", self.hosts == 0)
        if self.hosts == 0:
            object.__setattr__(self, "hosts", math.ceil(self.nodes / NODES_PER_HOST))
        require(
            1 <= self.hosts <= self.nodes,
            "hosts",
            f"must be 0 (auto: ceil(nodes/{NODES_PER_HOST})) or in 1..nodes ({self.nodes}), "
            f"got {self.hosts}",
        )
        require(
            self.cores_per_host >= 1, "cores_per_host", f"must be >= 1, got {self.cores_per_host}"
        )
        require(
            self.placement in ("block", "round_robin"),
            "placement",
            f"must be 'block' or 'round_robin', got {self.placement!r}",
        )
        require_positive(self, "f_trig", "f_align", "f_render", "duration", "stall_threshold")
        for key in ("f_trig", "f_align", "f_render"):
            v = getattr(self, key)
            require(v <= MAX_RATE_HZ, key, f"must be in (0, {MAX_RATE_HZ:g}] Hz, got {v}")
        require(
            self.duration <= MAX_DURATION_S,
            "duration",
            f"must be in (0, {MAX_DURATION_S:g}] s, got {self.duration}",
        )
        for key in ("align_phase", "render_phase"):
            v = getattr(self, key)
            require(0.0 <= v < 1.0, key, f"must be in [0, 1) (a fraction of a tick), got {v}")
        # like ``hosts_auto``: ``warmup_auto`` keeps an automatic warm-up automatic when
        # the scenario is written out (to_toml) or a sweep point changes the duration
        object.__setattr__(self, "warmup_auto", self.warmup == WARMUP_AUTO)
        if self.warmup == WARMUP_AUTO:
            object.__setattr__(self, "warmup", WARMUP_FRACTION * self.duration)
        require(
            0 <= self.warmup < self.duration,
            "warmup",
            f"must be in [0, duration={self.duration}) s, or -1 (auto: "
            f"{WARMUP_FRACTION:g} x duration), got {self.warmup}",
        )
        require(self.payload_bits >= 1, "payload_bits", f"must be >= 1, got {self.payload_bits}")
        require(
            self.trigger_payload_bits >= 0,
            "trigger_payload_bits",
            f"must be >= 0, got {self.trigger_payload_bits}",
        )
        self._check_dynamics()
        require(
            self.engine in ENGINES, "engine", f"must be one of {ENGINES}, got {self.engine!r}"
        )
        require(len(self.methods) > 0, "methods", f"must name at least one of {ALL_METHODS}")
        for m in self.methods:
            require(m in ALL_METHODS, "methods", f"unknown method {m!r}; allowed: {ALL_METHODS}")
        require(len(set(self.methods)) == len(self.methods), "methods", "lists a method twice")
        require(
            16 <= self.history_frames <= MAX_HISTORY_FRAMES,
            "history_frames",
            f"must be in 16..{MAX_HISTORY_FRAMES}, got {self.history_frames}",
        )
        require(
            self.bides.f_trig_min <= self.f_trig,
            "bides.f_trig_min",
            f"must be <= f_trig ({self.f_trig}), got {self.bides.f_trig_min}",
        )
        self._check_faults()
        dep = self.deployment  # the CPU stage and host clients: MQTT, the four methods
        require(dep == DeploymentSpec() or self.net.middleware == "mqtt",
                "deployment.preset" if dep.cpu else "deployment.clients",
                "needs net.middleware 'mqtt' (DDS participants have threads of their own)")
        require(dep.clients == "node" or "rpc" not in self.methods, "deployment.clients",
                "'host' does not apply to the rpc method (per-vehicle calls): drop 'rpc'")

    def _check_dynamics(self) -> None:
        """``dynamics`` names a model; ``dynamics_params`` a fit of it."""
        require(
            self.dynamics in DYNAMICS_BUILTIN or self.dynamics.startswith("jsbsim:"),
            "dynamics",
            f"must be one of {DYNAMICS_BUILTIN} or 'jsbsim:<model>', got {self.dynamics!r}",
        )
        if self.dynamics_params:
            from sigma_des.agents.fitted import fitted_params

            require(self.dynamics in ("quadrotor", "fixedwing"), "dynamics_params",
                    f"applies to dynamics 'quadrotor' or 'fixedwing', not {self.dynamics!r}")
            try:
                fitted_params(self.dynamics_params, self.dynamics)
            except ConfigError as e:
                raise ConfigError("dynamics_params", str(e)) from None

    def _check_faults(self) -> None:
        """Every fault names an existing node (crash, slow, drop) or host (degrade)."""
        for i, f in enumerate(self.faults):
            if f.kind in ("crash", "slow", "drop"):
                require(
                    f.node < self.nodes,
                    f"faults[{i}].node",
                    f"must be in 0..{self.nodes - 1}, got {f.node}",
                )
            else:
                require(
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

    def run_spec(self) -> RunSpec:
        """The engine's view of this scenario (:class:`~sigma_des.events.spec.RunSpec`):
        the fields both share by name, the placement, and the layers' own specs."""
        own = ("host_of", "net")
        same = {f.name: getattr(self, f.name) for f in dataclasses.fields(RunSpec)
                if f.name in self.__dataclass_fields__ and f.name not in own}
        return RunSpec(
            host_of=tuple(self.host_of), net=self.net_setup(), align=self.align_params(),
            collect=self.collector_spec(), time_warp=self.bides.time_warp,
            theta_warp=self.bides.theta_warp, log_rate=self.fidelity.log_rate, **same,
        )

    @property
    def topology(self) -> Topology:
        """The net layer's view of the placement: nodes, hosts and each node's host."""
        return Topology(self.nodes, self.hosts, tuple(self.host_of))

    def net_setup(self) -> NetSetup:
        """Everything the net layer takes from this scenario (its specs, topology,
        metrics window ``[warmup, duration)``, ``degrade`` and ``drop`` faults)."""
        kinds = {"trigger": TRIGGER, "state": STATE, "command": COMMAND}
        return NetSetup(
            net=self.net,
            broker=self.broker,
            dds=self.dds,
            topology=self.topology,
            warmup=self.warmup,
            end=self.duration,
            degrades=tuple(
                LinkDegrade(f.host, f.start, f.end, f.extra_delay, f.extra_loss)
                for f in self.faults
                if f.kind == "degrade"
            ),
            drops=frozenset(
                (kinds[f.message], f.node, f.frame) for f in self.faults if f.kind == "drop"
            ),
            deployment=self.deployment,
        )

    def align_params(self) -> AlignParams:
        """What the alignment method is built from (its spec and a few scalars)."""
        return AlignParams(
            f_trig=self.f_trig,
            seed=self.seed,
            middleware=self.net.middleware,
            lockstep=self.lockstep,
            hlc=self.hlc,
            bides=self.bides,
            rpc=self.rpc,
        )

    def collector_spec(self) -> CollectorSpec:
        """What the metrics collector needs of the scenario."""
        return CollectorSpec(
            nodes=self.nodes,
            warmup=self.warmup,
            duration=self.duration,
            f_trig=self.f_trig,
            history_frames=self.history_frames,
            stall_threshold=self.stall_threshold,
        )


# ---------------------------------------------------------------- loading


def to_dict(s: Scenario, keep_auto: bool = False) -> dict[str, Any]:
    """The scenario ``s`` as plain nested dicts and lists.

    Args:
        keep_auto: write automatic values as such (``hosts = 0``, ``warmup = -1``), so
            that editing ``nodes`` or ``duration`` re-derives them; False: the resolved
            values (what the run uses, and what the hash covers).
    """
    d = dict(plain(s))
    if s.deployment == DeploymentSpec():  # today's model: not written, hashes unchanged
        d.pop("deployment")
    else:  # keys added later are left out at 0 (as before they existed)
        d["deployment"] = {k: v for k, v in d["deployment"].items() if v or k not in LATER_KEYS}
    if keep_auto:
        if getattr(s, "hosts_auto", False):
            d["hosts"] = 0
        if getattr(s, "warmup_auto", False):
            d["warmup"] = WARMUP_AUTO
    if d["compute"]["host_share"] == 0.0:  # independent step draws: as before the key existed
        del d["compute"]["host_share"]
    return d


def to_toml(s: Scenario) -> str:
    """The full scenario as TOML (loadable by :func:`load`); automatic values stay so."""
    d = to_dict(s, keep_auto=True)
    faults = d.pop("faults")
    text = tomli_w.dumps(d)
    if faults:
        text += "\n" + tomli_w.dumps({"faults": faults})
    else:
        text = "faults = []\n" + text
    return text


def config_hash(s: Scenario) -> str:
    """Stable 12-hex-digit hash of all but the seed, the methods, the engine and ``record``."""
    d = to_dict(s)
    d.pop("seed")
    d.pop("methods")
    d.pop("engine")
    d.pop("record")
    blob = json.dumps(d, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]


def load(
    path: str | Path | None = None, overrides: typing.Iterable[str] = (), **values: Any
) -> Scenario:
    """Load a scenario from an optional TOML file, then apply overrides.

    Args:
        path: TOML file or the name of a shipped scenario (:mod:`sigma_des.shipped`;
            None = defaults).
        overrides: ``key=value`` strings (dotted keys), applied in order.
        **values: further top-level values (Python objects), applied last.

    Raises:
        ConfigError: bad file, unknown key, wrong type or out-of-range value.
    """
    data: dict[str, Any] = {}
    if path is not None:
        from sigma_des.shipped import resolve

        data = read_toml(resolve(path))
    for item in overrides:
        k, v = parse_set(item)
        set_key(data, k, v)
    for k, v in values.items():
        set_key(data, k, v)
    return from_dict(Scenario, data)


def with_overrides(sc: Scenario, overrides: typing.Iterable[str]) -> Scenario:
    """``sc`` with further ``key=value`` overrides (read and validated like ``--set``).

    Raises:
        ConfigError: a malformed override, unknown key, wrong type or out-of-range value.
    """
    items = tuple(overrides)
    if not items:
        return sc
    data = to_dict(sc, keep_auto=True)
    for item in items:
        set_key(data, *parse_set(item))
    return from_dict(Scenario, data)  # type: ignore[no-any-return]
