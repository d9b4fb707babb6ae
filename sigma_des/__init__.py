"""sigma_des: discrete-event simulation of time alignment in distributed swarm simulators.

Public API: :class:`Scenario` (the validated configuration), :func:`load` (TOML +
overrides), :func:`compare` (run methods side by side) and :class:`Results`.

Importing the package has no side effects: the names above load their modules on
first use, and numba's cache directory (:mod:`sigma_des.jitcache`) is set up when
numba itself is first imported, before any kernel is defined.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from sigma_des.jitcache import install_hook
from sigma_des.version import __version__

if TYPE_CHECKING:
    from sigma_des.api import Results, compare, run_method
    from sigma_des.config import METHODS, Scenario, load, to_toml
    from sigma_des.errors import ConfigError

install_hook()

__all__ = ["ConfigError", "METHODS", "Results", "Scenario", "__version__", "compare", "load",
           "run_method", "to_toml"]

#: Each public name's module, imported on first access.
_LAZY = {"Results": "api", "compare": "api", "run_method": "api", "METHODS": "config",
         "Scenario": "config", "load": "config", "to_toml": "config", "ConfigError": "errors"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f"sigma_des.{_LAZY[name]}"), name)
        globals()[name] = value  # later lookups skip this hook
        return value
    raise AttributeError(f"module 'sigma_des' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
