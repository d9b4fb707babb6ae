"""Physics agents layer: dynamics models, environment, sensors, autopilots and behaviours.

Import stays light (the numba kernels load on first use); the registries and
factories are re-exported lazily from :mod:`sigma_des.agents.registry`:
``DYNAMICS``, ``BEHAVIOURS``, ``make_dynamics``, ``make_behaviour``; the ideal
run :func:`~sigma_des.agents.ideal.fly` likewise (DTW is a metric:
:mod:`sigma_des.metrics.dtw`). See docs/concepts/aircraft.md.
"""

from __future__ import annotations

from typing import Any

__all__ = ["DYNAMICS", "BEHAVIOURS", "make_dynamics", "make_behaviour", "fly"]

_LAZY = {"DYNAMICS": "registry", "BEHAVIOURS": "registry", "make_dynamics": "registry",
         "make_behaviour": "registry", "fly": "ideal"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f"sigma_des.agents.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'sigma_des.agents' has no attribute {name!r}")
