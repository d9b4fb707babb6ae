"""The ground floor: what every layer above may use and which uses nothing of them.

- :mod:`sigma_des.core.sim` — the thin SimPy glue (plain callbacks with priorities);
- :mod:`sigma_des.core.rng` — counter-based random streams keyed by stable names;
- :mod:`sigma_des.core.counter_rng` — the same numbers inside numba kernels;
- :mod:`sigma_des.core.draws` — the lazy vectorised cache of per-message draws;
- :mod:`sigma_des.core.validate` — validation helpers for the spec dataclasses;
- :mod:`sigma_des.core.models` — the dynamics-model and behaviour protocols and the swarm view.

Nothing here imports any other part of sigma_des but :mod:`sigma_des.errors`.
"""
