"""The compiled message core as a backend of the engine (docs/concepts/engines.md).

:class:`CompiledCore` processes the messages of a
:class:`~sigma_des.events.engine.MethodRun` — trigger fan-out, node computation,
state fan-in, commands — without making them SimPy events. The engine keeps the
frame-level and control events (trigger issue with the whole-swarm physics step,
alignment ticks with adaptation and commands, render ticks) and composes the
core through a narrow interface: it publishes triggers, commands and
re-requests (:meth:`~CompiledCore.publish_trigger`, ...), and before each
control event at time ``t`` runs the core to ``t``
(:meth:`~CompiledCore.advance_to`: messages come first at equal times, as in the
specification), which stores the state deliveries in the aligner's ring buffers
(BiDES) or hands them to the aligner in one vectorised call
(:mod:`~sigma_des.events.fast.deliveries`). At the end :meth:`~CompiledCore.write_back`
copies the core's counters and latency samples into the objects the collector reads.

Exactness: the compiled core makes the same floating point operations in the
same order as the per-message engine and reads the same counter-based draws, so
result tables are identical on the same seed.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.models import DynamicsModel
from sigma_des.core.sim import Kernel
from sigma_des.events.align.base import Aligner
from sigma_des.events.align.hlc_clock import Stamp
from sigma_des.events.align.lockstep import LockstepAligner
from sigma_des.events.fast import channel, entries, loop
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.attempts import AttemptTables
from sigma_des.events.fast.deliveries import Deliveries
from sigma_des.events.fast.frame_draws import FrameDraws
from sigma_des.events.fast.growth import TABLE, before_run, grow
from sigma_des.events.fast.outbox import outbox_room
from sigma_des.events.fast.queue import ARENA
from sigma_des.events.fast.rollbacks import Rollbacks
from sigma_des.events.fast.spare import Spare, handed_back, state_for
from sigma_des.events.fast.support import (
    TABLE_MARGIN,
    CohortFallback,
    checked_int,
    unsupported,
)
from sigma_des.events.fast.tables import (
    DrawTables,
    lossy_classes,
    network_sources,
)
from sigma_des.events.node import PhysicsNodes
from sigma_des.events.spec import RunSpec
from sigma_des.events.tap import Tap, records
from sigma_des.events.truth import SwarmTruth
from sigma_des.metrics.collector import Collector
from sigma_des.net.kinds import COMMAND, REPUBLISH, REREQUEST, STATE, TRIGGER, rerequest_index
from sigma_des.net.network import Network

__all__ = ["SLACK", "CompiledCore", "Host"]

#: Spare capacity of the core's event table and delivery buffers beyond what one
#: frame needs; they grow (or are flushed) on demand, so this changes speed only.
SLACK = 256


def _empty(a: NDArray[Any]) -> NDArray[Any]:
    """An array of no rows, of ``a``'s dtype and row shape (one per kind, shared: it holds
    nothing to write, and a closed core never grows it)."""
    key = (a.dtype, a.shape[1:])
    e = _EMPTIES.get(key)
    if e is None:
        e = _EMPTIES[key] = np.zeros((0, *a.shape[1:]), dtype=a.dtype)
    return e


_EMPTIES: dict[tuple[np.dtype[Any], tuple[int, ...]], NDArray[Any]] = {}
#: the positions of the arrays a closed core drops (the event table, the truth's ring)
_DROPPED = tuple(L.INDEX[name] for name in (*TABLE, "obs_hist"))


class Host(Protocol):
    """What the compiled core reads and calls of the engine that composes it."""

    spec: RunSpec
    method: str
    n: int
    kernel: Kernel
    net: Network
    aligner: Aligner
    collector: Collector
    nodes: PhysicsNodes
    truth: SwarmTruth
    tap: Tap
    dyn: DynamicsModel


class CompiledCore:
    """The messages of one run, processed by the compiled loop.

    Args:
        host: the engine composing this core (its physics ring and command array
            are shared with the core, read and written in place).
        spare: what a retired core handed back (:meth:`retire`): its arrays, refilled
            here instead of new ones where their dtype and shape fit, and its seed-free
            values, copied here if this run's spec differs from its run's in the seed at
            most (:mod:`~sigma_des.events.fast.spare`: the same contents either way).

    Raises:
        CohortFallback: the scenario uses a feature the core does not reproduce.
    """

    def __init__(self, host: Host, spare: Spare | None = None) -> None:
        spec = host.spec
        why = unsupported(spec, host.method)
        if why is not None:
            raise CohortFallback(why)
        before_run(trim=spare is None)  # earlier runs' memory back first (growth): not
        # for a core refilling a retired one's arrays (a learning env's next episode)
        self.host = host
        self._lockstep = host.method == "lockstep"
        links = spec.net.net
        p_loss = (links.host_link.loss.p, links.server_link.loss.p)
        lossy = lossy_classes(spec)
        sources = network_sources(host.net, lossy)
        sources.append((CO.STEP, 0, host.nodes.step_time))
        self.tables = DrawTables(sources, spec.history_frames, host.n + 1)
        self.frame_draws = FrameDraws(self.tables, (TRIGGER, STATE, 0))  # 0: compute
        self.command_draws = FrameDraws(self.tables, (COMMAND,))  # a tick's, the same way
        self.rollbacks = Rollbacks(host.truth, host.nodes.step_time, host.n,
                                   host.method == "bides" and spec.time_warp, spec.theta_warp,
                                   self.frame_draws)
        self.deliveries = Deliveries(host, host.n)
        #: how often the loop returned, by exit code (``codes.EXIT_CODES``)
        self.exits = [0] * len(CO.EXIT_CODES)
        self.attempts = AttemptTables(host.net, lossy, spec.history_frames,
                                      host.n + 1, self._lockstep)
        #: the seed-free values handed on by :meth:`retire` (None: none)
        self.S, self._kept = state_for(self, p_loss, SLACK, ARENA, spare)
        self.S[L.INTS][CO.I_FREE] = self.S[L.FREE].size  # every slot is free
        channel.batching(self.S)  # fan-out batches and channels, where they apply
        self._outbox_room = outbox_room(self.S)  # the loop's spare slots for outboxes
        self.S[L.INTS][CO.I_PFREE] = self.S[L.POOL_FREE].size  # and every payload row
        self._closed = False
        self._typed: tuple[NDArray[Any], ...] = ()  # the state _entries was bound for
        self._bound = entries.DISPATCHED
        self._arg: Any = self.S  # what the bound entry points take for it (a handle)

    def ensure_space(self, k: int) -> None:
        """Grow the event table unless ``k`` slots and payload rows (plus a fan-out) are
        free (:func:`~sigma_des.events.fast.growth.grow`: contents and order kept)."""
        self._check_open()
        need = k + self.host.n + 4
        iv = self.S[L.INTS]
        if iv[CO.I_FREE] < need or iv[CO.I_PFREE] < need:
            self.S = grow(self.S, need)
            self._typed = ()  # arrays resized in place: the state is held again (handle.py)

    def load_kernels(self) -> int:
        """Load, for this state's types, the loop's entry points Python calls; return how
        many were not loaded yet. For benchmarks' warm-ups: a tiny run never reaches
        ``publish_commands`` or the rollbacks' entry points (≈ 30 ms to load, which the
        timed run would then pay)."""
        from numba import typeof, types

        s, i64, f64 = typeof(self.S), types.int64, types.float64
        sigs = {loop.advance: (s, f64, types.boolean),
                loop.publish_trigger: (s, i64, f64, f64, i64),
                loop.publish_commands: (s, i64, i64, types.int64[::1], types.float64[:, ::1], f64),
                loop.start: (s, i64, f64), loop.roll_back: (s, i64, i64, i64, f64),
                loop.owe_steps: (s, i64, i64, f64)}
        todo = [(k, sig) for k, sig in sigs.items()
                if sig not in k.signatures]  # type: ignore[attr-defined]
        for kernel, sig in todo:
            kernel.compile(sig)  # type: ignore[attr-defined]
        self._entries()  # and the entry points by handle (fast/entries.py)
        return len(todo)

    def _entries(self) -> entries.Entries:
        """The loop's entry points for the current state, and :attr:`_arg` what they take
        for it (both bound again when the state tuple was replaced:
        :func:`~sigma_des.events.fast.entries.bound`, a new handle)."""
        if self.S is not self._typed:
            self._bound = entries.bound(self.S)
            self._arg = self._bound.arg(self.S)
            self._typed = self.S
        return self._bound

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the run is over: its message core is closed")

    def close(self) -> None:
        """Drop the event table: the messages still in flight (a saturated broker's
        backlog, ≈ 250 MB at N = 1 000 after 60 s), which no result reads, before the
        results are assembled; and the core's reference to the truth's ring of published
        rows, so that :meth:`SwarmTruth.release` frees it. The core carries no more
        messages after it."""
        S = self.S
        closed = list(S)
        for i in _DROPPED:
            closed[i] = _empty(S[i])
        self.S = tuple(closed)
        self._closed = True
        self._typed, self._arg = (), None  # the handle held the old tuple (handle.py)

    def retire(self) -> Spare:
        """Close the core (:meth:`close`) and hand back, for a new core
        (:mod:`~sigma_des.events.fast.spare`), the arrays of its own (the fields with a
        fill and the seed-free ones it was given: no other object holds them) and its
        kept seed-free values (if it was made from a spare).

        The caller must hold no view of the arrays, and nothing may run this core again.
        """
        S = self.S
        self.close()
        return handed_back(S, self._kept)

    def array(self, name: str) -> NDArray[Any]:
        """The state array of field ``name`` (see :data:`~sigma_des.events.fast.layout.FIELDS`)."""
        return self.S[L.INDEX[name]]

    # ------------------------------------------------------------ publishes

    def publish_trigger(self, k: int, stamp: Stamp | None) -> None:
        """The server publishes trigger ``k`` to every node, now."""
        self.frame_draws.fill(k)  # the trigger's, its states' and the compute draws
        if self.attempts.acks:
            self.attempts.fill_ack(TRIGGER, k)
            self.attempts.fill_ack(STATE, k)
        self.ensure_space(2)
        hl, hc = (float(stamp.l), stamp.c) if stamp is not None else (math.nan, 0)
        now = self.host.kernel.now
        self._entries().publish_trigger(self._arg, checked_int(k, "trigger index"), now, hl,
                                        checked_int(hc, "trigger HLC counter"))
        # the core keeps no per-node trigger deliveries: the tap records the issue
        self.host.tap.issue(k, now)
        self.host.tap.trigger(-1, k, now, math.nan)

    def publish_commands(
        self, tick: int, stamp: int, nodes: NDArray[np.int64], cmds: NDArray[np.float64]
    ) -> None:
        """The server publishes ``cmds[i]`` (stamped ``stamp``) to each node ``i``, now."""
        if nodes.size == 0:
            return
        self.command_draws.fill(tick)
        if self.attempts.acks:
            self.attempts.fill_ack(COMMAND, tick)
        self.ensure_space(nodes.size + 2)
        rows = np.ascontiguousarray(cmds, dtype=np.float64)
        if rows.ndim != 2:
            raise ValueError(f"cmds: one row per node, got shape {rows.shape}")
        now = self.host.kernel.now
        self._entries().publish_commands(self._arg, checked_int(tick, "command tick"),
                                         checked_int(stamp, "command stamp"),
                                         np.ascontiguousarray(nodes, dtype=np.int64), rows, now)
        # the core keeps no per-node command deliveries: the tap records the sends
        tap = self.host.tap
        if records(tap, "commands"):
            tap.commands(nodes, tick, now, np.full(nodes.size, math.nan), rows[nodes])

    def publish_rerequest(self, node: int, frame: int, retry: int) -> None:
        """Lock-Step: the server re-requests ``node``'s state of ``frame``, now."""
        index = checked_int(rerequest_index(frame, retry), "re-request index")
        self.tables.fill(REREQUEST, index)
        self.tables.fill(REPUBLISH, index)
        self.attempts.fill_ack(REREQUEST, index)
        self.attempts.fill_ack(REPUBLISH, index)
        self.ensure_space(2)
        loop.publish_rerequest(self.S, node, frame, index, self.host.kernel.now)

    def server_free(self, t: float) -> float:
        """When the server process's loop thread is free of the bursts queued on it by
        ``t`` (Network.server_free; every message at or before ``t`` has run)."""
        if self.host.net.cpu is None:
            return t
        free = float(self.S[L.CPU_FREE][CO.P_SERVER])
        return free if free > t else t

    def server_tick(self, t: float) -> None:
        """An alignment tick at ``t``: a ``deployment.server_tick`` burst on the server's
        process (Network.server_tick), after every message at or before ``t``."""
        h = self.host
        tick = h.spec.net.deployment.server_tick
        if h.net.cpu is not None and tick > 0.0:
            loop.tick(self.S, CO.P_SERVER, tick, t)

    # ------------------------------------------------------------ nodes

    def exit_counts(self) -> dict[str, int]:
        """How often the loop returned to Python so far, by exit code name."""
        return {name: self.exits[code] for name, code in CO.EXIT_CODES.items()}

    def _rollback(self, i: int, c: int, current: int, now: float) -> None:
        """The rollback of node ``i`` to ``c`` the loop handed over (``NEED_ROLLBACK``).

        A second rollback of a node whose re-simulation is still owed flushes the
        first, then joins the loop's deferred ones; without batched steps (or with
        nothing to re-simulate) the truth rolls back at once and the loop owes the steps.
        """
        truth = self.host.truth
        if self.S[L.RESIM_PEND][i]:
            self.flush_rollbacks()
        self.ensure_space(2)
        if truth.batched and truth.first_resim(c) <= truth.latest:
            self._entries().roll_back(self._arg, i, c, current, now)
        else:
            steps = truth.rollback(i, c, current, self.host.nodes.cmd[i])
            self._entries().owe_steps(self._arg, i, steps, now)
        iv = self.S[L.INTS]
        if iv[CO.I_PEND] == CO.NEED_START:  # the job start it made needs rollback draws
            iv[CO.I_PEND] = 0
            self._start_job(i, now)

    def flush_rollbacks(self) -> None:
        """Re-simulate the deferred rollbacks (one batched call) and unmark their nodes."""
        self.rollbacks.flush(self.S)

    def _start_job(self, i: int, now: float) -> None:
        """Node ``i``'s job start the loop handed over (``NEED_START``): fill the rollback
        draws it owes into their table, then start it in the loop."""
        nd = self.S[L.NODE]
        self.S = self.rollbacks.fill(self.S, int(nd[CO.N_REQ, i]), int(nd[CO.N_RB, i]))
        self.ensure_space(2)
        self._entries().start(self._arg, i, now)

    # ------------------------------------------------------------ running

    def _sync_barrier(self) -> None:
        """Copy the Lock-Step aligner's barrier state into the core's mirror of it."""
        al = self.host.aligner
        assert isinstance(al, LockstepAligner)
        b = al.barrier()
        S = self.S
        S[L.LS_MIRROR][0] = b.got
        S[L.LS_MIRROR][1] = b.live
        iv = S[L.INTS]
        iv[CO.I_LCUR] = b.current
        iv[CO.I_LMISS] = b.missing
        iv[CO.I_LCOMP] = int(b.complete)

    def advance_to(self, bound: float, strict: bool) -> bool:
        """Run the messages up to ``bound`` (``< bound`` if ``strict``), then drain them.

        Serves the loop's requests for Python on the way (second rollbacks of a node
        still owed its re-simulation, job starts whose rollback draws are not in their
        table yet, buffer flushes, table growth, deferred re-simulations) and
        re-simulates every deferred rollback before it returns.

        Returns:
            True if it stopped early because a Lock-Step barrier completed (the next
            trigger may now come before ``bound``); False when it reached ``bound``.

        Raises:
            CohortFallback: a message needed a draw older than ``history_frames``.
        """
        self._check_open()
        self.S[L.INTS][CO.I_LATEST] = self.host.truth.latest  # rollbacks clamp to the ring
        self.deliveries.watch(self.S)  # a recording tap takes the states too
        while True:
            if self._lockstep:
                self.drain()
                self._sync_barrier()
            code = self._entries().advance(self._arg, float(bound), bool(strict))
            self.exits[code] += 1
            if code == CO.OK:  # (neither call has anything to do when its count is 0)
                iv = self.S[L.INTS]
                if iv[CO.I_DEFN]:
                    self.flush_rollbacks()
                if iv[CO.I_OUT]:
                    self.drain()
                return False
            if code == CO.BARRIER:
                # the aligner sees the completing state at its own arrival time
                self.flush_rollbacks()
                self.host.kernel.jump_to(float(self.S[L.FLOATS][CO.F_PT]))
                self.drain()
                return True
            self.serve(code)

    def serve(self, code: int) -> None:
        """Serve the loop's request for Python ``code`` (an exit of :func:`loop.advance`
        other than ``OK`` and ``BARRIER``); the loop then goes on where it stopped.

        Raises:
            CohortFallback: a message needed a draw older than ``history_frames``.
        """
        S = self.S
        if code == CO.NEED_SPACE:
            self.ensure_space(self.host.n + 8 + self._outbox_room)
        elif code == CO.NEED_FLUSH:
            self.drain()
            self.deliveries.latencies(S)
        elif code == CO.NEED_RESIM:
            self.flush_rollbacks()
        elif code == CO.NEED_FILL:  # a resend's draws (QoS 1 over datagram)
            tr = S[L.TR_INTS]
            self.attempts.fill(int(tr[CO.T_FKIND]), int(tr[CO.T_FINDEX]), int(tr[CO.T_FATT]))
        elif code in (CO.NEED_START, CO.NEED_ROLLBACK):
            now = float(S[L.FLOATS][CO.F_PT])
            i = int(S[L.INTS][CO.I_PNODE])
            if code == CO.NEED_START:
                self._start_job(i, now)
            else:
                self._rollback(i, int(S[L.INTS][CO.I_PA]), int(S[L.INTS][CO.I_PB]), now)
        else:
            raise CohortFallback(self._error(int(S[L.INTS][CO.I_ERR])))

    def _error(self, code: int) -> str:
        """Why the loop stopped with error ``code`` (the run falls back)."""
        return {
            L.ERR_HORIZON: "a send or clock reading beyond the link and clock tables "
                           f"(the run's end + {TABLE_MARGIN} s)",
            L.ERR_OUTBOX: f"more than {CO.OB_CAP} publishes of one process waiting for its "
                          "thread (deployment.lock_switch)",
            L.ERR_RANGE: "an HLC counter or stream sequence number beyond the event table's "
                         f"int32 columns (largest {L.EV_INT_MAX})",
        }.get(code, "a message needed a random draw older than history_frames "
                    f"({self.host.spec.history_frames}) frames")

    def drain(self) -> None:
        """Hand the buffered state deliveries to the aligner (unless the loop stored them
        in its ring) and the recording tap (:class:`~.deliveries.Deliveries`)."""
        self.deliveries.states(self.S)

    def write_back(self) -> None:
        """Hand the core's counters to the components that report them (their hooks);
        the counters handed over are zeroed, so a second call adds nothing."""
        S = self.S
        h = self.host
        self.deliveries.latencies(S)
        cnt = S[L.LINK_COUNT]
        fv = S[L.FLOATS]
        iv = S[L.INTS]
        tr = S[L.TR_INTS]
        h.net.carried(cnt[:, 0], cnt[:, 1], S[L.LINK_BUSY], int(tr[CO.T_RETX]),
                      int(tr[CO.T_GAVE]))
        cnt[:] = 0
        tr[CO.T_RETX] = tr[CO.T_GAVE] = 0
        h.net.broker.carried(float(fv[CO.F_BUSY]), float(fv[CO.F_WORK]), float(fv[CO.F_MAXWAIT]))
        fv[CO.F_WORK] = fv[CO.F_MAXWAIT] = 0.0
        cpu = h.net.cpu
        if cpu is not None:  # every burst of the run was served here (server ticks too)
            acc = S[L.CPU_ACC]
            nb = S[L.CPU_BURSTS]
            for p, proc in enumerate(cpu.processes):
                proc.carried(float(S[L.CPU_FREE][p]), float(acc[p, CO.CA_BUSY]),
                             float(acc[p, CO.CA_WAIT]), int(nb[p]), float(acc[p, CO.CA_QUEUED]))
            acc[:] = 0.0
            nb[:] = 0
        h.nodes.count_history_misses(int(iv[CO.I_HMISS]))
        h.collector.delivered_batch(1, np.empty(0), int(iv[CO.I_MSGS]), int(iv[CO.I_DUPS]))
        h.kernel.count(int(iv[CO.I_NEV]))
        for slot in (CO.I_DUPS, CO.I_MSGS, CO.I_HMISS, CO.I_NEV):
            iv[slot] = 0
