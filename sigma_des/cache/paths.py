"""Where the package's on-disk caches live: one root, one subdirectory per cache.

``$SIGMA_DES_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/sigma_des``, else
``~/.cache/sigma_des``. The ideal-run cache (:mod:`sigma_des.cache.ideal`) uses
``<root>/ideal`` and numba's kernels (:mod:`sigma_des.jitcache`) ``<root>/numba``.
Light on purpose: :mod:`sigma_des.jitcache` reads it before any other module of the
package is imported.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ENV_VAR", "OFF", "default_root", "root"]

#: Environment variable naming the cache root (``off`` / ``0`` / empty: no cache).
ENV_VAR = "SIGMA_DES_CACHE_DIR"

#: Values of :data:`ENV_VAR` that switch the ideal-run cache off (case-insensitive).
OFF = ("", "0", "off", "false", "no")


def default_root() -> Path:
    """The root when :data:`ENV_VAR` is unset: ``$XDG_CACHE_HOME/sigma_des`` or ``~/.cache/...``."""
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "sigma_des"


def root() -> Path | None:
    """The cache root, or None when :data:`ENV_VAR` switches caching off."""
    env = os.environ.get(ENV_VAR)
    if env is None:
        return default_root()
    return None if env.strip().lower() in OFF else Path(env)
