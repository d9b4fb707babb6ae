"""Live-mode topics and the binary payload layout (little-endian ``struct``).

Topics of run ``R`` (``R`` is a per-run token, so two runs on one broker never mix):

* downstream (server -> hosts): ``sd/R/down/trig`` (triggers, one per frame, to
  every host), ``sd/R/down/h<H>/cmd`` (behaviour commands for nodes of host H),
  ``sd/R/down/h<H>/rereq`` (Lock-Step re-requests), ``sd/R/down/ctl`` (``stop``);
* upstream (hosts -> server): ``sd/R/up/h<H>/state`` (one message per node state),
  ``sd/R/up/h<H>/ready`` and ``sd/R/up/h<H>/stats`` (JSON, once per run).

Payloads (byte sizes in brackets; ``f64`` times are seconds since the run's start
on one monotonic clock):

The kind byte is the message kind of :mod:`sigma_des.net.kinds` (the DES's):

* trigger [33]: kind u8 = 1, frame u32, t_send f64, dt f64, hlc_l f64, hlc_c u32
* state [85]: kind u8 = 2 (5 = republished), node u32, frame u32, t_gen f64,
  t_send f64, hlc_l f64, hlc_c u32, 12 x f32 published state (``OBS_FIELDS``)
* command [23 + 8 m]: kind u8 = 3, node u32, stamp_frame i32, tick u32, t_send f64,
  m u16, m x f64 values
* rerequest [21]: kind u8 = 4, node u32, frame u32, retry u32, t_send f64

With ``--bundle``, a host packs the states its nodes finish in one turn of its loop
into one PUBLISH: the payload is those 85-byte records back to back (at most
:data:`MAX_BUNDLE`); the server accepts any whole number of records.

The paper's state is 150 bits (19 bytes: pose and velocity packed at reduced
precision); ours is 85 bytes because it carries the whole 12-column published
state in float32 plus the time and HLC fields the measurements need. The DES
counts ``payload_bits`` (default 150) on the wire; to compare wire throughput,
set ``payload_bits = 680`` (85 bytes) in the DES. Every decoder checks length,
kind, ranges and finiteness and raises :class:`WireError` on anything else.
"""

from __future__ import annotations

import math
import struct

import numpy as np
from numpy.typing import NDArray

from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER

__all__ = [
    "COMMAND",
    "REPUBLISH",
    "REREQUEST",
    "STATE",
    "TRIGGER",
    "Topics",
    "WireError",
    "decode_command",
    "decode_rerequest",
    "decode_state",
    "decode_trigger",
    "encode_command",
    "encode_rerequest",
    "encode_state",
    "encode_trigger",
    "MAX_BUNDLE",
    "STATE_BYTES",
    "TRIGGER_BYTES",
]

_TRIG = struct.Struct("<BIdddI")
_STATE = struct.Struct("<BIIdddI12f")
_CMD_HEAD = struct.Struct("<BIiIdH")
_REREQ = struct.Struct("<BIIId")
TRIGGER_BYTES = _TRIG.size
STATE_BYTES = _STATE.size
MAX_COMMAND_VALUES = 64
#: Most states one PUBLISH may carry (``--bundle``: a host's states of one loop turn).
MAX_BUNDLE = 4096
_U32 = 2**32 - 1


class WireError(ValueError):
    """A payload that is malformed, truncated, oversized, out of range or not finite."""


class Topics:
    """Topic names of one run."""

    def __init__(self, run: str) -> None:
        self.run = run
        base = f"sd/{run}"
        self.base = base
        self.trig = f"{base}/down/trig"
        self.ctl = f"{base}/down/ctl"
        self.up_all = f"{base}/up/#"

    def cmd(self, host: int) -> str:
        """Commands for the nodes of ``host``."""
        return f"{self.base}/down/h{host}/cmd"

    def rereq(self, host: int) -> str:
        """Lock-Step re-requests for the nodes of ``host``."""
        return f"{self.base}/down/h{host}/rereq"

    def host_down(self, host: int) -> str:
        """Everything a host subscribes to besides triggers and control."""
        return f"{self.base}/down/h{host}/#"

    def state(self, host: int) -> str:
        """States published by ``host``."""
        return f"{self.base}/up/h{host}/state"

    def ready(self, host: int) -> str:
        """``host`` is connected and subscribed."""
        return f"{self.base}/up/h{host}/ready"

    def stats(self, host: int) -> str:
        """``host``'s end-of-run counters (JSON)."""
        return f"{self.base}/up/h{host}/stats"

    def parse_up(self, topic: str) -> tuple[int, str] | None:
        """``(host, leaf)`` of an upstream topic, None if it is not one of ours."""
        prefix = f"{self.base}/up/h"
        if not topic.startswith(prefix):
            return None
        rest = topic[len(prefix):]
        h, sep, leaf = rest.partition("/")
        if not sep or not h.isdigit() or leaf not in ("state", "ready", "stats"):
            return None
        return int(h), leaf


def _finite(*xs: float) -> bool:
    return all(math.isfinite(x) for x in xs)


def encode_trigger(frame: int, t_send: float, dt: float, hlc_l: float, hlc_c: int) -> bytes:
    """A trigger payload (``hlc_l`` may be ``-inf`` when HLC is off)."""
    return _TRIG.pack(TRIGGER, frame, t_send, dt, hlc_l, hlc_c)


def decode_trigger(b: bytes) -> tuple[int, float, float, float, int]:
    """``(frame, t_send, dt, hlc_l, hlc_c)`` of a trigger payload."""
    if len(b) != _TRIG.size:
        raise WireError(f"trigger: {len(b)} bytes, expected {_TRIG.size}")
    kind, frame, t_send, dt, hl, hc = _TRIG.unpack(b)
    if kind != TRIGGER or not _finite(t_send, dt) or not dt > 0 or math.isnan(hl):
        raise WireError("trigger: bad kind, time or dt")
    return frame, t_send, dt, hl, hc


def encode_state(
    node: int, frame: int, t_gen: float, t_send: float, hlc_l: float, hlc_c: int,
    obs: NDArray[np.float64], republish: bool = False,
) -> bytes:
    """A state payload (``obs``: the node's 12-column published state)."""
    return _STATE.pack(REPUBLISH if republish else STATE, node, frame, t_gen, t_send,
                       hlc_l, hlc_c, *obs.tolist())


def decode_state(
    b: bytes, n: int
) -> tuple[int, int, int, float, float, float, int, NDArray[np.float64]]:
    """``(kind, node, frame, t_gen, t_send, hlc_l, hlc_c, obs)``; ``node`` must be < ``n``."""
    if len(b) != _STATE.size:
        raise WireError(f"state: {len(b)} bytes, expected {_STATE.size}")
    v = _STATE.unpack(b)
    kind, node, frame, t_gen, t_send, hl, hc = v[:7]
    obs = np.asarray(v[7:], dtype=np.float64)
    if kind not in (STATE, REPUBLISH) or node >= n or frame >= 2**31:
        raise WireError(f"state: bad kind {kind}, node {node} or frame {frame}")
    if not _finite(t_gen, t_send) or math.isnan(hl) or not np.isfinite(obs).all():
        raise WireError("state: NaN or infinite field")
    return kind, node, frame, t_gen, t_send, hl, hc, obs


def encode_command(
    node: int, stamp_frame: int, tick: int, t_send: float, values: NDArray[np.float64]
) -> bytes:
    """A command payload (NaN values mean 'keep' and are allowed)."""
    vals = values.tolist()
    return _CMD_HEAD.pack(COMMAND, node, stamp_frame, tick, t_send, len(vals)) + struct.pack(
        f"<{len(vals)}d", *vals
    )


def decode_command(b: bytes, width: int) -> tuple[int, int, int, float, NDArray[np.float64]]:
    """``(node, stamp_frame, tick, t_send, values)``; exactly ``width`` values expected."""
    h = _CMD_HEAD.size
    if len(b) < h:
        raise WireError(f"command: {len(b)} bytes, shorter than its {h}-byte header")
    kind, node, stamp, tick, t_send, m = _CMD_HEAD.unpack(b[:h])
    if kind != COMMAND or m != width or m > MAX_COMMAND_VALUES or len(b) != h + 8 * m:
        raise WireError(f"command: bad kind {kind}, width {m} or length {len(b)}")
    if not math.isfinite(t_send) or stamp < -1:
        raise WireError("command: bad time or stamp")
    values = np.frombuffer(b, dtype="<f8", count=m, offset=h).astype(np.float64)
    if np.isinf(values).any():
        raise WireError("command: infinite value")
    return node, stamp, tick, t_send, values


def encode_rerequest(node: int, frame: int, retry: int, t_send: float) -> bytes:
    """A Lock-Step re-request payload."""
    return _REREQ.pack(REREQUEST, node, frame, min(retry, _U32), t_send)


def decode_rerequest(b: bytes) -> tuple[int, int, int, float]:
    """``(node, frame, retry, t_send)`` of a re-request payload."""
    if len(b) != _REREQ.size:
        raise WireError(f"rerequest: {len(b)} bytes, expected {_REREQ.size}")
    kind, node, frame, retry, t_send = _REREQ.unpack(b)
    if kind != REREQUEST or not math.isfinite(t_send):
        raise WireError("rerequest: bad kind or time")
    return node, frame, retry, t_send
