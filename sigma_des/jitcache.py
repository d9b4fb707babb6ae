"""Where numba caches the compiled kernels, chosen before any kernel is defined.

numba caches ``cache=True`` functions next to their source (``__pycache__``) or,
failing that, in the user's cache directory (``~/.cache/numba``). A user who can
write neither (a read-only install and no writable HOME) would get
``RuntimeError: cannot cache function ...: no locator available`` on import.
:func:`ensure_cache_dir` detects that case and points numba at a private
temporary directory instead, with a one-line warning on stderr.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

__all__ = ["ensure_cache_dir"]

_PACKAGE = Path(__file__).resolve().parent


def _can_write_dir(d: Path) -> bool:
    """True if directory ``d`` exists or can be made, and a file can be created in it."""
    try:
        os.makedirs(d, exist_ok=True)
        tempfile.TemporaryFile(dir=d).close()
    except OSError:
        return False
    return True


def _user_cache_dir() -> Path:
    from numba.misc.appdirs import AppDirs

    return Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def _in_tree_ok(package: Path) -> bool:
    dirs = {p.parent for p in package.rglob("*.py") if "__pycache__" not in p.parts}
    return all(_can_write_dir(d / "__pycache__") for d in dirs)


def ensure_cache_dir(package: Path = _PACKAGE) -> str | None:
    """Make sure numba has somewhere to cache ``package``'s kernels.

    Does nothing when ``NUMBA_CACHE_DIR`` is set, the package tree is writable or
    the user-wide cache directory is. Otherwise sets ``NUMBA_CACHE_DIR`` (inherited
    by worker processes) to ``<tmp>/sigma_des-numba-<uid>`` and warns once.

    Args:
        package: the package directory whose ``__pycache__`` folders numba would use.

    Returns:
        The temporary cache directory chosen, or None if none was needed.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    if _in_tree_ok(package) or _can_write_dir(_user_cache_dir()):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    tmp = Path(tempfile.gettempdir()) / f"sigma_des-numba-{uid}"
    if not _can_write_dir(tmp):
        tmp = Path(tempfile.mkdtemp(prefix="sigma_des-numba-"))
    os.environ["NUMBA_CACHE_DIR"] = str(tmp)
    if "numba" in sys.modules:  # numba read its configuration already
        from numba.core import config

        config.CACHE_DIR = str(tmp)  # type: ignore[attr-defined]
    print(
        f"sigma-des: warning: cannot write numba's cache next to {package} or in "
        f"{_user_cache_dir()}; caching compiled kernels in {tmp}",
        file=sys.stderr,
    )
    return str(tmp)
