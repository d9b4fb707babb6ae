"""The cohort engine: frame-level control in SimPy, messages in a compiled core.

:class:`CohortRun` is a :class:`~sigma_des.events.engine.MethodRun` whose
messages (trigger fan-out, node computation, state fan-in, commands) never
become SimPy events. SimPy keeps the frame-level and control events — trigger
issue with the whole-swarm physics step, alignment ticks (with adaptation and
commands) and render ticks. Before each control event at time ``t`` the driver
runs the compiled message core (:mod:`sigma_des.events.cohort_jit`) through every
message event at or before ``t`` (messages come first at equal times, as in the
specification), then hands the batch of state deliveries to the aligner in one
vectorised call, and the latency samples to the collector.

Exactness: the compiled core makes the same floating point operations in the
same order as the per-message engine and reads the same counter-based draws, so
result tables are identical on the same seed. Features whose per-message
behaviour is not reproduced by the core are listed by :func:`unsupported`; for
them :func:`run` falls back to the per-message engine for the whole run and
says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents.base import Behaviour, DynamicsModel
from sigma_des.config import Scenario
from sigma_des.core.draws import DrawCache
from sigma_des.events import cohort_jit as J
from sigma_des.events import cohort_state as CS
from sigma_des.events.align.base import OBS_WIDTH, StateBatch
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.engine import _ROLLBACK, _STEP, END, PAUSED, TRIGGER_DUE, MethodRun

__all__ = ["CohortFallback", "CohortRun", "execute", "make_run", "unsupported"]


class CohortFallback(RuntimeError):
    """The cohort core met something it cannot reproduce exactly (run per message)."""


def unsupported(sc: Scenario, method: str) -> str | None:
    """Why ``method`` on ``sc`` cannot run on the cohort core (None: it can).

    These features fall back to the per-message engine for the whole run: drop and
    degrade faults, NTP-corrected clocks, Gilbert–Elliott loss, MQTT QoS 1 over
    datagrams (resends and PUBACK hops), and the stream transport on a link with
    loss or random latency (in-order hold-back and retransmission); the DDS
    middleware and the ``rpc`` method (issue 16: per-message models only).
    """
    why: list[str] = []
    kinds = sorted({f.kind for f in sc.faults} - {"crash", "slow"})
    if kinds:
        why.append(f"faults of kind {', '.join(kinds)}")
    if sc.clocks.ntp_period > 0:
        why.append("NTP-corrected clocks")
    net = sc.net
    for name, link in (("host_link", net.host_link), ("server_link", net.server_link)):
        if link.loss.model != "bernoulli":
            why.append(f"{name}: Gilbert-Elliott loss")
        elif net.transport == "stream" and (
            link.latency.dist != "constant" or link.loss.p > 0.0
        ):
            why.append(f"{name}: stream transport with loss or random latency")
    if net.transport == "datagram" and net.qos == 1:
        why.append("QoS 1 over datagram (resends, PUBACK hops)")
    if net.middleware == "dds":
        why.append("DDS middleware (per-reader sends, participant threads, heartbeats, discovery)")
    if method == "rpc":
        why.append("rpc method (per-vehicle synchronous calls, game-thread render)")
    return "; ".join(why) if why else None


def make_run(
    sc: Scenario, method: str, dynamics: DynamicsModel, behaviour: Behaviour | None
) -> tuple[MethodRun, str]:
    """The run object for ``sc.engine`` and the fallback reason ("" if none)."""
    if sc.engine == "cohort":
        why = unsupported(sc, method)
        if why is None:
            return CohortRun(sc, method, dynamics, behaviour), ""
        return MethodRun(sc, method, dynamics, behaviour), why
    return MethodRun(sc, method, dynamics, behaviour), ""


def execute(
    sc: Scenario,
    method: str,
    dynamics: Callable[[], DynamicsModel],
    behaviour: Callable[[], Behaviour | None],
    progress: Callable[[float], None] | None = None,
    tap: Callable[[], Any] | None = None,
) -> tuple[MethodRun, dict[str, Any], dict[str, str]]:
    """Run ``method`` on the engine ``sc.engine`` asks for, falling back when needed.

    Args:
        sc: the scenario.
        method: alignment method.
        dynamics: makes the dynamics model (called again for a mid-run fallback).
        behaviour: makes a fresh behaviour (behaviours may keep state).
        progress: called with the simulated time after every simulated second.
        tap: makes a fresh recording tap for each attempt (a mid-run fallback starts
            the recording again); the tap is closed when its attempt ends.

    Returns:
        The finished run, its result dict and ``{"requested", "used", "fallback"}``.
    """
    run, why = make_run(sc, method, dynamics(), behaviour())
    try:
        out = _attempt(run, progress, tap)
    except CohortFallback as exc:  # met mid-run: redo the whole run per message
        why = str(exc)
        run = MethodRun(sc, method, dynamics(), behaviour())
        out = _attempt(run, progress, tap)
    used = "events" if why or sc.engine == "events" else "cohort"
    return run, out, {"requested": sc.engine, "used": used, "fallback": why}


def _attempt(
    run: MethodRun, progress: Callable[[float], None] | None, tap: Callable[[], Any] | None
) -> dict[str, Any]:
    """One run attempt, recorded through a fresh tap when ``tap`` is given."""
    if tap is None:
        return run.run(progress)
    run.tap = tap()
    try:
        return run.run(progress)
    finally:
        run.tap.close()


_Sampler = Callable[[int, int], NDArray[np.float64]]

#: Spare capacity of the core's event table and delivery buffers beyond what one
#: frame needs; they grow (or are flushed) on demand, so this changes speed only.
SLACK = 256


class CohortRun(MethodRun):
    """One scenario under one method, messages processed by the compiled core.

    Args:
        sc: the scenario (must be supported: see :func:`unsupported`).
        method: ``none``, ``hlc`` or ``bides``.
        dynamics: the vectorised dynamics model.
        behaviour: behaviour producing commands (None: no commands).

    Raises:
        CohortFallback: the scenario uses a feature the core does not reproduce.
    """

    def __init__(
        self, sc: Scenario, method: str, dynamics: DynamicsModel, behaviour: Behaviour | None
    ) -> None:
        why = unsupported(sc, method)
        if why is not None:
            raise CohortFallback(why)
        super().__init__(sc, method, dynamics, behaviour)
        n = self.n
        net = self.net
        self.cmd = np.ascontiguousarray(self.cmd, dtype=np.float64)
        self._t_event = 0.0
        R = sc.history_frames
        W = OBS_WIDTH
        M = int(self.cmd.shape[1])
        cap = 4 * (n + 1) + SLACK
        iv = np.zeros(CS.I_LEN, dtype=np.int64)
        iv[CS.I_FREE] = cap
        fv = np.zeros(CS.F_LEN)
        q = np.zeros(CS.Q_LEN, dtype=np.int64)
        q[CS.Q_N] = n
        q[CS.Q_H] = self.H
        q[CS.Q_HLC] = int(self.use_hlc)
        q[CS.Q_WARP] = int(method == "bides" and sc.bides.time_warp)
        q[CS.Q_THETA] = sc.bides.theta_warp
        q[CS.Q_QOS1S] = int(net.qos1 and not net.datagram)
        q[CS.Q_ACK] = net.ack_bytes
        q[CS.Q_W] = W
        q[CS.Q_M] = M
        q[CS.Q_LOCK] = int(method == "lockstep")
        g = np.array([sc.warmup, sc.duration])
        nl = sc.hosts + 1
        spb = np.zeros((2, nl))
        for h in range(nl):
            spb[1, h] = net.up[h].sec_per_byte
            spb[0, h] = net.down[h].sec_per_byte
        # draw tables: a row of all subjects per (source, kind, index), filled by Python
        cmap = np.full((CS.N_SOURCES, 6), -1, dtype=np.int64)
        cval = np.zeros(CS.N_SOURCES)
        self._fills: dict[int, list[tuple[int, _Sampler]]] = {k: [] for k in range(6)}
        p_loss = np.array([sc.net.host_link.loss.p, sc.net.server_link.loss.p])
        combos: list[tuple[int, int, DrawCache]] = []
        for cls, is_server in ((0, False), (1, True)):
            # server → broker: trigger, command, re-request; node → broker: (re)published
            # state; the downlinks carry them on to their receivers
            kinds_up = (1, 3, 4) if is_server else (2, 5)
            kinds_down = (2, 5) if is_server else (1, 3, 4)
            for up, kinds in ((1, kinds_up), (0, kinds_down)):
                src = CS.lat_source(cls, up)
                lat = net.latency_draws(is_server, bool(up))
                for k in kinds:
                    combos.append((src, k, lat))
                    if p_loss[cls] > 0.0:
                        combos.append((CS.U_OFFSET + src, k, net.loss_draws(is_server, bool(up))))
        for k in (1, 2, 3, 4, 5):
            combos.append((CS.SVC_PUB, k, net.broker.publish_draws))
            combos.append((CS.SVC_DEL, k, net.broker.delivery_draws))
        combos.append((CS.STEP, 0, self.step_time))
        nc = 0
        for src, k, cache in combos:
            if cache.constant is not None:
                cval[src] = cache.constant
                continue
            cmap[src, k] = nc
            sampler_kind = _STEP if src == CS.STEP else k
            self._fills[k].append((nc, _vector_of(cache, sampler_kind)))
            nc += 1
        self._dval = np.zeros((max(nc, 1), R, n + 1))
        self._dtag = np.full((max(nc, 1), R), -1, dtype=np.int64)
        wb = np.zeros(6, dtype=np.int64)
        wb[1] = net.wire_bytes(sc.trigger_payload_bits)
        wb[2] = net.wire_bytes(sc.payload_bits)
        wb[3] = net.wire_bytes(sc.commands.payload_bits)
        wb[4] = net.wire_bytes(sc.trigger_payload_bits)
        wb[5] = net.wire_bytes(sc.payload_bits)
        nd = np.zeros((CS.N_ROWS, n), dtype=np.int64)
        nd[[CS.N_FRAME, CS.N_REQ, CS.N_TARGET, CS.N_CSTAMP]] = -1
        self._nd = nd
        # Python-side views used by MethodRun._rollback
        self.rb_steps = nd[CS.N_RB]  # type: ignore[assignment]
        self.node_busy = nd[CS.N_BUSY]  # type: ignore[assignment]
        crash = np.array(self.crash_at, dtype=np.float64)
        ptr = np.zeros(n + 1, dtype=np.int64)
        rows: list[tuple[float, float, float]] = []
        for i in range(n):
            rows.extend(self.slow.get(i, ()))
            ptr[i + 1] = len(rows)
        slow = np.array(rows if rows else [(0.0, 0.0, 1.0)], dtype=np.float64)
        cores = np.zeros((sc.hosts, sc.cores_per_host))
        out_cap = 2 * (n + 1) + SLACK
        lat_cap = 4 * (n + 1) + SLACK
        P = max(W, M)
        fields: list[Any] = [None] * CS.N_FIELDS
        fields[CS.HT] = np.zeros(cap)
        fields[CS.HE] = np.zeros(cap, dtype=np.int64)
        fields[CS.HS] = np.zeros(0, dtype=np.int64)  # unused: keys hold the slot
        fields[CS.EVI] = np.zeros((cap, CS.E_COLS), dtype=np.int64)
        fields[CS.EVF] = np.zeros((cap, CS.EF_PAY + P))
        fields[CS.FREE] = np.arange(cap, dtype=np.int64)[::-1].copy()
        fields[CS.II] = iv
        fields[CS.FF] = fv
        fields[CS.QQ] = q
        fields[CS.GG] = g
        fields[CS.LBUSY] = np.zeros((2, nl))
        fields[CS.LCNT] = np.zeros((2, 2, nl), dtype=np.int64)
        fields[CS.LSPB] = spb
        fields[CS.LINK_OF] = np.array(net.link_of, dtype=np.int64)
        fields[CS.CMAP] = cmap
        fields[CS.CVAL] = cval
        fields[CS.DVAL] = self._dval
        fields[CS.DTAG] = self._dtag
        fields[CS.PLOSS] = p_loss
        fields[CS.WB] = wb
        fields[CS.ND] = nd
        fields[CS.HOST_OF] = np.array(self.host_of, dtype=np.int64)
        fields[CS.CRASH] = crash
        fields[CS.SLOW_PTR] = ptr
        fields[CS.SLOW] = slow
        fields[CS.CORES] = cores
        fields[CS.HLC_L] = np.full(n, -math.inf)
        fields[CS.HLC_C] = np.zeros(n, dtype=np.int64)
        fields[CS.OFF] = np.array(self._offset, dtype=np.float64)
        fields[CS.DRIFT] = np.array(self._drift, dtype=np.float64)
        fields[CS.SLOT_FRAME] = self.slot_frame
        fields[CS.OBS_HIST] = self.obs_hist
        fields[CS.CMD] = self.cmd
        fields[CS.OUT_I] = np.zeros((out_cap, 3), dtype=np.int64)
        fields[CS.OUT_F] = np.zeros((out_cap, 3 + W))
        fields[CS.LAT_BUF] = np.zeros((3, lat_cap))
        last_i = np.zeros((n, 2), dtype=np.int64)
        last_i[:, 0] = -1
        fields[CS.LAST_I] = last_i
        fields[CS.LAST_F] = np.zeros((n, 2 + W))
        fields[CS.LS] = np.zeros((2, n), dtype=np.int64)
        # duplicate check of re-requests and republished states (Lock-Step only)
        seen_shape = (2, n + 1, sc.history_frames) if method == "lockstep" else (2, 1, 1)
        fields[CS.SEEN] = np.full(seen_shape, -1, dtype=np.int64)
        self._lockstep = method == "lockstep"
        self._fields = fields
        self.S = tuple(fields)

    # ------------------------------------------------------------ draw tables

    def _fill(self, kind: int, index: int) -> None:
        """Make the draw rows of ``(kind, index)`` present (a pure function of the key)."""
        R = self._dtag.shape[1]
        r = index % R
        for c, sample in self._fills[kind]:
            if self._dtag[c, r] != index:
                v = sample(index, 0)
                self._dval[c, r, : v.size] = v
                self._dtag[c, r] = index

    # ------------------------------------------------------------ space

    def _ensure_space(self, k: int) -> None:
        iv = self.S[CS.II]
        if iv[CS.I_FREE] >= k + self.n + 4:
            return
        f = self._fields
        old = f[CS.HT].size
        new = 2 * old + k
        if new > CS.MAX_SLOTS:
            raise CohortFallback(f"more than {CS.MAX_SLOTS} messages in flight")
        for pos in (CS.HT, CS.HE):
            a = np.zeros(new, dtype=f[pos].dtype)
            a[:old] = f[pos]
            f[pos] = a
        for pos in (CS.EVI, CS.EVF):
            a = np.zeros((new,) + f[pos].shape[1:], dtype=f[pos].dtype)
            a[:old] = f[pos]
            f[pos] = a
        nfree = int(iv[CS.I_FREE])
        free = np.zeros(new, dtype=np.int64)
        free[:nfree] = f[CS.FREE][:nfree]
        extra = np.arange(new - 1, old - 1, -1, dtype=np.int64)
        free[nfree : nfree + extra.size] = extra
        f[CS.FREE] = free
        iv[CS.I_FREE] = nfree + extra.size
        self.S = tuple(f)

    # ------------------------------------------------------------ MethodRun hooks

    def _send_trigger(self, k: int, stamp: Stamp | None) -> None:
        self._fill(1, k)
        self._fill(2, k)
        self._fill(0, k)
        self._ensure_space(2)
        hl, hc = (stamp.l, stamp.c) if stamp is not None else (math.nan, 0)
        J.publish_trigger(self.S, k, self.kernel.now, hl, hc)
        if self.tap is not None:  # the core keeps no per-node trigger deliveries: the issue
            self.tap.trigger(-1, k, self.kernel.now, math.nan)

    def _send_command_batch(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        if nodes.size == 0:
            return
        self._fill(3, tick)
        self._ensure_space(nodes.size + 2)
        rows = np.ascontiguousarray(cmds, dtype=np.float64)
        J.publish_commands(
            self.S, tick, stamp, nodes.astype(np.int64), rows, self.kernel.now
        )
        if self.tap is not None:  # the core keeps no per-node command deliveries: the sends
            t = self.kernel.now
            self.tap.commands(nodes, tick, t, np.full(nodes.size, math.nan), rows[nodes])

    def rerequest(self, node: int, frame: int, retry: int) -> None:
        index = frame * 64 + min(retry, 63)
        self._fill(4, index)
        self._fill(5, index)
        self._ensure_space(2)
        J.publish_rerequest(self.S, node, frame, index, self.kernel.now)

    def _start_job(self, i: int) -> None:
        """A job start that needs Python (rollback draws): same arithmetic as the core."""
        now = self._t_event
        nd = self._nd
        target = int(nd[CS.N_REQ, i])
        cost = 0.0
        for f in range(int(nd[CS.N_FRAME, i]) + 1, target + 1):
            cost += self.step_time.get(_STEP, i, f, 0)
        rb = int(nd[CS.N_RB, i])
        if rb:
            for j in range(rb):
                cost += self.step_time.get(_ROLLBACK, i, target, j)
            nd[CS.N_RB, i] = 0
        for a, b, factor in self.slow.get(i, ()):
            if a <= now < b:
                cost *= factor
        self._ensure_space(2)
        J.reserve(self.S, i, target, cost, now)

    # ------------------------------------------------------------ driver

    def _sync_barrier(self) -> None:
        """Copy the Lock-Step aligner's barrier state into the core's mirror of it."""
        al: Any = self.aligner
        S = self.S
        S[CS.LS][0] = al.got
        S[CS.LS][1] = al.live
        iv = S[CS.II]
        iv[CS.I_LCUR] = al.current
        iv[CS.I_LMISS] = al.missing
        iv[CS.I_LCOMP] = int(al.complete)

    def _messages(self, bound: float, strict: bool) -> bool:
        """Run the message core to ``bound``, serving its requests for Python.

        Returns:
            True if it stopped early because a Lock-Step barrier completed (the next
            trigger may now come before ``bound``); False when it reached ``bound``.
        """
        while True:
            if self._lockstep:
                self._flush()
                self._sync_barrier()
            code = J.advance(self.S, bound, strict)
            if code == CS.OK:
                return False
            if code == CS.BARRIER:
                # the aligner sees the completing state at its own arrival time
                self.kernel.env._now = float(self.S[CS.FF][CS.F_PT])
                self._flush()
                return True
            if code == CS.NEED_SPACE:
                self._ensure_space(self.n + 8)
            elif code == CS.NEED_FLUSH:
                self._flush()
            elif code == CS.NEED_START:
                self._t_event = float(self.S[CS.FF][CS.F_PT])
                self._start_job(int(self.S[CS.II][CS.I_PNODE]))
            elif code == CS.NEED_ROLLBACK:
                iv = self.S[CS.II]
                i = int(iv[CS.I_PNODE])
                self._t_event = float(self.S[CS.FF][CS.F_PT])
                self._rollback(i, int(iv[CS.I_PA]), int(iv[CS.I_PB]), self.cmd[i].copy())
            else:
                raise CohortFallback(
                    "a message needed a random draw older than history_frames "
                    f"({self.sc.history_frames}) frames"
                )

    def _flush(self) -> None:
        """Hand buffered state deliveries to the aligner, latencies to the collector."""
        S = self.S
        iv = S[CS.II]
        o = int(iv[CS.I_OUT])
        if o:
            oi = S[CS.OUT_I][:o]
            of = S[CS.OUT_F][:o]
            self.aligner.on_states(StateBatch(
                of[:, 0], oi[:, 0], oi[:, 1], of[:, 1], of[:, 3 : 3 + OBS_WIDTH], of[:, 2], oi[:, 2]
            ))
            if self.tap is not None:
                self.tap.states(of[:, 0], oi[:, 0], oi[:, 1], of[:, 1], of[:, 3 : 3 + OBS_WIDTH])
            iv[CS.I_OUT] = 0
        for k in range(3):
            m = int(iv[CS.I_LAT + k])
            if m:
                self.collector.delivered_batch(k + 1, S[CS.LAT_BUF][k, :m].copy(), 0)
                iv[CS.I_LAT + k] = 0

    def _advance(self, progress: Callable[[float], None] | None) -> None:
        env = self.kernel.env
        dur = self.sc.duration
        next_p = 1.0
        while True:
            tc = env.peek()
            last = tc >= dur
            bound = dur if last else tc
            if self._messages(bound, last):
                continue  # a barrier completed: a trigger may now come before tc
            self._flush()
            if progress is not None:
                while next_p < dur and next_p <= bound:
                    progress(next_p)
                    next_p += 1.0
            if last:
                break
            env.step()
        if progress is not None:
            progress(dur)
        self._write_back()

    def advance_until(self, stop: Callable[[], bool]) -> int:
        """:meth:`MethodRun.advance_until` with messages run by the compiled core."""
        env = self.kernel.env
        dur = self.sc.duration
        while True:
            if stop():
                return PAUSED
            tc = env.peek()
            last = tc >= dur
            if self._messages(dur if last else tc, last):
                continue  # a barrier completed: a trigger may now come before tc
            self._flush()
            if last:
                self._write_back()
                return END
            if self.pending_state is None and self._head_is_issue():
                return TRIGGER_DUE
            env.step()

    def _write_back(self) -> None:
        """Copy the core's counters into the objects the collector reads."""
        S = self.S
        net = self.net
        cnt = S[CS.LCNT]
        busy = S[CS.LBUSY]
        for h in range(self.sc.hosts + 1):
            net.up[h].bytes = int(cnt[1, 0, h])
            net.up[h].packets = int(cnt[1, 1, h])
            net.up[h].busy = float(busy[1, h])
            net.down[h].bytes = int(cnt[0, 0, h])
            net.down[h].packets = int(cnt[0, 1, h])
            net.down[h].busy = float(busy[0, h])
        fv = S[CS.FF]
        iv = S[CS.II]
        net.broker.busy = float(fv[CS.F_BUSY])
        net.broker.work = float(fv[CS.F_WORK])
        net.broker.max_wait = float(fv[CS.F_MAXWAIT])
        self.history_misses += int(iv[CS.I_HMISS])
        self.collector.delivered_batch(1, np.empty(0), int(iv[CS.I_MSGS]))
        self.collector.duplicates += int(iv[CS.I_DUPS])
        iv[CS.I_DUPS] = 0
        self.kernel.events += int(iv[CS.I_NEV])
        iv[CS.I_MSGS] = 0
        iv[CS.I_HMISS] = 0
        iv[CS.I_NEV] = 0


def _vector_of(cache: DrawCache, kind: int) -> _Sampler:
    def sample(index: int, attempt: int) -> NDArray[np.float64]:
        return cache.vector(kind, index, attempt)

    return sample
