"""The unit and allowed range of every scenario key, machine-readable.

:data:`RANGES` maps each spec dataclass of the scenario to ``{field: Range}``; a
:class:`Range` knows its bounds (numbers, or the dotted key of another scenario key),
its open or closed ends, its choices and its unit. :func:`scenario_keys` walks
:class:`~sigma_des.config.Scenario` and yields one :class:`Key` per dotted key (type,
unit, default, range, description from the class's ``Attributes:`` docstring): the
scenario-key reference of the documentation is generated from it.

The checks themselves stay in each spec's ``__post_init__``; ``tests/docs/
test_ranges.py`` probes every range here against them (a value on each closed end is
accepted, one just outside each end is refused with a ``ConfigError``), so this table
and the validation cannot disagree.
"""

from __future__ import annotations

import builtins
import dataclasses
import math
import re
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import sigma_des.config as _cfg
from sigma_des.events.spec import DROP_MESSAGES, FAULT_KINDS, MAX_EXTRA_DELAY, MAX_SLOW_FACTOR
from sigma_des.net.deployment import (
    CLIENTS,
    CPU_SECONDS,
    MAX_CORES,
    MAX_DEMAND,
    MAX_RUNQ,
    PRESETS,
    RUNQ_KEYS,
)
from sigma_des.net.latency import DIST_NAMES, Dist
from sigma_des.net.loss import LOSS_MODELS, LossSpec
from sigma_des.net.spec import MAX_RETRIES, MIDDLEWARES
from sigma_des.specs import RECORD_MODES

__all__ = ["RANGES", "Key", "Range", "scenario_keys"]

Bound = float | str | None


@dataclass(frozen=True)
class Range:
    """The values a key accepts.

    Attributes:
        lo: lower bound: a number, the dotted key of another key, or None (none).
        hi: upper bound, likewise.
        lo_open: ``lo`` itself is refused.
        hi_open: ``hi`` itself is refused.
        choices: the allowed values of a key that takes one of a few.
        also: further accepted values outside ``[lo, hi]`` (e.g. ``-1``: automatic).
        text: the range as words, where no bound says it (a path, a name).
        note: a condition the bounds do not say (shown after the range).
        probe: the range is checked against the validation (``tests/docs``); False
            where it is checked only when a run starts or needs a sample file.
    """

    lo: Bound = None
    hi: Bound = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[Any, ...] = ()
    also: tuple[float, ...] = ()
    text: str = ""
    note: str = ""
    probe: bool = True

    def describe(self, integer: bool = False) -> str:
        """The range in words: ``[0, 1)``, ``1 … 100000``, ``> 0``, ``one of a, b``."""
        if self.text:
            out = self.text
        elif self.choices:
            out = "one of " + ", ".join(_lit(c) for c in self.choices)
        else:
            out = self._interval(integer)
        if self.also:
            out = " or ".join([*(_lit(a) for a in self.also), out])
        return f"{out}; {self.note}" if self.note else out

    def _interval(self, integer: bool) -> str:
        lo, hi = _name(self.lo), _name(self.hi)
        if self.lo is not None and self.hi is not None:
            if integer and not (self.lo_open or self.hi_open):
                return f"{lo} … {hi}"
            return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '≥'} {lo}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '≤'} {hi}"
        return "any"


def _lit(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f'"{v}"' if isinstance(v, str) else f"{v:g}"


def _name(b: Bound) -> str:
    if isinstance(b, str) or b is None:
        return b or ""
    return str(b) if isinstance(b, int) else f"{b:g}"


def _r(lo: Bound = None, hi: Bound = None, lo_open: bool = False, hi_open: bool = False,
       **kw: Any) -> Range:
    return Range(lo, hi, lo_open, hi_open, **kw)


def _pos(**kw: Any) -> Range:
    return Range(0.0, None, lo_open=True, **kw)


def _nonneg(**kw: Any) -> Range:
    return Range(0.0, None, **kw)


def _one_of(*choices: Any, **kw: Any) -> Range:
    return Range(choices=choices, **kw)


_FLAG = _one_of(True, False)
_PROB = _r(0.0, 1.0)
_PROB_BELOW_ONE = _r(0.0, 1.0, hi_open=True)
_RATE = _r(0.0, _cfg.MAX_RATE_HZ, lo_open=True)
_PATH = Range(text="a file path", probe=False)

#: ``class -> {field: (unit, Range)}``: every leaf key of the scenario.
RANGES: dict[type, dict[str, tuple[str, Range]]] = {
    _cfg.Scenario: {
        "seed": ("", _r(0, 2**63 - 1)),
        "nodes": ("", _r(1, 1_000_000)),
        "hosts": ("", _r(1, "nodes", also=(0,), note="0: ceil(nodes / 20)")),
        "cores_per_host": ("cores", _r(1)),
        "placement": ("", _one_of("block", "round_robin")),
        "f_trig": ("Hz", _RATE),
        "f_align": ("Hz", _RATE),
        "f_render": ("Hz", _RATE),
        "align_phase": ("ticks", _r(0.0, 1.0, hi_open=True)),
        "render_phase": ("ticks", _r(0.0, 1.0, hi_open=True)),
        "duration": ("s", _r(0.0, _cfg.MAX_DURATION_S, lo_open=True)),
        "warmup": ("s", _r(0.0, "duration", hi_open=True, also=(-1,),
                           note="-1: 0.1 × duration")),
        "payload_bits": ("bit", _r(1)),
        "trigger_payload_bits": ("bit", _r(0)),
        "dynamics": ("", _one_of(*_cfg.DYNAMICS_BUILTIN, "jsbsim:<model>", probe=False)),
        "dynamics_params": ("", Range(text='"" or the path of a `sigma-des tune` fit',
                                      probe=False)),
        "engine": ("", _one_of(*_cfg.ENGINES)),
        "methods": ("", Range(text="a non-empty list, no repeats, of " + ", ".join(
            _lit(m) for m in _cfg.ALL_METHODS), probe=False)),
        "history_frames": ("frames", _r(16, _cfg.MAX_HISTORY_FRAMES)),
        "stall_threshold": ("s", _pos()),
    },
    _cfg.NetSpec: {
        "transport": ("", _one_of("datagram", "stream")),
        "qos": ("", _one_of(0, 1)),
        "rto": ("s", _pos()),
        "qos1_timeout": ("s", _pos()),
        "max_retries": ("", _r(0, MAX_RETRIES)),
        "tcpip_bytes": ("B", _r(0)),
        "ethernet_bytes": ("B", _r(0)),
        "topic_bytes": ("B", _r(1, 65535)),
        "middleware": ("", _one_of(*MIDDLEWARES, note='"dds" needs transport "datagram" '
                                   'and qos 0')),
    },
    _cfg.LinkSpec: {"bandwidth_mbps": ("Mbit/s", _pos())},
    Dist: {
        "dist": ("", _one_of(*DIST_NAMES, note='"empirical" needs `file`')),
        **{k: ("s", _nonneg()) for k in ("value", "low", "mean", "std")},
        "high": ("s", _r("low")),
        "file": ("", Range(text='"" or a sample file (needed by "empirical")', probe=False)),
    },
    LossSpec: {
        "model": ("", _one_of(*LOSS_MODELS)),
        "p": ("", _PROB_BELOW_ONE),
        **{k: ("", _PROB) for k in ("p_gb", "p_bg", "loss_good", "loss_bad")},
        "slot": ("s", _pos()),
    },
    _cfg.ComputeSpec: {"host_share": ("", _r(0.0, 1.0, hi_open=True))},
    _cfg.BrokerSpec: {},
    _cfg.ClockSpec: {"offset_std": ("s", _nonneg()), "drift_ppm_std": ("ppm", _nonneg()),
                     "ntp_period": ("s", _nonneg(note="0: no NTP")),
                     "ntp_residual_std": ("s", _nonneg())},
    _cfg.LockstepSpec: {"retry_timeout": ("s", _pos()),
                        "eviction_timeout": ("s", _nonneg(note="0: never"))},
    _cfg.HLCSpec: {"liveness_timeout": ("s", _nonneg(note="0: never"))},
    _cfg.BidesSpec: {
        "ring_size": ("frames", _r(2, 100_000)),
        "hole_fill": ("", _FLAG), "lag_exclusion": ("", _FLAG),
        "theta_lag": ("frames", _r(1)),
        "adaptation": ("", _FLAG),
        "lag_high": ("frames", _r(1, note="and ≥ bides.lag_low")),
        "lag_low": ("frames", _r(0, "bides.lag_high")),
        "rate_down": ("", _r(0.0, 1.0, lo_open=True, hi_open=True)),
        "rate_up": ("", _r(1.0, lo_open=True)),
        "f_trig_min": ("Hz", _r(0.0, "f_trig", lo_open=True)),
        "hold_down": ("ticks", _r(1)), "hold_up": ("ticks", _r(1)),
        "time_warp": ("", _FLAG),
        "theta_warp": ("frames", _r(0)),
    },
    _cfg.CommandSpec: {
        "enabled": ("", _FLAG),
        "behaviour": ("", _one_of("cohesion", "route", "formation", "follow", "separation",
                                  "none", probe=False, note="checked when a run starts")),
        "every": ("ticks", _r(1)),
        "payload_bits": ("bit", _r(0)),
    },
    _cfg.FidelitySpec: {"enabled": ("", _FLAG), "log_rate": ("Hz", _pos()),
                        "dtw_nodes": ("", _r(1))},
    _cfg.DdsSpec: {
        "meta_cost": ("s", _nonneg()), "executor_per_entity": ("s", _nonneg()),
        "endpoints": ("", _r(0)),
        "multicast": ("", _FLAG), "reliable": ("", _FLAG),
        "history_depth": ("samples", _r(1)),
        "heartbeat_period": ("s", _pos()),
        "heartbeat_response_delay": ("s", _nonneg()), "nack_response_delay": ("s", _nonneg()),
        "spdp_period": ("s", _pos()), "spdp_initial_count": ("", _r(0)),
        "spdp_initial_period": ("s", _pos()),
        "spdp_bytes": ("B", _r(1, 65507)), "sedp_bytes": ("B", _r(1, 65507)),
        "udpip_bytes": ("B", _r(0)),
    },
    _cfg.RpcSpec: {"in_flight": ("calls", _r(0, note="0: one per vehicle")),
                   "render_per_vehicle": ("s", _nonneg())},
    _cfg.RecordSpec: {
        "mode": ("", _one_of(*RECORD_MODES)),
        "deadband_pos": ("m", _nonneg()), "deadband_vel": ("m/s", _nonneg()),
        "deadband_att": ("rad", _nonneg()),
        "keyframe_every": ("frames", _r(1, 1_000_000)),
    },
    _cfg.FaultSpec: {
        "kind": ("", _one_of(*FAULT_KINDS)),
        "node": ("", _r(0, "nodes", hi_open=True, note="crash, slow and drop")),
        "host": ("", _r(0, "hosts", hi_open=True, note="degrade")),
        "start": ("s", _r(0.0, math.inf, hi_open=True)),
        "end": ("s", _r("start", math.inf, lo_open=True, note="inf: until the end")),
        "factor": ("", _r(1.0, MAX_SLOW_FACTOR)),
        "extra_delay": ("s", _r(0.0, MAX_EXTRA_DELAY)),
        "extra_loss": ("", _PROB_BELOW_ONE),
        "message": ("", _one_of(*DROP_MESSAGES)),
        "frame": ("frames", _r(0, note="drop")),
    },
    _cfg.DeploymentSpec: {
        "preset": ("", _one_of(*PRESETS)),
        "cores": ("cores", _r(1, MAX_CORES)),
        "background": ("cores", _r(0.0, "deployment.cores", hi_open=True)),
        **{k: ("s", _r(0.0, MAX_DEMAND)) for k in CPU_SECONDS},
        **{f"{w}_record": ("s", _r(0.0, f"deployment.{w}_demand")) for w in ("host", "server")},
        **{k: ("s per CPU s", _r(0.0, MAX_RUNQ)) for k in RUNQ_KEYS},
        "runq_growth": ("", _FLAG),
        "broker_runq_growth": ("", _FLAG),
        "server_runq_growth": ("", _FLAG),
        "clients": ("", _one_of(*CLIENTS)),
        "bundle": ("", _FLAG),
    },
}

#: What a class's own docstring does not say per field.
_DOC = {
    (_cfg.BrokerSpec, "publish_service"): "broker service time per inbound PUBLISH (s).",
    (_cfg.BrokerSpec, "delivery_service"): "broker service time per delivery (s).",
    (_cfg.HLCSpec, "liveness_timeout"): "a node silent this long is treated as dead (s).",
}


@dataclass(frozen=True)
class Key:
    """One leaf key of the scenario, as the reference lists it.

    Attributes:
        key: dotted key (``net.host_link.loss.p``; ``faults[].kind`` for a list entry).
        section: the table it sits in (``""`` for the top level).
        type: ``int``, ``float``, ``bool``, ``str`` or ``list[str]``; ``table`` for a
            table (its keys follow it).
        unit: its unit (``""``: none).
        default: the default, as TOML would write it (``""``: absent by default).
        range: what it accepts.
        doc: what it does (from the class's ``Attributes:`` docstring).
        cls: the dataclass that holds it.
        name: its field name there.
    """

    key: str
    section: str
    type: str
    unit: str
    default: str
    range: Range
    doc: str
    cls: builtins.type = field(repr=False)
    name: str = ""


def _attr_docs(cls: type) -> dict[str, str]:
    """``{field: text}`` of a Google-style ``Attributes:`` section of ``cls``'s docstring."""
    lines = (cls.__doc__ or "").splitlines()
    out: dict[str, str] = {}
    inside, indent, cur = False, 0, ""
    for line in lines:
        if line.strip() == "Attributes:":
            inside, indent = True, len(line) - len(line.lstrip()) + 4
            continue
        if not inside:
            continue
        if line.strip() and len(line) - len(line.lstrip()) < indent:
            break
        m = re.match(rf"^ {{{indent}}}(\w+): (.*)$", line)
        if m:
            cur = m.group(1)
            out[cur] = m.group(2).strip()
        elif cur and line.strip():
            out[cur] += " " + line.strip()
    return out


def _type_name(tp: Any) -> str:
    if typing.get_origin(tp) is tuple:
        return f"list[{_type_name(typing.get_args(tp)[0])}]"
    return getattr(tp, "__name__", str(tp))


def _toml(v: Any) -> str:
    if isinstance(v, tuple):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return _lit(v) if isinstance(v, bool | str | int | float) else str(v)


def _field_defaults(cls: type) -> types.SimpleNamespace:
    """The defaults of ``cls``'s fields (a list entry's defaults need not be valid alone)."""
    return types.SimpleNamespace(**{
        f.name: f.default if f.default is not dataclasses.MISSING
        else f.default_factory()  # type: ignore[operator]
        for f in dataclasses.fields(cls)
        if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
    })


def scenario_keys() -> Iterator[Key]:
    """Every leaf key of the scenario, in the order ``sigma-des config`` prints them.

    The defaults are those of ``sigma-des config`` (``hosts = 0`` and ``warmup = -1``:
    automatic); a list-of-tables key (``faults``) is listed once as ``faults[]`` with
    :class:`~sigma_des.config.FaultSpec`'s defaults; ``latency_down`` (absent by
    default) with the keys of a delay distribution.
    """
    sc = _cfg.Scenario()
    auto = {"hosts": 0, "warmup": _cfg.WARMUP_AUTO}
    yield from _walk(_cfg.Scenario, sc, "", auto)


def _walk(cls: type, obj: Any, prefix: str, auto: dict[str, Any]) -> Iterator[Key]:
    hints = typing.get_type_hints(cls)
    docs = _attr_docs(cls)
    table = RANGES[cls]
    for f in dataclasses.fields(cls):
        tp, key = hints[f.name], prefix + f.name
        value = getattr(obj, f.name) if obj is not None else None
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        doc = docs.get(f.name) or _DOC.get((cls, f.name), "")
        sub: Any = None
        if typing.get_origin(tp) is tuple and dataclasses.is_dataclass(args[0]):
            sub, value, key = args[0], _field_defaults(typing.cast(type, args[0])), key + "[]"
        elif typing.get_origin(tp) in (typing.Union, types.UnionType):
            tp = args[0]
        if sub is None and dataclasses.is_dataclass(tp):
            sub = tp
        if sub is not None:
            doc = doc or (sub.__doc__ or "").strip().splitlines()[0]
            yield Key(key, prefix.rstrip("."), "table", "", "", Range(text="a table"), doc, sub,
                      f.name)
            yield from _walk(sub, value, key + ".", {})
            continue
        unit, rng = table[f.name]
        default = "" if value is None else _toml(auto.get(f.name, value))
        yield Key(key, prefix.rstrip("."), _type_name(tp), unit, default, rng, doc, cls, f.name)
