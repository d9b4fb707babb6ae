"""What a retired compiled core hands to the next core of the same kind of run.

A learning env restarts its scenes' runs many times from copies of one run spec that
differ in the seed only (``sigma_des.env.scenes.with_seed``). When a scene's episode
ends, its core (:meth:`~sigma_des.events.fast.driver.CompiledCore.retire`) hands back a
:class:`Spare`: the arrays it alone held, which the next core refills in place instead
of allocating new ones, and the state's dimensions and the first values of the arrays
that hold no random draw (:func:`~sigma_des.events.fast.setup.seed_free`), which the next
core takes instead of deriving them again from the spec, the network and the nodes. Those
values are used only by a run of the same spec but for the seed, the same method and the
very same dynamics model (:func:`same_but_seed`); the arrays, whatever the run, only
where their dtype and shape fit. :func:`state_for` builds a core's state from a spare,
:func:`handed_back` is what a retiring core hands on. Either way a core's state is bit
for bit the one it would have built from nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from operator import itemgetter
from typing import TYPE_CHECKING, Any

from numpy.typing import NDArray

from sigma_des.events.fast import layout as L
from sigma_des.events.fast import setup
from sigma_des.events.fast.declare import reusable

if TYPE_CHECKING:
    from sigma_des.events.fast.driver import CompiledCore

__all__ = ["Kept", "Spare", "handed_back", "refilled", "same_but_seed", "state_for"]

State = tuple[NDArray[Any], ...]
#: the state's fields with a fill (names; their arrays taken out of a state by
#: ``_FILLED_OF``): the arrays a core makes for itself
_FILLED = tuple(f.name for f in L.FIELDS if f.fill is not None)
_FILLED_OF = itemgetter(*(L.INDEX[name] for name in _FILLED))


@dataclass(frozen=True)
class Kept:
    """The first values of a core's seed-free arrays and what they were made for.

    Attributes:
        spec: the run spec they were made from (any seed).
        method: the run's alignment method.
        dyn: the run's dynamics model (the very object).
        dims: the state's dimensions (:func:`~sigma_des.events.fast.setup.dims`: a
            function of the same).
        arrays: the values, by field name (copies nothing writes).
    """

    spec: Any
    method: str
    dyn: object
    dims: Mapping[str, int]
    arrays: Mapping[str, NDArray[Any]]


@dataclass(frozen=True)
class Spare:
    """A retired core's own arrays (by field name) and its kept values (None: none)."""

    arrays: Mapping[str, NDArray[Any]]
    kept: Kept | None


def same_but_seed(a: Any, b: Any) -> bool:
    """Whether run specs ``a`` and ``b`` are equal but for their seeds (the spec's and its
    aligner's parameters'); fields holding the same object are not compared further."""
    if type(a) is not type(b) or type(a.align) is not type(b.align):
        return False
    for x, y, skip in ((a, b, ("seed", "align")), (a.align, b.align, ("seed",))):
        vy = vars(y)
        for name, v in vars(x).items():
            if name not in skip and not (v is vy[name] or v == vy[name]):
                return False
    return True


def refilled(kept: Mapping[str, NDArray[Any]], spare: Mapping[str, NDArray[Any]]
             ) -> dict[str, NDArray[Any]]:
    """Arrays holding the values of ``kept``: ``spare``'s of the same name refilled in
    place where they fit (:func:`~sigma_des.events.fast.declare.reusable`), else copies."""
    out: dict[str, NDArray[Any]] = {}
    get = spare.get
    for name, v in kept.items():
        a = get(name)
        if a is not None and reusable(a, v.dtype, v.shape):
            a[...] = v
            out[name] = a
        else:
            out[name] = v.copy()
    return out


def state_for(core: CompiledCore, p_loss: tuple[float, float], slack: int, arena: float,
              spare: Spare | None) -> tuple[State, Kept | None]:
    """The state tuple of a new ``core`` (its tables built, its state not yet), from
    ``spare`` where it serves, and the seed-free values the core hands on at retirement
    (None: a one-off run, made without a spare, keeps none).

    Args:
        core: the core being built.
        p_loss: the Bernoulli loss of the host links and of the server's link.
        slack: spare event slots beyond what one frame needs.
        arena: the queue's arena rows per event slot.
        spare: what a retired core handed back (None: every array made new).
    """
    h = core.host
    kept = spare.kept if spare is not None else None
    if kept is not None and not (kept.method == h.method and kept.dyn is h.dyn
                                 and same_but_seed(kept.spec, h.spec)):
        kept = None
    given = setup.given(core, p_loss, slack, kept.arrays if kept is not None else None)
    if kept is not None:
        given.update(refilled(kept.arrays, spare.arrays))  # type: ignore[union-attr]
        dims = kept.dims
    else:
        dims = setup.dims(core, slack, arena)
        if spare is not None:  # the values to hand on (not kept by a one-off run)
            kept = Kept(h.spec, h.method, h.dyn, dims,
                        {name: given[name].copy() for name in setup.seed_free(given)})
    return L.allocate(dims, given, spare.arrays if spare is not None else None), kept


def handed_back(S: State, kept: Kept | None) -> Spare:
    """What a retiring core with state ``S`` hands to the next one: the arrays of its own
    (the fields with a fill and the seed-free ones it was given: no other object holds
    them) and its kept values."""
    arrays = dict(zip(_FILLED, _FILLED_OF(S), strict=True))
    if kept is not None:
        names = tuple(kept.arrays)
        of = _KEPT_OF.get(names)
        if of is None:
            if len(_KEPT_OF) >= 64:
                _KEPT_OF.clear()
            of = _KEPT_OF[names] = _getter([L.INDEX[name] for name in names])
        arrays.update(zip(names, of(S), strict=True))
    return Spare(arrays, kept)


def _getter(positions: list[int]) -> Callable[[State], tuple[NDArray[Any], ...]]:
    """The arrays at ``positions`` of a state, as a tuple (also of one or none)."""
    if len(positions) == 1:
        one = positions[0]
        return lambda S: (S[one],)
    return itemgetter(*positions) if positions else (lambda S: ())


#: per tuple of kept names, what takes their arrays out of a state
_KEPT_OF: dict[tuple[str, ...], Callable[[State], tuple[NDArray[Any], ...]]] = {}
