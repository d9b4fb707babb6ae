"""Results of pure functions of frozen specs, kept per identity of the specs.

A learning env restarts its scenes' runs many times from copies of one run spec that
differ in the seed only (``sigma_des.env.scenes.with_seed``): the copies share the
spec's parts (its network setup, faults, clocks). What the compiled core derives from
such parts alone — whether the cohort core supports the run, the deployment tables — is
the same for every episode, and an :class:`IdentityMemo` computes it once. A memo's
entry holds the objects it is keyed by, so their identities cannot be reused while it
lives; the parts are frozen dataclasses, so the same objects mean the same values.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

__all__ = ["IdentityMemo"]

T = TypeVar("T")


class IdentityMemo(Generic[T]):
    """The last ``size`` results of a function, per (objects by identity, plain values).

    Args:
        size: how many results are kept (the oldest is dropped first).
    """

    def __init__(self, size: int = 16) -> None:
        self.size = size
        self._entries: dict[Hashable, tuple[tuple[object, ...], T]] = {}

    def get(self, objects: tuple[object, ...], values: Hashable, make: Callable[[], T]) -> T:
        """The result kept for ``objects`` (the very same objects) and ``values``, else
        ``make()``'s, kept."""
        key = (tuple(map(id, objects)), values)
        hit = self._entries.get(key)
        if hit is not None and all(a is b for a, b in zip(hit[0], objects, strict=True)):
            return hit[1]
        out = make()
        if len(self._entries) >= self.size:
            del self._entries[next(iter(self._entries))]
        self._entries[key] = (objects, out)
        return out

    def clear(self) -> None:
        """Drop every result."""
        self._entries.clear()
