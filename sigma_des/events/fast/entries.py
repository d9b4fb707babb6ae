"""The loop's entry points for the core's state type, called without numba's dispatch.

A call through a numba dispatcher first fingerprints the type of every argument to pick
the compiled version, then unboxes them. The core's state is a tuple of over a hundred
arrays, so each costs several µs a call, and the driver calls the loop several times per
trigger. Every state tuple of the core has the same type (the declaration fixes each
array's dtype and number of dimensions; built, grown and replaced arrays are
C-contiguous and writable), so :func:`bound` resolves, once per state type (keyed by
the dispatcher's own fingerprint of the tuple), the compiled entry points that take the
state by :class:`~sigma_des.events.fast.handle.Handle` (the tuple unboxed once per
tuple, :mod:`~sigma_des.events.fast.handle`): the loop's own machine code, reached
without a dispatch and without unboxing the tuple again. Callers pass the declared
types (ints, floats and bools; C-contiguous int64 and float64 arrays): an entry point
converts what it is given, it does not pick a version.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sigma_des.events.fast import handle, loop
from sigma_des.events.fast.dispatch import Dispatcher, compute_fingerprint
from sigma_des.events.fast.handle import ENTRIES, Handle, HandleType

__all__ = ["Entries", "bound"]

Kernel = Callable[..., Any]
#: the loop's entry points Python calls on a hot path
NAMES = ("advance", "publish_trigger", "publish_commands", "start", "roll_back", "owe_steps")


class Entries:
    """The loop's entry points Python calls on a hot path, for one state type.

    Args:
        kernels: each entry point by the name of the loop's function it runs.
        by_handle: they take a :class:`~sigma_des.events.fast.handle.Handle` of the state
            (else the state tuple: :meth:`arg` gives what to pass).
    """

    __slots__ = ("_held", "advance", "by_handle", "owe_steps", "publish_commands",
                 "publish_trigger", "roll_back", "start")

    def __init__(self, kernels: dict[str, Kernel], by_handle: bool = False,
                 held: tuple[int, Kernel] | None = None) -> None:
        self.by_handle = by_handle
        #: a handle's buffer size and the compiled store of this state type (by handle)
        self._held = held
        self.advance = kernels["advance"]
        self.publish_trigger = kernels["publish_trigger"]
        self.publish_commands = kernels["publish_commands"]
        self.start = kernels["start"]
        self.roll_back = kernels["roll_back"]
        self.owe_steps = kernels["owe_steps"]

    def arg(self, S: tuple[Any, ...]) -> Any:
        """What these entry points take for state ``S`` (its handle, or ``S`` itself)."""
        if not self.by_handle:
            return S
        return Handle(S) if self._held is None else Handle(S, *self._held)


#: the dispatchers themselves (what a core calls before its state is bound)
DISPATCHED = Entries({name: getattr(loop, name) for name in NAMES})
_BY_TYPE: dict[Any, Entries] = {}


def _signatures(state: Any) -> dict[str, tuple[Any, ...]]:
    from numba import types

    i64, f64 = types.int64, types.float64
    return {"advance": (state, f64, types.boolean),
            "publish_trigger": (state, i64, f64, f64, i64),
            "publish_commands": (state, i64, i64, types.int64[::1], types.float64[:, ::1], f64),
            "start": (state, i64, f64), "roll_back": (state, i64, i64, i64, f64),
            "owe_steps": (state, i64, i64, f64)}


def bound(S: tuple[Any, ...]) -> Entries:
    """The entry points for the type of state ``S`` (compiled or loaded on first use):
    by handle, or the loop's own functions if one was replaced (a test counting calls)."""
    now = [getattr(loop, name) for name in NAMES]
    if now != _LOOP:  # the first call, or a kernel replaced or put back
        _LOOP[:] = now
        _PLAIN[:] = [] if all(isinstance(k, Dispatcher) for k in now) else [True]
    if _PLAIN or compute_fingerprint is None:
        return Entries(dict(zip(NAMES, now, strict=True)))  # one was replaced (a test
        # counting calls): call what is there
    key = compute_fingerprint(S)
    got = _BY_TYPE.get(key)
    if got is None:
        from numba import typeof, types

        state = typeof(S)
        sigs = _signatures(HandleType(state))
        held = (int(handle._size(S)), handle._store.compile((state, types.int64)))  # type: ignore[attr-defined]
        got = _BY_TYPE[key] = Entries({name: ENTRIES[name].compile(sig)  # type: ignore[attr-defined]
                                       for name, sig in sigs.items()}, True, held)
    return got


#: the loop's entry points as last seen, and whether one of them is not a dispatcher
_LOOP: list[Kernel] = []
_PLAIN: list[bool] = []
