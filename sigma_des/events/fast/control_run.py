"""A run's control events handed to the compiled control loop (:mod:`~.control`).

:class:`CompiledControl` takes over a :class:`~sigma_des.events.engine.MethodRun` that
runs on the compiled core: from then on its trigger issues and alignment ticks run in
:func:`~sigma_des.events.fast.control.run`, not on the SimPy kernel, and
:meth:`CompiledControl.advance_until` replaces the run's own stepping hook. Python serves
what the loop returns for (the core's requests, deferred rollbacks, a block of frame
draws, room for a fan-out, a command tick) and keeps the run's objects — trigger source,
aligner, truth, kernel clock — up to date at each return, so the run reads as if its
events had run on the kernel.

:func:`unsupported` says why a run cannot be taken over (then it keeps its own path):
the loop covers BiDES and ``none`` without metrics, recording or trajectory log, on a
dynamics model with compiled kernels (``compiled_physics``) whose rollbacks are not
deferred.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.filled import filled
from sigma_des.core.models import Behaviour, DynamicsModel, SwarmView
from sigma_des.core.sim import Kernel
from sigma_des.events.align.base import Aligner
from sigma_des.events.align.bides import BidesAligner
from sigma_des.events.align.none import NoneAligner
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import control as C
from sigma_des.events.fast.dispatch import compute_fingerprint
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.events.fast.handle import HandleType
from sigma_des.events.spec import RunSpec
from sigma_des.events.tap import Tap
from sigma_des.events.trigger import TriggerSource
from sigma_des.events.truth import NO_LOG, SwarmTruth
from sigma_des.metrics.null import NullCollector

__all__ = ["END", "PAUSED", "CompiledControl", "unsupported"]

#: Stop codes of :meth:`CompiledControl.advance_until` (those of ``MethodRun.advance_until``)
PAUSED = 0
END = 2


class _Run(Protocol):
    """What the control loop reads and calls of the run it takes over (a ``MethodRun``)."""

    spec: RunSpec
    method: str
    n: int
    kernel: Kernel
    trigger: TriggerSource
    aligner: Aligner
    truth: SwarmTruth
    core: Any
    tap: Tap
    collector: Any
    dyn: DynamicsModel
    behaviour: Behaviour | None
    align_tick: int
    nodes: Any

    def align(self) -> None: ...

    def _align(self) -> None: ...

    def send_commands(self) -> None: ...

    def publish_commands(self, tick: int, stamp: int, nodes: NDArray[np.int64],
                         cmds: NDArray[np.float64]) -> None: ...


def unsupported(run: _Run) -> str | None:
    """Why ``run``'s control events cannot run compiled (None: they can)."""
    if not isinstance(run.core, CompiledCore):
        return "the run is not on the compiled core"
    if run.method not in ("bides", "none") or not isinstance(run.aligner,
                                                             (BidesAligner, NoneAligner)):
        return f"method {run.method!r} (only bides and none)"
    if not isinstance(run.collector, NullCollector):
        return "the run collects metrics"
    if type(run.tap) is not Tap:
        return "the run is recorded"
    truth = run.truth
    if truth.traj is not NO_LOG or truth.stepped_rows is not None:
        return "the truth keeps a trajectory log or held rows"
    if getattr(run.dyn, "compiled_physics", None) is None:
        return f"dynamics {run.dyn.name!r} has no compiled kernels"
    if run.core.attempts.acks:
        return "acknowledged messages"
    own = (run.trigger.issue, run.align, run._align)
    other = [ev for *_, ev in run.kernel.env._queue  # type: ignore[attr-defined]
             if getattr(ev, "fn", None) not in own]
    if other:  # e.g. a fault's timer: only the trigger and the tick run in the loop
        return f"the kernel holds other events ({getattr(other[0], 'fn', other[0])!r})"
    return None


def _method(al: Aligner, ci: NDArray[np.int64], cf: NDArray[np.float64]
            ) -> tuple[NDArray[Any], ...]:
    """The aligner's method and parameters into the control state; the newest-state
    arrays the loop writes for ``none`` (the aligner's own; placeholders for BiDES)."""
    if isinstance(al, NoneAligner):
        ci[C.CI_METHOD] = C.NONE
        ci[C.CI_DIRTY] = int(al._dirty)
        al._dirty = False  # the loop's flag from now on
        return al._frame, al._gen, al._obs
    assert isinstance(al, BidesAligner)
    b = al.spec
    ci[C.CI_METHOD] = C.BIDES
    ci[C.CI_HI], ci[C.CI_LO], ci[C.CI_RATE_CHANGES] = al._hi, al._lo, al.rate_changes
    ci[C.CI_ADAPT] = int(b.adaptation)
    ci[C.CI_THETA_LAG] = b.theta_lag if b.lag_exclusion else -1
    ci[C.CI_HOLE_FILL] = int(b.hole_fill)
    ci[C.CI_LAG_HIGH], ci[C.CI_LAG_LOW] = b.lag_high, b.lag_low
    ci[C.CI_HOLD_DOWN], ci[C.CI_HOLD_UP] = b.hold_down, b.hold_up
    cf[C.CF_F_NOMINAL], cf[C.CF_F_MIN] = al.f_nominal, b.f_trig_min
    cf[C.CF_RATE_DOWN], cf[C.CF_RATE_UP] = b.rate_down, b.rate_up
    return (filled(1, -1, np.int64), filled(1, np.nan),
            filled((1, al.shown_obs.shape[1]), np.nan))


class CompiledControl:
    """The control events of ``run`` in the compiled loop (see the module docstring).

    Args:
        run: the run, started (:meth:`MethodRun.start`) and not advanced by its own hooks
            since (its pending control events are read off the kernel).

    Raises:
        ValueError: the run is not supported (:func:`unsupported`) or its kernel holds an
            event other than the trigger issue and the alignment tick.
    """

    def __init__(self, run: _Run) -> None:
        why = unsupported(run)
        if why is not None:
            raise ValueError(f"compiled control: {why}")
        self.run = run
        core: CompiledCore = run.core
        spec = run.spec
        al = run.aligner
        truth = run.truth
        trig = run.trigger
        fd = core.frame_draws
        ci = np.zeros(len(C.CI_FIELDS), dtype=np.int64)
        cf = np.zeros(len(C.CF_FIELDS))
        ci[C.CI_LATEST], ci[C.CI_K0] = trig.latest, trig.base[1]
        cf[C.CF_T0], cf[C.CF_BASE_F], cf[C.CF_F_TRIG] = trig.base[0], trig.base[2], trig.f_trig
        ci[C.CI_ALIGN_TICK] = run.align_tick
        ci[C.CI_ALIGNED] = al.aligned_frame
        ci[C.CI_EVERY] = spec.commands.every if run.behaviour is not None else 0
        ci[C.CI_CPU] = int(run.core.host.net.cpu is not None)
        ci[C.CI_TRUTH_LATEST] = truth.latest
        ci[C.CI_SPACE] = 2 + run.n + 4  # CompiledCore.ensure_space(2)'s need
        ci[C.CI_ROLLBACKS], ci[C.CI_RESIM_STEPS] = truth.rollbacks, truth.resim_steps
        cf[C.CF_NOW] = run.kernel.now
        cf[C.CF_END] = spec.duration
        cf[C.CF_PHYS_T] = truth.phys_t
        cf[C.CF_ALIGN_PHASE], cf[C.CF_F_ALIGN] = spec.align_phase, spec.f_align
        cf[C.CF_TICK_COST] = spec.net.deployment.server_tick
        newest = _method(al, ci, cf)
        self._take_events(run, ci, cf)
        # the truth's state: an array of its own from now on (rollbacks write its rows)
        truth.state = np.array(truth.state, dtype=np.float64, order="C")
        step, observe, resim, params = run.dyn.compiled_physics()  # type: ignore[attr-defined]
        for kernel in (step, observe, resim):
            _stable_uuid(kernel)  # before anything pickles them (the loop's cache keys)
        self._kernels = (step, observe, resim)
        # the shown rows the loop writes (the aligner gets copies at each return)
        self._shown = (al.shown_frame.copy(), al.shown_gen.copy(), al.shown_obs.copy(),
                       al.flag.copy())
        self.ci, self.cf = ci, cf
        self._rest = (trig.trig_time, truth.ckpt, truth.obs_hist, truth.slot_frame,
                      truth.frame_dt, truth.phys_hist, truth.state, run.nodes.cmd,
                      *self._shown, fd._values, fd._tags, fd._tables, fd._widths, fd._block,
                      np.ascontiguousarray(params, dtype=np.float64),
                      np.array(truth.initial, dtype=np.float64, order="C"),
                      np.zeros(truth.state.shape[1]), np.empty_like(truth.state), *newest,
                      np.zeros(run.n, dtype=np.bool_), np.zeros(run.n, dtype=np.bool_))
        self._sync_draws()
        core.deliveries.watch(core.S)  # no tap: states to the ring, or to the loop (none)
        #: how often the loop returned, by code (the core's exits and :data:`control.CODES`)
        self.returns: dict[int, int] = {}
        self._entry: Any = None  # the loop's entry point for the core's current state
        self._bound: tuple[Any, ...] = ()  # the state it was bound for
        #: the behaviour's ``capture`` (record the view, send nothing), if it has one
        self._capture: Callable[[SwarmView], None] | None = getattr(run.behaviour, "capture",
                                                                     None)

    @staticmethod
    def _take_events(run: _Run, ci: NDArray[np.int64], cf: NDArray[np.float64]) -> None:
        """Move the run's pending trigger issue and alignment tick off its kernel."""
        q = run.kernel.env._queue  # type: ignore[attr-defined]
        for t, _prio, _eid, ev in q:
            fn = getattr(ev, "fn", None)
            if fn == run.trigger.issue:
                ci[C.CI_TRIG_ON], cf[C.CF_TRIG_T] = 1, t
            elif fn == run.align or fn == run._align:
                ci[C.CI_ALIGN_ON], cf[C.CF_ALIGN_T] = 1, t
                ci[C.CI_ALIGN_DIRECT] = int(fn == run._align)
            else:
                raise ValueError(f"compiled control: the kernel holds another event ({fn!r})")
        # dropped unprocessed: no cycle through their callbacks (as SimPy leaves a
        # processed event), so reference counting frees them
        for *_, ev in q:
            ev.callbacks = None  # type: ignore[assignment]
        q.clear()

    def _sync_draws(self) -> None:
        fd = self.run.core.frame_draws
        self.ci[C.CI_FD_FIRST], self.ci[C.CI_FD_COUNT] = fd._first, fd._count

    def _sync(self) -> None:
        """The run's objects as the loop left them (the kernel's clock, the trigger
        source, the aligner, the truth, the tick count)."""
        run = self.run
        ci, cf = self.ci.tolist(), self.cf.tolist()  # Python numbers, read once
        run.kernel.jump_to(cf[C.CF_NOW])
        trig = run.trigger
        trig.latest = ci[C.CI_LATEST]
        trig.f_trig = cf[C.CF_F_TRIG]
        trig.base = (cf[C.CF_T0], ci[C.CI_K0], cf[C.CF_BASE_F])
        al = run.aligner
        al.aligned_frame = ci[C.CI_ALIGNED]
        al.new_snapshot = bool(ci[C.CI_NEW_SNAPSHOT])
        if isinstance(al, BidesAligner):
            al._hi, al._lo = ci[C.CI_HI], ci[C.CI_LO]
            al.rate_changes = ci[C.CI_RATE_CHANGES]
        elif isinstance(al, NoneAligner):
            al._dirty = bool(ci[C.CI_DIRTY])
        if ci[C.CI_ALIGN_TICK] > 0 and al.peak_bytes == 0:  # the buffers' size is fixed:
            al.note_memory()  # every tick notes the same
        frame, gen, obs, flag = self._shown
        al.shown_frame, al.shown_gen, al.shown_obs, al.flag = (frame.copy(), gen.copy(),
                                                               obs.copy(), flag.copy())
        run.align_tick = ci[C.CI_ALIGN_TICK]
        self._sync_truth(ci, cf)

    def _sync_truth(self, ci: list[int] | None = None, cf: list[float] | None = None) -> None:
        """The clock and the truth as the loop left them (what serving the core reads;
        ``ci``, ``cf``: the control arrays as lists, if read already)."""
        run = self.run
        if ci is None or cf is None:
            ci, cf = self.ci.tolist(), self.cf.tolist()
        run.kernel.jump_to(cf[C.CF_NOW])
        truth = run.truth
        truth.latest = ci[C.CI_TRUTH_LATEST]
        truth.phys_t = cf[C.CF_PHYS_T]
        truth.rollbacks = ci[C.CI_ROLLBACKS]
        truth.resim_steps = ci[C.CI_RESIM_STEPS]

    def _bind(self) -> Any:
        """The loop's entry point and its first argument for the core's current state
        (bound again when the core replaced or grew it: a new handle)."""
        core: CompiledCore = self.run.core
        bound = core._entries()
        if core.S is not self._bound:
            self._entry = _entry_for(core.S, bound.by_handle, core._arg,
                                     (self.ci, self.cf, *self._rest), self._kernels)
            self._bound = core.S
        return core._arg

    def advance_until(self, stop: Callable[[], bool]) -> int:
        """Run until ``stop()`` holds after a command tick (``PAUSED``; the caller may
        publish commands now, as ``MethodRun.advance_until``'s caller does) or the end
        (``END``: every message before it ran, the counters written back)."""
        core: CompiledCore = self.run.core
        ctl = (self.ci, self.cf, *self._rest)
        step, observe, resim = self._kernels
        while True:
            arg = self._bind()
            code = self._entry(arg, ctl, step, observe, resim)
            self.returns[code] = self.returns.get(code, 0) + 1
            if code < len(CO.EXIT_CODES):
                core.exits[code] += 1
                self._sync_truth()
                core.serve(code)
                al = self.run.aligner
                if isinstance(al, NoneAligner) and al._dirty:  # a flush took states
                    self.ci[C.CI_DIRTY] = 1
                    al._dirty = False
            elif code == C.START:
                self._sync_truth()
                core._start_job(int(self.ci[C.CI_NEED_NODE]), float(self.cf[C.CF_PT]))
            elif code == C.COMMAND_TICK:
                self._sync()
                self._send_commands()
                if stop():
                    return PAUSED
            elif code == C.DRAWS:
                core.frame_draws.fill(int(self.ci[C.CI_NEED_K]))
                self._sync_draws()
            elif code == C.SPACE:
                core.ensure_space(2)
            elif code == C.DEFERRED:
                self._sync_truth()
                core.flush_rollbacks()
            elif code == C.OUT:  # pragma: no cover - none takes them in the loop, BiDES has a ring
                core.drain()
            elif code == C.END:
                self._sync()
                core.exits[CO.OK] += 1
                core.exits[CO.NEED_ROLLBACK] += int(self.ci[C.CI_ROLLED])
                self.ci[C.CI_ROLLED] = 0
                core.write_back()
                return END
            else:  # pragma: no cover - a code the loop does not return
                raise AssertionError(f"compiled control: unknown code {code}")

    def _send_commands(self) -> None:
        """The command tick's behaviour call (AlignmentServer.send_commands) on the tick
        the loop just ran (its index is one below the run's tick count now).

        A behaviour with a ``capture`` method (one that records the view and sends
        nothing, e.g. a learning env's) has it called instead of ``commands``.
        """
        run = self.run
        al = run.aligner
        assert run.behaviour is not None
        view = SwarmView(obs=al.shown_obs, frame=al.shown_frame, valid=~np.isnan(al.shown_gen),
                         aligned_frame=al.aligned_frame)
        if self._capture is not None:
            self._capture(view)
            return
        cmds = run.behaviour.commands(view, run.dyn)
        ok = ~np.isnan(cmds).all(axis=1)
        if ok.any():  # (no rows: the run's publish_commands would do nothing)
            run.publish_commands(run.align_tick - 1, al.aligned_frame, np.flatnonzero(ok), cmds)


#: the loop's entry points, by the types of what they take (see ``entries.bound``)
_ENTRIES: dict[tuple[Any, ...], Any] = {}


def _entry_for(S: tuple[Any, ...], by_handle: bool, arg: Any, ctl: tuple[Any, ...],
               kernels: tuple[Any, ...]) -> Any:
    """The compiled entry point of the control loop for state ``S`` taken as ``arg`` (its
    handle, or ``S`` itself), control arrays ``ctl`` and the physics ``kernels``: resolved
    once per set of types, then called without numba's dispatch (whose typing of the
    kernels' dispatcher arguments cost more than the loop's work on a small swarm)."""
    assert compute_fingerprint is not None  # the pinned numba has it
    key = (compute_fingerprint(S), by_handle, compute_fingerprint(ctl), *map(id, kernels))
    got = _ENTRIES.get(key)
    if got is None:
        from numba import typeof

        kernel = C.run_held if by_handle else C.run
        first = HandleType(typeof(S)) if by_handle else typeof(S)
        sig = (first, typeof(ctl), *(typeof(k) for k in kernels))
        got = _ENTRIES[key] = kernel.compile(sig)  # type: ignore[attr-defined]
    return got


def _stable_uuid(kernel: Any) -> None:
    """Give a physics kernel (a numba dispatcher) the same identity in every process.

    The loop's cached overloads are keyed by the kernels' dispatcher types, which numba
    pickles by the dispatcher's uuid (random, drawn when first pickled). In another
    process that uuid names no live dispatcher: loading the cache index rebuilds a
    stand-in that dies once numba's memo of recent dispatchers drops it, after which the
    next overload saved to that index fails (``ReferenceError: underlying object has
    vanished``) and the entries never match the live kernel's type. A uuid derived from
    the kernel's module and name (set before anything pickles it) makes a loaded key
    resolve to the live kernel itself.
    """
    if getattr(kernel, "_MemoMixin__uuid", "") is not None or not hasattr(kernel, "_set_uuid"):
        return  # not a dispatcher, or its identity is set already
    import uuid

    fn = kernel.py_func
    name = f"sigma_des.kernel:{fn.__module__}.{fn.__qualname__}"
    kernel._set_uuid(str(uuid.uuid5(uuid.NAMESPACE_URL, name)))
