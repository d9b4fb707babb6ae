"""The compiled core's one numba decorator (every compiled function uses it).

A module of its own so that the primitives and the modules they call
(:mod:`~sigma_des.events.fast.loss`, :mod:`~sigma_des.events.fast.clock`) share it
without importing each other in a circle.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from numba import njit

__all__ = ["jit"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: Compiled without numba's reference counting: every array is borrowed from the
#: driver and nothing is allocated, and NRT's atomic increments on each array access
#: made the loop ~4x slower.
jit: Callable[[_F], _F] = njit(cache=True, _nrt=False)  # type: ignore[call-overload]
