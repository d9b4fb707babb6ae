"""Live-mode topics and the binary payload layout (little-endian ``struct``).

Topics of run ``R`` (``R`` is a per-run token, :func:`run_token`: 8 random hex digits
and the method, so two runs on one broker never mix):

* downstream (server -> hosts): ``sd/R/down/trig`` (triggers, one per frame, to
  every host), ``sd/R/down/h<H>/cmd`` (behaviour commands for nodes of host H),
  ``sd/R/down/h<H>/rereq`` (Lock-Step re-requests), ``sd/R/down/ctl`` (``stop``);
* upstream (hosts -> server): ``sd/R/up/h<H>/state``, ``…/ready``, ``…/stats`` (JSON).

Payloads (bytes in brackets; ``f64`` times in s since the run's start; the kind byte
is the message kind of :mod:`sigma_des.net.kinds`):

* trigger [33]: kind u8 = 1, frame u32, t_send f64, dt f64, hlc_l f64, hlc_c u32
* state [93]: kind u8 = 2 (5 = republished), node u32, frame u32, index u64 (the
  frame; a republish: the re-request it answers), t_gen f64, t_send f64, hlc_l f64,
  hlc_c u32, 12 x f32 published state (``OBS_FIELDS``)
* command [23 + 8 m]: kind u8 = 3, node u32, stamp_frame i32, tick u32, t_send f64,
  m u16, m x f64 values
* rerequest [21]: kind u8 = 4, node u32, frame u32, retry u32, t_send f64

With ``--bundle`` a host's states of one loop turn are records back to back in one
PUBLISH (at most :data:`MAX_BUNDLE`). A state is 93 bytes, not the paper's 150 bits:
it carries the whole published state in float32 plus the times and HLC fields the
measurements need (``calibrate`` sets the DES's ``payload_bits`` to match). Every
decoder checks length, kind, ranges and finiteness and raises :class:`WireError` on
anything else; given the run's :class:`Window`, also that frames and times lie within
the run (a forged trigger for frame 2^32-1 would make a host step four billion frames).
Control messages: :func:`decode_control`; the hosts' counters: :func:`check_stats`.
"""

from __future__ import annotations

import json
import math
import secrets
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, RETRY_SLOTS, STATE, TRIGGER

__all__ = [
    "COMMAND",
    "REPUBLISH",
    "REREQUEST",
    "STATE",
    "TRIGGER",
    "STATS_FIELDS",
    "Topics",
    "Window",
    "WireError",
    "check_stats",
    "decode_control",
    "decode_command",
    "decode_rerequest",
    "decode_state",
    "decode_trigger",
    "encode_command",
    "encode_rerequest",
    "encode_state",
    "encode_trigger",
    "MAX_BUNDLE",
    "REREQUEST_BYTES",
    "RUN_TOKEN_DIGITS",
    "STATE_BYTES",
    "TRIGGER_BYTES",
    "command_bytes",
    "run_token",
    "state_topic_bytes",
]

_TRIG = struct.Struct("<BIdddI")
_STATE = struct.Struct("<BIIQdddI12f")
_CMD_HEAD = struct.Struct("<BIiIdH")
_REREQ = struct.Struct("<BIIId")
TRIGGER_BYTES = _TRIG.size
STATE_BYTES = _STATE.size
REREQUEST_BYTES = _REREQ.size
#: Random hex digits that open a run's topic token (:func:`run_token`).
RUN_TOKEN_DIGITS = 8
MAX_COMMAND_VALUES = 64
#: Most states one PUBLISH may carry (``--bundle``: a host's states of one loop turn).
MAX_BUNDLE = 4096
_U32 = 2**32 - 1
#: Largest magnitude accepted for a published state or command value, and HLC time.
MAX_VALUE = 1e9
#: Hosts wait this long after ``duration`` for ``stop`` (their loop's bound).
LINGER_S = 120.0
#: The server's ``go`` puts the time origin at most this far ahead (``idle_window``).
MAX_IDLE_S = 60.0


class WireError(ValueError):
    """A payload that is malformed, truncated, oversized, out of range or not finite."""


@dataclass(frozen=True)
class Window:
    """What the messages of one run may carry.

    Attributes:
        max_frame: the last frame the run can trigger (``duration * f_trig`` + 2: the
            rate never rises above the nominal ``f_trig``).
        f_trig: the nominal trigger rate (Hz): frame ``k`` is issued no sooner than
            ``k / f_trig`` s after the start.
        t_lo: earliest time a message may carry (s since the run's start).
        t_hi: latest time a message may carry.
        dt_max: longest trigger step (s): ``1 / bides.f_trig_min``, with slack.
    """

    max_frame: int
    f_trig: float
    t_lo: float
    t_hi: float
    dt_max: float

    @classmethod
    def of(cls, duration: float, f_trig: float, f_trig_min: float) -> Window:
        """The window of a run of ``duration`` s at nominal rate ``f_trig``."""
        return cls(max_frame=int(math.ceil(duration * f_trig)) + 2, f_trig=f_trig,
                   t_lo=-MAX_IDLE_S - 1.0, t_hi=duration + LINGER_S + 1.0,
                   dt_max=1.5 / min(f_trig, f_trig_min))

    def frame(self, what: str, k: int) -> None:
        """Raise :class:`WireError` unless frame ``k`` lies in the run."""
        if not 0 <= k <= self.max_frame:
            raise WireError(f"{what}: frame {k} outside 0..{self.max_frame}")

    def times(self, what: str, *ts: float) -> None:
        """Raise :class:`WireError` unless every time lies in the run."""
        for t in ts:
            if not self.t_lo <= t <= self.t_hi:
                raise WireError(f"{what}: time {t} outside {self.t_lo:g}..{self.t_hi:g} s")


def _hlc_ok(hl: float) -> bool:
    """An HLC time: ``-inf`` (HLC off) or a finite time of sane magnitude."""
    return hl == -math.inf or (math.isfinite(hl) and abs(hl) <= MAX_VALUE)


def command_bytes(width: int) -> int:
    """Bytes of one command record of ``width`` values (``23 + 8 * width``)."""
    return _CMD_HEAD.size + 8 * width


def run_token(method: str) -> str:
    """A fresh run token for a run of ``method``: random hex digits, then the method."""
    return secrets.token_hex(RUN_TOKEN_DIGITS // 2) + method


def state_topic_bytes(method: str, host: int) -> int:
    """Bytes of ``host``'s state topic in any run of ``method`` (its token's length is
    fixed)."""
    return len(Topics("0" * RUN_TOKEN_DIGITS + method).state(host).encode("utf-8"))


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


def decode_trigger(b: bytes, win: Window | None = None,
                   t_recv: float | None = None) -> tuple[int, float, float, float, int]:
    """``(frame, t_send, dt, hlc_l, hlc_c)`` of a trigger payload.

    Args:
        b: the payload.
        win: the run's window (None: no frame/time range checks).
        t_recv: when it arrived (s since the start; with ``win``): a trigger must not
            be for a frame the server cannot have issued yet.
    """
    if len(b) != _TRIG.size:
        raise WireError(f"trigger: {len(b)} bytes, expected {_TRIG.size}")
    kind, frame, t_send, dt, hl, hc = _TRIG.unpack(b)
    if kind != TRIGGER or not _finite(t_send, dt) or not dt > 0 or math.isnan(hl):
        raise WireError("trigger: bad kind, time or dt")
    if win is not None:
        win.frame("trigger", frame)
        win.times("trigger", t_send)
        if dt > win.dt_max or not _hlc_ok(hl):
            raise WireError(f"trigger: dt {dt} above {win.dt_max:g} s or bad HLC time {hl}")
        if t_recv is not None and frame > win.f_trig * (max(t_recv, 0.0) + 1.0) + 2:
            raise WireError(f"trigger: frame {frame} cannot have been issued by {t_recv:.3f} s")
    return frame, t_send, dt, hl, hc


def encode_state(
    node: int, frame: int, t_gen: float, t_send: float, hlc_l: float, hlc_c: int,
    obs: NDArray[np.float64], republish: bool = False, index: int = -1,
) -> bytes:
    """A state payload (``obs``: the node's 12-column published state). A republish
    carries ``index``, the re-request it answers
    (:func:`~sigma_des.net.kinds.rerequest_index`): the key of its draws and of its
    delivery, as the DES's REPUBLISH; a state carries its frame there.

    Raises:
        ValueError: a republish without its re-request's index.
    """
    if republish and index < 0:
        raise ValueError("encode_state: a republish needs the index of its re-request")
    return _STATE.pack(REPUBLISH if republish else STATE, node, frame,
                       index if republish else frame, t_gen, t_send, hlc_l, hlc_c,
                       *obs.tolist())


def decode_state(
    b: bytes, n: int, win: Window | None = None
) -> tuple[int, int, int, int, float, float, float, int, NDArray[np.float64]]:
    """``(kind, node, frame, index, t_gen, t_send, hlc_l, hlc_c, obs)``; ``node`` must be
    < ``n``, a state's ``index`` its frame, a republish's that of a re-request of its
    frame or a later one (a node republishes its last state) (and, given the run's window
    ``win``, frame and times within the run)."""
    if len(b) != _STATE.size:
        raise WireError(f"state: {len(b)} bytes, expected {_STATE.size}")
    v = _STATE.unpack(b)
    kind, node, frame, index, t_gen, t_send, hl, hc = v[:8]
    obs = np.asarray(v[8:], dtype=np.float64)
    if kind not in (STATE, REPUBLISH) or node >= n or frame >= 2**31:
        raise WireError(f"state: bad kind {kind}, node {node} or frame {frame}")
    if (index != frame) if kind == STATE else not (
            frame * RETRY_SLOTS <= index < 2**31 * RETRY_SLOTS):
        raise WireError(f"state: index {index} of a {'state' if kind == STATE else 'republish'}"
                        f" of frame {frame}")
    if not _finite(t_gen, t_send) or math.isnan(hl) or not np.isfinite(obs).all():
        raise WireError("state: NaN or infinite field")
    if win is not None:
        win.frame("state", frame)
        win.times("state", t_gen, t_send)
        if not _hlc_ok(hl) or np.abs(obs).max() > MAX_VALUE:
            raise WireError(f"state: HLC time or a published value beyond {MAX_VALUE:g}")
    return kind, node, frame, index, t_gen, t_send, hl, hc, obs


def encode_command(
    node: int, stamp_frame: int, tick: int, t_send: float, values: NDArray[np.float64]
) -> bytes:
    """A command payload (NaN values mean 'keep' and are allowed)."""
    vals = values.tolist()
    return _CMD_HEAD.pack(COMMAND, node, stamp_frame, tick, t_send, len(vals)) + struct.pack(
        f"<{len(vals)}d", *vals
    )


def decode_command(b: bytes, width: int, win: Window | None = None
                   ) -> tuple[int, int, int, float, NDArray[np.float64]]:
    """``(node, stamp_frame, tick, t_send, values)``; exactly ``width`` values expected
    (and, given the run's window ``win``, stamp, time and values within the run)."""
    h = _CMD_HEAD.size
    if len(b) < h:
        raise WireError(f"command: {len(b)} bytes, shorter than its {h}-byte header")
    kind, node, stamp, tick, t_send, m = _CMD_HEAD.unpack(b[:h])
    if kind != COMMAND or m != width or m > MAX_COMMAND_VALUES or len(b) != command_bytes(m):
        raise WireError(f"command: bad kind {kind}, width {m} or length {len(b)}")
    if not math.isfinite(t_send) or stamp < -1:
        raise WireError("command: bad time or stamp")
    values = np.frombuffer(b, dtype="<f8", count=m, offset=h).astype(np.float64)
    if np.isinf(values).any():
        raise WireError("command: infinite value")
    if win is not None:
        if stamp > win.max_frame or tick > _U32 // 2:
            raise WireError(f"command: stamp {stamp} or tick {tick} outside the run")
        win.times("command", t_send)
        if (np.abs(values[~np.isnan(values)]) > MAX_VALUE).any():
            raise WireError(f"command: a value beyond {MAX_VALUE:g}")
    return node, stamp, tick, t_send, values


def encode_rerequest(node: int, frame: int, retry: int, t_send: float) -> bytes:
    """A Lock-Step re-request payload."""
    return _REREQ.pack(REREQUEST, node, frame, min(retry, _U32), t_send)


def decode_rerequest(b: bytes, win: Window | None = None) -> tuple[int, int, int, float]:
    """``(node, frame, retry, t_send)`` of a re-request payload (given the run's window
    ``win``: frame and time within the run)."""
    if len(b) != _REREQ.size:
        raise WireError(f"rerequest: {len(b)} bytes, expected {_REREQ.size}")
    kind, node, frame, retry, t_send = _REREQ.unpack(b)
    if kind != REREQUEST or not math.isfinite(t_send):
        raise WireError("rerequest: bad kind or time")
    if win is not None:
        win.frame("rerequest", frame)
        win.times("rerequest", t_send)
    return node, frame, retry, t_send


def decode_control(b: bytes, mono_now: float) -> tuple[str, float]:
    """``("go", t0)`` or ``("stop", nan)`` of a control payload.

    Args:
        b: the payload: ``go:<t0>`` (``t0``: the run's time origin, monotonic seconds,
            at most :data:`MAX_IDLE_S` s ahead) or ``stop``.
        mono_now: ``time.monotonic()`` now (one clock for every process of a run).
    """
    if b == b"stop":
        return "stop", math.nan
    if not b.startswith(b"go:") or len(b) > 40:
        raise WireError("control: neither go:<t0> nor stop")
    try:
        t0 = float(b[3:].decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        raise WireError("control: go:<t0> needs a number") from None
    if not mono_now - 10.0 <= t0 <= mono_now + MAX_IDLE_S + 1.0:
        raise WireError(f"control: t0 {t0!r} is not within the next {MAX_IDLE_S:g} s")
    return "go", t0


#: The hosts' end-of-run counters: non-negative integers, but ``links`` (a dict of
#: ``"<link>.<dir>": [bytes, packets]``), ``host`` and ``step_real_s`` (seconds).
STATS_FIELDS = ("rollbacks", "resim_steps", "history_misses", "rejected", "resent", "gave_up",
                "connects", "disconnects", "steps")


def _count(x: Any) -> bool:
    return type(x) is int and 0 <= x < 2**53


def _wake_ok(w: Any) -> bool:
    """A loop's wake-up sums (:class:`~sigma_des.live.loop.WakeStats`): two counts and
    three (four with ``wall_s``, which a host before it did not send) non-negative
    finite floats."""
    keys = {"wakes", "calls", "cpu_s", "skk", "skc"}
    if not isinstance(w, dict) or set(w) not in (keys, keys | {"wall_s"}):
        return False
    if not (_count(w["wakes"]) and _count(w["calls"])):
        return False
    return all(type(w[k]) in (int, float) and 0 <= w[k] < 1e18 for k in set(w) - {"wakes", "calls"})


def check_stats(payload: bytes, host: int) -> dict[str, Any]:
    """The end-of-run counters of ``host`` from their JSON payload, checked field by field.

    Raises:
        WireError: not JSON, not an object, a field missing, extra, of the wrong type
            or out of range, or ``host`` not the publishing host.
    """
    try:
        st = json.loads(payload)
    except (ValueError, RecursionError):
        raise WireError("stats: not JSON") from None
    keys = {"host", "links", "step_real_s", "wake", *STATS_FIELDS}
    if not isinstance(st, dict) or set(st) != keys:
        raise WireError(f"stats: must be an object with exactly the keys {sorted(keys)}")
    if st["host"] != host or type(st["host"]) is not int:
        raise WireError(f"stats: host {st['host']!r} is not {host}")
    bad = [k for k in STATS_FIELDS if not _count(st[k])]
    s = st["step_real_s"]
    if type(s) not in (int, float) or not 0 <= s <= 1e9:
        bad.append("step_real_s")
    if not _wake_ok(st["wake"]):
        bad.append("wake")
    links = st["links"]
    if not isinstance(links, dict) or len(links) > 1024 or not all(
            isinstance(v, list) and len(v) == 2 and _count(v[0]) and _count(v[1])
            for v in links.values()):
        bad.append("links")
    if bad:
        raise WireError(f"stats: bad {', '.join(bad)}")
    return st
