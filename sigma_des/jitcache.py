"""Where numba caches the compiled kernels: a directory named by their sources' fingerprint.

numba's ``cache=True`` checks only the defining file of a kernel, so an edit of a
constant module (``events/fast/codes.py``, ``layout.py``) or of a callee in another file would load
stale kernels. :func:`ensure_cache_dir` points numba at::

    <root>/numba/<fingerprint>/

* ``<root>`` is ``$NUMBA_CACHE_DIR`` if set, else the package's cache root
  (:func:`sigma_des.cache.paths.root`: ``$SIGMA_DES_CACHE_DIR``, ``$XDG_CACHE_HOME/
  sigma_des`` or ``~/.cache/sigma_des``). ``SIGMA_DES_CACHE_DIR=off`` switches off the
  ideal-run cache only: kernels then use the default root (they cannot go stale, and
  compiling them in every process would cost ~1.5 CPU-minutes each); to keep them out of
  ``~/.cache`` set ``NUMBA_CACHE_DIR``. If the root cannot be written (read-only HOME),
  ``<tmp>/sigma_des-numba-<uid>`` is used instead, with a one-line warning.
* ``<fingerprint>`` is :func:`sigma_des.cache.sources.fingerprint` (16 hex digits).

numba's locator reads ``numba.config.CACHE_DIR`` when a ``cache=True`` dispatcher is
created, so the directory must be set before any kernel is defined, yet ``import
sigma_des`` must not import numba (a second of CPU) nor create directories. So
``sigma_des/__init__.py`` calls :func:`install_hook`: a finder on ``sys.meta_path``
that, the first time ``numba`` is imported (by whichever module needs it), lets numba
load and then calls :func:`ensure_cache_dir` before the importing module continues —
before its ``@njit(cache=True)`` lines run. If numba is already loaded when the
package is imported, :func:`install_hook` calls :func:`ensure_cache_dir` at once.

The root is exported as ``NUMBA_CACHE_DIR`` (child processes share it). A new
fingerprint directory prunes its siblings but the :data:`KEEP` most recent (and any used
in the last :data:`GRACE_S` s). Set ``NUMBA_*`` variables before importing the package.
Details: docs/concepts/engines.md ("Where the compiled code is cached")."""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from sigma_des.cache.paths import default_root, root
from sigma_des.cache.sources import PACKAGE, fingerprint

__all__ = ["GRACE_S", "KEEP", "cache_root", "ensure_cache_dir", "install_hook",
           "kernels_cached", "loaded_specialisations", "prune"]

#: Fingerprint directories kept besides the current one, the most recently used first.
KEEP = 3
#: Never prune a directory used this recently (s): another checkout may be running.
GRACE_S = 3600.0

_FINGERPRINT = re.compile(r"[0-9a-f]{16}")


def loaded_specialisations() -> int:
    """How many specialisations the package's kernels hold (loaded or compiled so far).

    Counts the numba dispatchers bound to a name of an imported ``sigma_des`` module, so
    a benchmark can tell that its timed part loaded no kernel (0 if numba is not loaded).
    """
    if "numba" not in sys.modules:
        return 0
    from numba.core.registry import CPUDispatcher

    kernels = {id(obj): obj for name, mod in list(sys.modules.items())
               if name.startswith("sigma_des") and mod is not None
               for obj in list(vars(mod).values()) if isinstance(obj, CPUDispatcher)}
    return sum(len(k.signatures) for k in kernels.values())


def _can_write_dir(d: Path) -> bool:
    """True if directory ``d`` exists or can be made, and a file can be created in it."""
    try:
        os.makedirs(d, exist_ok=True)
        tempfile.TemporaryFile(dir=d).close()
    except OSError:
        return False
    return True


def cache_root() -> Path:
    """``$NUMBA_CACHE_DIR`` if set, else the package's cache root (default if switched off)."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:
        return Path(env)
    return root() or default_root()


def _fallback(wanted: Path) -> Path:
    """A writable root in the temporary directory, for when ``wanted`` is not writable."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    tmp = Path(tempfile.gettempdir()) / f"sigma_des-numba-{uid}"
    if not _can_write_dir(tmp):
        tmp = Path(tempfile.mkdtemp(prefix="sigma_des-numba-"))
    print(f"sigma-des: warning: cannot write numba's cache in {wanted}; "
          f"caching compiled kernels in {tmp}", file=sys.stderr)
    return tmp


def kernels_cached(package: Path = PACKAGE) -> bool:
    """Whether numba's cache for ``package``'s current sources holds compiled kernels.

    False before the first run after an install or an edit: the next run then compiles
    (about a minute), which the command line says instead of a silent, stalled start.
    """
    d = cache_root() / "numba" / fingerprint(package)
    return d.is_dir() and any(d.rglob("*.nbi"))


def ensure_cache_dir(package: Path = PACKAGE) -> str:
    """Point numba's cache at ``<root>/numba/<fingerprint of package>``; prune old ones.

    Args:
        package: the package whose kernels' sources are fingerprinted.

    Returns:
        The directory set as ``numba.config.CACHE_DIR``.
    """
    rt = cache_root()
    fp = fingerprint(package)
    d = rt / "numba" / fp
    is_new = not d.is_dir()
    if not _can_write_dir(d):
        rt = _fallback(rt)
        d = rt / "numba" / fp
        is_new = not d.is_dir()
        _can_write_dir(d)
        os.environ["NUMBA_CACHE_DIR"] = str(rt)
    os.environ.setdefault("NUMBA_CACHE_DIR", str(rt))
    from numba.core import config

    # numba re-reads its configuration before each compilation when a NUMBA_* variable
    # changed since it last looked, which would replace CACHE_DIR by the bare root
    config.reload_config()
    config.CACHE_DIR = str(d)  # type: ignore[attr-defined]
    try:
        os.utime(d)  # "last used", for prune
    except OSError:
        pass
    if is_new:
        prune(d.parent, fp)
    return str(d)


def prune(parent: Path, current: str, keep: int = KEEP, grace_s: float = GRACE_S,
          now: float | None = None) -> list[str]:
    """Remove old fingerprint directories of ``parent`` (see the module docstring).

    Args:
        parent: the ``<root>/numba`` directory.
        current: the fingerprint in use (never removed).
        keep: how many others to keep, the most recently used first.
        grace_s: directories used less than this many seconds ago are kept too.
        now: the current time (``time.time()`` if None).

    Returns:
        The fingerprints removed; empty if another process holds the prune lock.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: never prune
        return []
    now = time.time() if now is None else now
    try:
        lock = (parent / ".prune.lock").open("a")
    except OSError:
        return []
    with lock:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return []  # another process is pruning
        used = sorted(((p.stat().st_mtime, p.name) for p in parent.iterdir()
                       if p.is_dir() and _FINGERPRINT.fullmatch(p.name) and p.name != current),
                      reverse=True)
        removed = []
        for mtime, name in used[keep:]:
            if now - mtime < grace_s:
                continue
            trash = parent / f".trash-{name}-{os.getpid()}"
            try:
                os.rename(parent / name, trash)
            except OSError:
                continue  # removed by another process meanwhile
            shutil.rmtree(trash, ignore_errors=True)
            removed.append(name)
        return removed


class _NumbaLoader(importlib.abc.Loader):
    """numba's own loader, followed by :func:`ensure_cache_dir` once numba is loaded."""

    def __init__(self, inner: importlib.abc.Loader) -> None:
        self.inner = inner

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return self.inner.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        _remove_hook()
        # the module's spec and __loader__ name numba's own loader again, as if unhooked
        module.__loader__ = self.inner
        if module.__spec__ is not None:
            module.__spec__.loader = self.inner
        self.inner.exec_module(module)
        ensure_cache_dir()


class _NumbaHook(importlib.abc.MetaPathFinder):
    """Finds ``numba`` through the other finders and hooks its loader.

    It stays in place until numba is loaded (a mere ``importlib.util.find_spec``
    must not disarm it).
    """

    def find_spec(self, fullname: str, path: Sequence[str] | None = None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname != "numba":
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None and spec.loader is not None:
                spec.loader = _NumbaLoader(spec.loader)
                return spec
        return None  # not installed: the import fails as it would without the hook


def _remove_hook() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _NumbaHook)]


def install_hook() -> None:
    """Set numba's cache directory when numba is first imported (now if it already is).

    Cheap, and until numba is imported its only effect is exporting the root as
    ``NUMBA_CACHE_DIR`` (when unset): the root is fixed when the package is imported,
    as the module docstring says, even if ``SIGMA_DES_CACHE_DIR`` changes later (the
    test suite moves the ideal-run cache that way, not the kernels). Idempotent.
    """
    os.environ.setdefault("NUMBA_CACHE_DIR", str(cache_root()))
    if "numba" in sys.modules:
        _remove_hook()
        ensure_cache_dir()
    elif not any(isinstance(f, _NumbaHook) for f in sys.meta_path):
        sys.meta_path.insert(0, _NumbaHook())
