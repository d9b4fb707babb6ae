"""Python's cyclic garbage collector paused around a run (the DES engine's and the live
loops'): reference counting still frees everything that is not a cycle, and a run makes
no cycles worth a collection in its middle (docs/concepts/engines.md,
docs/concepts/decisions.md)."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["gc_paused"]


@contextmanager
def gc_paused(collect: int | None = None) -> Iterator[None]:
    """Pause the cyclic collector for the ``with`` block and restore it after (left off
    if it was off before). With ``collect`` set, collect that generation afterwards
    (always, also after an error)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()
        if collect is not None:
            gc.collect(collect)
