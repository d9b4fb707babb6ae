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
where their dtype and shape fit. Either way a core's state is bit for bit the one it would have
built from nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from numpy.typing import NDArray

from sigma_des.events.fast.declare import reusable

__all__ = ["Kept", "Spare", "refilled", "same_but_seed"]


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
    for name, v in kept.items():
        a = spare.get(name)
        if a is not None and reusable(a, v.dtype, v.shape):
            a[...] = v
            out[name] = a
        else:
            out[name] = v.copy()
    return out
