"""What the Python drivers take from numba's dispatch to call compiled entry points directly.

:mod:`~sigma_des.events.fast.entries` and :mod:`~sigma_des.events.fast.control_run`
resolve a compiled entry point once per state type (the dispatcher's own type
fingerprint as the key) and then call its machine code without a dispatch. They need
numba's ``Dispatcher`` class and its fingerprint function, imported here once at module
level. Kept in a module of their own: a module importing numba at module level is a
root of the kernels' source fingerprint (:mod:`sigma_des.cache.sources`), and this one
imports nothing of ``sigma_des``, so the drivers (and everything they import) stay out
of the fingerprint and their edits keep the compiled cache.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba.core.dispatcher import Dispatcher

__all__ = ["Dispatcher", "compute_fingerprint"]

compute_fingerprint: Callable[[Any], Any] | None
try:
    from numba._dispatcher import compute_fingerprint
except ImportError:  # pragma: no cover - a numba without it: dispatch every call
    compute_fingerprint = None
