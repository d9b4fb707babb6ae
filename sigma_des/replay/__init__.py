"""Replay memory: rebuild recorded trajectories at any rate.

:func:`interpolate` (SciPy's standard interpolants and our dynamic-window Hermite,
:mod:`sigma_des.replay.window`), :func:`slerp_attitude`, and :func:`replay` which
reads an MCAP recording (:mod:`sigma_des.record`) and resamples every node.
"""

from sigma_des.replay.interpolate import (
    INTERP_METHODS,
    MIN_SAMPLES,
    hermite_tangents,
    interpolate,
    slerp_attitude,
)
from sigma_des.replay.window import RULES, WindowRule, window_sizes

__all__ = [
    "INTERP_METHODS",
    "MIN_SAMPLES",
    "RULES",
    "WindowRule",
    "hermite_tangents",
    "interpolate",
    "slerp_attitude",
    "window_sizes",
]
