"""``sigma-des warmup``: compile every numba kernel a default run uses, once, in parallel.

* :mod:`sigma_des.warmup.units` — the warm-up units (tiny comparisons and ideal
  flights, through :mod:`sigma_des.api`) and :func:`~sigma_des.warmup.units.warm`,
  which runs them in spawned processes;
* :mod:`sigma_des.warmup.cli` — the subcommand's arguments and output.

A top floor (it runs comparisons): the caches themselves live in :mod:`sigma_des.cache`
and :mod:`sigma_des.jitcache`, below :mod:`sigma_des.api`.
"""
