"""Reset arguments of the vectorised envs (Gymnasium's conventions) and the text render.

``reset(seed=..., options=...)`` of :class:`~sigma_des.env.SwarmVec`:

* ``seed``: ``None`` (every reset scene plays its next episode; the first reset uses
  the construction seed), an int (every reset scene plays episode 0 of that root
  seed) or a list of one entry per scene, each ``None`` or an int (a per-scene root:
  scene ``s`` then plays what scene ``s`` of a batch reset with that int plays);
* ``options``: ``{"reset_mask": m}`` with ``m`` a numpy bool array of shape
  ``(n_scenes,)`` with at least one True: only those scenes restart (Gymnasium's
  partial reset, meant for ``autoreset="disabled"``); the other scenes keep their
  episode and their observation. No other option exists.

The Gymnasium adapter takes its ``(num_envs,)`` forms (one entry per scene and
agent) and requires the agents of a scene to agree (:func:`per_scene`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["RENDER_MODES", "check_render_mode", "parse_reset", "per_scene", "render_ansi"]

#: Render modes of the envs: ``ansi`` = a text table of the true swarm state.
RENDER_MODES = ["ansi"]


def check_seed(seed: Any, name: str = "seed") -> int | None:
    """``seed`` if it is None or a non-negative integer (Gymnasium's rule), else an error
    naming ``name``.

    Raises:
        TypeError: not an integer (a bool is refused too).
        ValueError: a negative integer.
    """
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise TypeError(f"{name}: must be a non-negative int or None, got "
                        f"{type(seed).__name__} {seed!r}")
    if seed < 0:
        raise ValueError(f"{name}: must be a non-negative int or None, got {seed}")
    return int(seed)


def check_render_mode(mode: Any) -> str | None:
    """``mode`` if it is None or one of :data:`RENDER_MODES`, else a ValueError."""
    if mode is not None and mode not in RENDER_MODES:
        raise ValueError(f"render_mode: must be None or one of {RENDER_MODES}, got {mode!r}")
    return mode


def parse_reset(seed: Any, options: Mapping[str, Any] | None, n: int
                ) -> tuple[list[int | None], NDArray[np.bool_] | None]:
    """Per-scene roots (None: next episode) and the reset mask (None: all) of ``n`` scenes.

    Raises:
        TypeError, ValueError: a bad seed, an unknown option or a bad mask, named.
    """
    if isinstance(seed, list | tuple):
        if len(seed) != n:
            raise ValueError(f"seed: a list needs one entry per scene ({n}), got {len(seed)}")
        roots = [check_seed(x, f"seed[{i}]") for i, x in enumerate(seed)]
    else:
        roots = [check_seed(seed)] * n
    opts = dict(options or {})
    mask = opts.pop("reset_mask", None)
    if opts:
        raise ValueError(f"options: unknown reset options {sorted(opts)}; the only one is "
                         "'reset_mask' (configure the env at construction)")
    if mask is not None:
        if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
            raise TypeError("options['reset_mask']: must be a numpy array of dtype bool, got "
                            f"{type(mask).__name__}"
                            + (f" of {mask.dtype}" if isinstance(mask, np.ndarray) else ""))
        if mask.shape != (n,):
            raise ValueError(f"options['reset_mask']: must have shape ({n},), got {mask.shape}")
        if not mask.any():
            raise ValueError("options['reset_mask']: must contain at least one True value")
    return roots, mask


def per_scene(values: Any, n_scenes: int, n_agents: int, name: str) -> Any:
    """A ``(num_envs,)`` list or array (scene-major) as one entry per scene.

    Entries of one scene's agents must be equal (they share the scene). A list of
    ``n_scenes`` entries is taken as it is; anything else is returned unchanged.

    Raises:
        ValueError: the agents of a scene disagree.
    """
    if isinstance(values, np.ndarray) and values.shape == (n_scenes * n_agents,):
        rows = values.reshape(n_scenes, n_agents)
        bad = np.flatnonzero((rows != rows[:, :1]).any(axis=1))
        if bad.size:
            raise ValueError(f"{name}: the {n_agents} agents of scene {bad[0]} share it and "
                             f"must agree, got {rows[bad[0]].tolist()}")
        return rows[:, 0].copy()
    if isinstance(values, list | tuple) and len(values) == n_scenes * n_agents != n_scenes:
        for s in range(n_scenes):
            row = list(values[s * n_agents:(s + 1) * n_agents])
            if any(x != row[0] or type(x) is not type(row[0]) for x in row):
                raise ValueError(f"{name}: the {n_agents} agents of scene {s} share it and "
                                 f"must agree, got {row}")
        return [values[s * n_agents] for s in range(n_scenes)]
    return values


def render_ansi(truth: NDArray[np.float64], t: float, agents: list[int],
                aoi: NDArray[np.float64], error: NDArray[np.float64], title: str) -> str:
    """A text table of one scene: per node its true north, east, altitude, speed and
    heading; per agent the age of its shown state and its true error (``-`` if none)."""
    lines = [f"{title} t={t:.3f} s",
             f"{'node':>7} {'north m':>9} {'east m':>9} {'alt m':>7} {'u m/s':>6} "
             f"{'hdg deg':>7} {'age s':>6} {'err m':>6}"]
    for i, row in enumerate(truth):
        j = agents.index(i) if i in agents else -1
        age = "-" if j < 0 or not np.isfinite(aoi[j]) else f"{aoi[j]:.3f}"
        err = "-" if j < 0 or not np.isfinite(error[j]) else f"{error[j]:.2f}"
        lines.append(f"{'node_' + str(i):>7} {row[9]:9.2f} {row[10]:9.2f} {row[11]:7.1f} "
                     f"{row[0]:6.2f} {np.degrees(row[5]):7.1f} {age:>6} {err:>6}")
    return "\n".join(lines)
