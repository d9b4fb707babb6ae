"""Small memory pages for a run's large arrays: numpy's huge-page hint switched off.

numpy asks Linux for transparent huge pages (``madvise(MADV_HUGEPAGE)``) on every array
of 4 MiB or more. With the kernel's usual THP setting for such memory (defrag
``madvise``), the first write to each 2 MiB of it waits while the kernel compacts
memory whenever no free 2 MiB page is at hand, which on a machine whose memory holds
a page cache is most of the time. A run writes its largest arrays a frame at a time
(the physics truth's rings, the rollback-draw table), so these stalls fell in the
simulated seconds (at N = 10 000, most of a BiDES run's system time), while ordinary
4 KiB pages cost a small, steady fraction of that (docs/concepts/engines.md, "The
physics truth's memory").

:func:`small_pages` turns the hint off for the process; the physics truth calls it
before it allocates its rings, so every run (the DES engines, the env's scenes, a live
host) gets ordinary pages from its first array on. numpy's own switch wins: with
``NUMPY_MADVISE_HUGEPAGE`` set in the environment (``1`` keeps huge pages) nothing
is changed. Pages never change a value: results are bit-identical either way.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import lru_cache

__all__ = ["huge_page_hint", "small_pages"]

#: numpy's environment switch of its huge-page hint (read when numpy is imported).
ENV = "NUMPY_MADVISE_HUGEPAGE"


@lru_cache(maxsize=1)
def _hooks() -> tuple[Callable[[bool], bool], Callable[[], bool]] | None:
    """numpy's private setter and getter of the hint (None where this numpy has none)."""
    try:
        from numpy._core import multiarray
    except ImportError:  # pragma: no cover - numpy 1.x
        from numpy.core import multiarray  # type: ignore[no-redef]
    setter = getattr(multiarray, "_set_madvise_hugepage", None)
    getter = getattr(multiarray, "_get_madvise_hugepage", None)
    if setter is None or getter is None:  # pragma: no cover - a numpy without the hint
        return None
    return setter, getter


def huge_page_hint() -> bool:
    """True if numpy currently asks for huge pages on its large arrays."""
    hooks = _hooks()
    return hooks is not None and bool(hooks[1]())


def small_pages() -> bool:
    """Switch numpy's huge-page hint off for this process, unless the user set
    ``NUMPY_MADVISE_HUGEPAGE`` (then leave it as numpy set it).

    Returns:
        True if the hint is off after the call.
    """
    hooks = _hooks()
    if hooks is None:  # pragma: no cover - a numpy without the hint
        return True
    if ENV not in os.environ:
        hooks[0](False)
    return not hooks[1]()
