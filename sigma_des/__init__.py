"""sigma_des: discrete-event simulation of time alignment in distributed swarm simulators.

Public API: :class:`Scenario` (the validated configuration), :func:`load` (TOML +
overrides), :func:`compare` (run methods side by side) and :class:`Results`.
"""

__version__ = "0.1.0"

from sigma_des.jitcache import ensure_cache_dir  # noqa: E402

ensure_cache_dir()  # before any numba kernel is defined: its directory names its sources

from sigma_des.api import Results, compare, run_method  # noqa: E402
from sigma_des.config import METHODS, Scenario, load, to_toml  # noqa: E402
from sigma_des.errors import ConfigError  # noqa: E402

__all__ = ["ConfigError", "METHODS", "Results", "Scenario", "__version__", "compare", "load",
           "run_method", "to_toml"]
